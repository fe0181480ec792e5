"""Wall time of the analyser and the design under Gauss-Markov profiles, beside another checkout.

Runs each command as a user would (``python -m seqdesign.cli ...``, a fresh process)
from this checkout and, with ``--against DIR``, from another one (e.g. the commit
before a change), interleaved so that both see the same load; prints the wall time,
the user+sys CPU time of the child, the peak PSS of the command and its workers
together (sampled each second) and the worst ratio each reported, and the
load average before and after (on a shared machine the CPU figure is the one that
says what the code costs).

    python benchmarks/gm_speed.py [--against DIR ...] [--only analyze|design|front]
                                  [--adis-design FILE] [--repeat N]

The commands: ``analyze designed-30min-gm --profile navigation-gm`` with and without
``--with all``; ``analyze FILE`` of a 10-minute design under the ADIS16405 profile
fitted from a real log (``benchmarks/profiles/adis16405.toml``; ``--adis-design``,
default: designed by the first design command below); ``design --budget-min 10
--workers 2`` under that profile against the ``mems`` requirements; a 30-minute
``navigation-gm --with all`` design with ``--workers 2``; and the
Gauss-Markov front ``design --pareto --budgets 10,20,30,40 --profile navigation-gm``.
``--against`` may be given several times (e.g. the commit before a change and the
one before the whole line of work); ``--repeat N`` runs each command N times, the
checkouts interleaved each time.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ADIS = ROOT / "benchmarks" / "profiles" / "adis16405.toml"


def run(root: Path, args: list[str]) -> tuple[float, float, float, str]:
    """Wall time, child CPU time (user + sys), peak memory (GB) and stdout of one CLI run from ``root``.

    The memory is the largest proportional set size (PSS: shared pages split between the
    processes that share them) of the command and its workers together, sampled each second.
    """
    cpu0 = os.times()
    t = time.perf_counter()
    # as a user runs it: the modules' bytecode cached (a shell may have told Python not to write it)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"} | {"PYTHONPATH": str(root)}
    with tempfile.TemporaryFile("w+") as stdout:
        proc = subprocess.Popen(
            [sys.executable, "-m", "seqdesign.cli", *args], cwd=root, stdout=stdout, text=True, env=env
        )
        peak = 0
        while True:  # memory sampled each second; the end seen within milliseconds
            peak = max(peak, tree_pss_kb(proc.pid))
            try:
                proc.wait(timeout=1.0)
                break
            except subprocess.TimeoutExpired:
                pass
        if proc.returncode:
            raise subprocess.CalledProcessError(proc.returncode, args)
        stdout.seek(0)
        out = stdout.read()
    wall = time.perf_counter() - t
    cpu1 = os.times()
    cpu = (cpu1.children_user - cpu0.children_user) + (cpu1.children_system - cpu0.children_system)
    return wall, cpu, peak / 1e6, out


def tree_pss_kb(pid: int) -> int:
    """PSS (kB) of a process and its descendants, from /proc (0 where /proc is not Linux's)."""
    children: dict[int, list[int]] = {}
    for d in Path("/proc").glob("[0-9]*"):
        try:
            ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(d.name))
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        try:
            for line in Path(f"/proc/{p}/smaps_rollup").read_text().splitlines():
                if line.startswith("Pss:"):
                    total += int(line.split()[1])
                    break
        except OSError:
            pass
        todo += children.get(p, [])
    return total


def worst_of(args: list[str], out: str) -> str:
    """The worst ratio a command reported."""
    if args[0] == "analyze":
        doc = json.loads(out)
        w = doc["worst"]
        text = f"{w['name']} {w['ratio']:.5f}"
        extras = doc.get("extras") or doc.get("with")
        if extras:
            text += f"; with the terms {extras['worst_with']['name']} {extras['worst_with']['ratio']:.5f}"
        return text
    # the report's rows: "   30m   30.0m   sax     1.290 ..." (the paper's line after them is not a design's)
    rows = re.findall(r"^\s+(\S+m)\s+\S+m\s+(\w+)\s+(\d+\.\d+)", out, re.MULTILINE)
    return "; ".join(f"{b} {name} {ratio}" for b, name, ratio in rows) or out.strip().splitlines()[-1][:60]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", type=Path, action="append", default=[], help="another checkout (repeatable)")
    ap.add_argument("--only", choices=["analyze", "design", "front"])
    ap.add_argument("--adis-design", type=Path, help="a 10-minute design under the ADIS profile")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each command per checkout")
    a = ap.parse_args()
    roots = [ROOT] + [d.resolve() for d in a.against]
    tmp = Path(tempfile.mkdtemp())
    adis_design = a.adis_design or tmp / "0" / "adis-10min.toml"  # this checkout's design
    commands = []
    if a.only in (None, "design"):
        # (against the paper's navigation-grade requirements the ADIS design is refused: every
        # candidate leaves the gyro biases not estimable at that scale)
        commands += [
            ["design", "--budget-min", "10", "--workers", "2", "--profile", str(ADIS)]
            + ["--requirements", "mems", "-o", "{out}/adis-10min.toml"],
            ["design", "--budget-min", "30", "--workers", "2", "--profile", "navigation-gm", "--with", "all"]
            + ["-o", "{out}/gm-30min-all.toml"],
        ]
    if a.only in (None, "analyze"):
        commands += [
            ["analyze", "designed-30min-gm", "--profile", "navigation-gm", "--json"],
            ["analyze", "designed-30min-gm", "--profile", "navigation-gm", "--with", "all", "--json"],
            ["analyze", str(adis_design), "--profile", str(ADIS), "--json"],
        ]
    if a.only in (None, "front"):
        commands.append(
            ["design", "--pareto", "--budgets", "10,20,30,40", "--profile", "navigation-gm", "--workers", "2"]
            + ["-o", "{out}/front"]
        )
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    print("  (" + ", ".join(map(str, roots)) + ")")
    print(f"  outputs in {tmp}")
    for n, args in [(n, args) for n, args in enumerate(commands) for _ in range(a.repeat)]:
        for i, root in enumerate(roots):
            out_dir = tmp / str(i)
            out_dir.mkdir(exist_ok=True)
            concrete = [x.replace("{out}", str(out_dir)) for x in args]
            if concrete[0] == "analyze" and concrete[1].endswith(".toml") and not Path(concrete[1]).exists():
                print(f"  (no {concrete[1]}: skipped)")
                continue
            w, c, gb, o = run(root, concrete)
            (out_dir / f"{n}.out").write_text(o)
            label = " ".join(args[:2] + [x for x in args[2:] if not x.startswith("{out}")])
            figures = f"{w:8.1f} s wall {c:8.1f} s cpu {gb:5.2f} GB"
            print(f"{label[:80]:<80} [{i}] {figures}  {worst_of(concrete, o)}", flush=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
