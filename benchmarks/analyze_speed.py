"""CLI wall time of ``seqdesign analyze`` and ``compare`` (issue 18's analyser targets).

Runs ``python -m seqdesign.cli analyze NAME --json`` for every shipped sequence
(``sequences/*.toml``) and ``compare`` of the four older ones as a user would, each
in a fresh process, best of ``--repeat`` (default 3), and prints the wall time,
the user+sys CPU of that best run, and the worst ratio the command reported. The
load average before and after is printed too: on a shared machine the wall figure
is only meaningful when the load is low.

    python benchmarks/analyze_speed.py [--repeat 3] [--profile navigation]
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


def timed(args: list[str], repeat: int) -> tuple[float, float, str]:
    """Best wall time of ``repeat`` runs, that run's child CPU time, and its stdout."""
    best = (float("inf"), 0.0, "")
    for _ in range(repeat):
        cpu0 = os.times()
        t = time.perf_counter()
        out = subprocess.run([sys.executable, "-m", "seqdesign.cli", *args], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout
        wall = time.perf_counter() - t
        cpu1 = os.times()
        cpu = (cpu1.children_user - cpu0.children_user) + (cpu1.children_system
                                                           - cpu0.children_system)
        if wall < best[0]:
            best = (wall, cpu, out)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--profile", default="navigation")
    a = ap.parse_args()
    names = sorted(p.stem for p in (ROOT / "sequences").glob("*.toml"))
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'command':<44}{'wall s':>8}{'cpu s':>8}  worst ratio")
    for name in names:
        wall, cpu, out = timed(["analyze", name, "--profile", a.profile, "--json"], a.repeat)
        w = json.loads(out)["worst"]
        print(f"{'analyze ' + name:<44}{wall:8.2f}{cpu:8.2f}  {w['name']} {w['ratio']:.4f}",
              flush=True)
    wall, cpu, out = timed(["compare", *COMPARED, "--profile", a.profile], a.repeat)
    worst = re.findall(r"(\w+) (\d+\.\d+)", re.search(r"^worst\s+(.*)$", out, re.M).group(1))
    print(f"{'compare of the four':<44}{wall:8.2f}{cpu:8.2f}  "
          + " / ".join(f"{n} {r}" for n, r in worst))
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
