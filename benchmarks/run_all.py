"""Speed and accuracy benchmarks: `make bench` (or `python benchmarks/run_all.py [--mc N]`).

Prints a Markdown table of what was measured, on this machine, now. Figures
in BENCHMARKS.md come from this script; the tests assert physics, not time.
"""
from __future__ import annotations

import argparse
import datetime
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent / "seqdesign"


def wall(cmd: list[str], repeat: int = 3) -> float:
    """Best-of-``repeat`` wall time of a CLI command (start-up included)."""
    best = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        best = min(best, time.perf_counter() - t)
    return best


def best_of(fn, repeat: int = 5) -> float:
    best = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mc", type=int, default=0, help="also run N Monte Carlo trials per sequence")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()

    from calib.profiles import load_profile
    from calib.sequence import load_sequence
    from seqdesign.observability import analyze, analyze_tolerance

    rows = []
    tmp = Path(tempfile.mkdtemp(prefix="seqdesign-bench-"))
    npz, csv = tmp / "run.npz", tmp / "run.csv"
    sim = [str(BIN), "simulate", "paper-9pos", "--table2", "--setup-deg", "1", "-2", "3", "--seed", "7"]
    rows.append(("simulate paper-9pos (28.2 min, 200 Hz) -> NPZ, CLI wall", wall(sim + ["-o", str(npz)]), "<= 3 s"))
    rows.append(("simulate paper-9pos -> CSV, CLI wall", wall(sim + ["-o", str(csv)], 1), "-"))
    rows.append(("calibrate 28.2 min 200 Hz run from NPZ, CLI wall",
                 wall([str(BIN), "calibrate", str(npz), "-o", str(tmp / "r.toml")]), "<= 5 s"))
    rows.append(("calibrate the same run from CSV, CLI wall",
                 wall([str(BIN), "calibrate", str(csv), "-o", str(tmp / "r2.toml")], 1), "-"))
    seq, prof = load_sequence("paper-9pos"), load_profile("navigation")
    lat = math.radians(40.0)
    analyze(seq, prof, lat)  # warm caches (casadi step model, whitening) as a search loop would
    rows.append(("one analysis, nominal mounting, in-process (paper-9pos)",
                 best_of(lambda: analyze(seq, prof, lat)), "<= 10 ms"))
    rows.append(("worst case over +-3 deg (27 mountings), in-process",
                 best_of(lambda: analyze_tolerance(seq, prof, lat, 0.0, 3.0), 2), "<= 2 s"))
    rows.append(("analyze paper-9pos (+-3 deg), CLI wall incl. start-up",
                 wall([str(BIN), "analyze", "paper-9pos"]), "<= 3 s"))
    rows.append(("analyze paper-9pos --tolerance-deg 0, CLI wall",
                 wall([str(BIN), "analyze", "paper-9pos", "--tolerance-deg", "0"]), "-"))

    print(f"Measured {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC on "
          f"{platform.node()} ({platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}); command: python benchmarks/run_all.py"
          + (f" --mc {args.mc}" if args.mc else ""))
    print()
    print("| what | measured | target |")
    print("|---|---|---|")
    for what, sec, target in rows:
        shown = f"{sec * 1000:.1f} ms" if sec < 1 else f"{sec:.2f} s"
        print(f"| {what} | {shown} | {target} |")

    if args.mc:
        from calib import params as P
        from seqdesign.montecarlo import run_trials
        for name in ("paper-9pos",):
            s = load_sequence(name)
            t = time.perf_counter()
            trials = run_trials(s, prof, args.mc, seed=1000, workers=args.workers)
            el = time.perf_counter() - t
            pred = analyze(s, prof, lat)
            print()
            print(f"Monte Carlo {name}: N = {args.mc} (navigation profile, Table 2 errors, random "
                  f"mounting within +-3 deg, flip errors within +-0.5 deg), {el:.0f} s with "
                  f"{args.workers} workers; all converged: {bool(trials.converged.all())}")
            print(f"mean NEES (reported covariance) {trials.nees.mean():.2f}, (predicted) "
                  f"{trials.nees_against(pred.covariance).mean():.2f}; 99 % interval [18.1, 24.2]")
            print()
            print("| param | RMS error | mean reported sigma | RMS/sigma | predicted sigma | RMS/predicted |")
            print("|---|---|---|---|---|---|")
            rms, ms = P.from_si(trials.rms_error), P.from_si(trials.mean_sigma)
            ps = P.from_si(pred.sigma)
            for p in P.PARAMETERS:
                i = p.index
                print(f"| {p.name} | {rms[i]:.4g} {p.unit} | {ms[i]:.4g} | {rms[i] / ms[i]:.2f} | "
                      f"{ps[i]:.4g} | {rms[i] / ps[i]:.2f} |")


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    main()
