"""CLI wall time of ``seqdesign analyze`` and ``compare`` (issue 18's analyser targets).

Runs ``python -m seqdesign.cli analyze NAME --json`` for every shipped sequence
(``sequences/*.toml``) and ``compare`` of the four older ones as a user would, each
in a fresh process, best of ``--repeat`` (default 3), and prints the wall time,
the user+sys CPU of that best run, and the worst ratio the command reported. The
load average before and after is printed too: on a shared machine the wall figure
is only meaningful when the load is low, the CPU figure always is.

``--against DIR`` also runs the same commands from another checkout (e.g. one of an
older commit), interleaved run by run so that both see the same load.

    python benchmarks/analyze_speed.py [--repeat 3] [--profile navigation] [--against DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COMPARED = ["paper-9pos", "paper-9pos-turns", "designed-15min", "designed-30min"]


def run(root: Path, args: list[str]) -> tuple[float, float, str]:
    """Wall time, child CPU time (user + sys) and stdout of one CLI run from ``root``."""
    cpu0 = os.times()
    t = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-m", "seqdesign.cli", *args], cwd=root, capture_output=True, text=True, check=True
    ).stdout
    wall = time.perf_counter() - t
    cpu1 = os.times()
    cpu = (cpu1.children_user - cpu0.children_user) + (cpu1.children_system - cpu0.children_system)
    return wall, cpu, out


def worst_of(args: list[str], out: str) -> str:
    """The worst ratio a command printed."""
    if args[0] == "analyze":
        w = json.loads(out)["worst"]
        return f"{w['name']} {w['ratio']:.4f}"
    line = re.search(r"^worst\s+(.*)$", out, re.M).group(1)
    return " / ".join(f"{n} {r}" for n, r in re.findall(r"(\w+) (\d+\.\d+)", line))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--profile", default="navigation")
    ap.add_argument("--against", type=Path, help="another checkout to time side by side")
    a = ap.parse_args()
    roots = [ROOT] + ([a.against.resolve()] if a.against else [])
    names = sorted(p.stem for p in (ROOT / "sequences").glob("*.toml"))
    commands = [["analyze", n, "--profile", a.profile, "--json"] for n in names]
    commands.append(["compare", *COMPARED, "--profile", a.profile])
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(
        f"{'command':<36}"
        + "".join(f"{'wall s':>8}{'cpu s':>7}  {'worst ratio':<14}" for _ in roots)
        + "  ("
        + ", ".join(map(str, roots))
        + ")"
    )
    for args in commands:
        best = [(float("inf"), 0.0, "")] * len(roots)
        for _ in range(a.repeat):
            for i, root in enumerate(roots):
                r = run(root, args)
                best[i] = min(best[i], r)
        label = args[1] if args[0] == "analyze" else "compare of the four"
        print(
            f"{label:<36}" + "".join(f"{w:8.2f}{c:7.2f}  {worst_of(args, o):<14}" for w, c, o in best),
            flush=True,
        )
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
