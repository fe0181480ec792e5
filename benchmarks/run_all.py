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


def cli_rows(tmp: Path) -> list:
    """Simulate, calibrate (plain, extra terms, GM) and analyse through the CLI."""
    rows = []
    npz, csv = tmp / "run.npz", tmp / "run.csv"
    sim = [str(BIN), "simulate", "paper-9pos", "--table2", "--setup-deg", "1", "-2", "3", "--seed", "7"]
    rows.append(
        ("simulate paper-9pos (28.2 min, 200 Hz) -> NPZ, CLI wall", wall(sim + ["-o", str(npz)]), "<= 3 s")
    )
    rows.append(("simulate paper-9pos -> CSV, CLI wall", wall(sim + ["-o", str(csv)], 1), "-"))
    rows.append(
        (
            "calibrate 28.2 min 200 Hz run from NPZ, CLI wall",
            wall([str(BIN), "calibrate", str(npz), "-o", str(tmp / "r.toml")]),
            "<= 5 s",
        )
    )
    rows.append(
        (
            "calibrate the same run from CSV, CLI wall",
            wall([str(BIN), "calibrate", str(csv), "-o", str(tmp / "r2.toml")], 1),
            "-",
        )
    )
    # Issue 8: a real unit's terms simulated and fitted; bias instability weighted.
    npz_x = tmp / "run-extra.npz"
    subprocess.run(
        sim + ["--extra", "rxx=3,ryy=-2,k2y=20,dt_ga=0.3", "-o", str(npz_x)],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    rows.append(
        (
            "calibrate --with all (21 + 13 extra parameters), same run size, CLI wall",
            wall([str(BIN), "calibrate", str(npz_x), "--with", "all", "-o", str(tmp / "rx.toml")]),
            "-",
        )
    )
    npz_gm = tmp / "run-gm.npz"
    subprocess.run(
        sim + ["--profile", "navigation-gm", "-o", str(npz_gm)],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    rows.append(
        (
            "calibrate --profile navigation-gm (9-state GM whitening), CLI wall",
            wall(
                [
                    str(BIN),
                    "calibrate",
                    str(npz_gm),
                    "--profile",
                    "navigation-gm",
                    "-o",
                    str(tmp / "rgm.toml"),
                ]
            ),
            "-",
        )
    )
    rows.append(
        (
            "analyze paper-9pos --with all (+-3 deg, 27 direct evaluations), CLI wall",
            wall([str(BIN), "analyze", "paper-9pos", "--with", "all"], 1),
            "-",
        )
    )
    rows.append(
        (
            "analyze paper-9pos --profile navigation-gm (+-3 deg), CLI wall",
            wall([str(BIN), "analyze", "paper-9pos", "--profile", "navigation-gm"], 1),
            "-",
        )
    )
    return rows


def analysis_rows(seq, prof, lat) -> list:
    """The analyser in-process and through the CLI."""
    from calib.analysis.mounting import analyze
    from calib.analysis.worst_case import analyze_tolerance
    from calib.nav.site import Site

    site = Site.at(lat)
    analyze(seq, prof, site)  # warm caches (casadi step model, whitening) as a search loop would
    return [
        (
            "one analysis, nominal mounting, in-process (paper-9pos)",
            best_of(lambda: analyze(seq, prof, site)),
            "<= 10 ms",
        ),
        (
            "worst case over +-3 deg (27 mountings), in-process",
            best_of(lambda: analyze_tolerance(seq, prof, site, 3.0), 2),
            "<= 2 s",
        ),
        (
            "analyze paper-9pos (+-3 deg), CLI wall incl. start-up",
            wall([str(BIN), "analyze", "paper-9pos"]),
            "<= 3 s",
        ),
        (
            "analyze paper-9pos --tolerance-deg 0, CLI wall",
            wall([str(BIN), "analyze", "paper-9pos", "--tolerance-deg", "0"]),
            "-",
        ),
    ]


def search_rows(seq, prof, lat, tmp: Path) -> list:
    """The search loop: one candidate = a walk scored by the segment model; a whole design."""
    from calib.nav.site import Site
    from seqdesign.search import Constraints, Move, SearchModel, beam_search

    c9 = Constraints(budget_s=1800.0, max_flips=8, max_quarters=1)
    m9 = SearchModel.build(c9, 180.0, Site.at(lat), prof)
    walk = [Move(s.axis, 1 if s.angle_deg > 0 else -1, 1) for s in seq.steps]

    def score_walk():
        cand = m9.start_candidate()
        for mv in walk:
            cand = next(k for k in m9.extend([cand], "worst") if k.walk[-1] == mv)
        return cand

    rows = [
        (
            "one analysis inside the search (paper's 9-position walk, segment model)",
            best_of(score_walk),
            "<= 10 ms",
        )
    ]
    c15 = Constraints(budget_s=900.0, max_flips=10, max_quarters=5)
    t = time.perf_counter()
    m15 = SearchModel.build(c15, 57.3, Site.at(lat), prof)
    build = time.perf_counter() - t
    t = time.perf_counter()
    _, n = beam_search(m15, "worst", 200)
    el = time.perf_counter() - t
    rows.append(
        (
            f"search: {n} candidates scored by beam search (15 min, width 200)",
            el,
            f"{n / el:,.0f} candidates/s (>= 10,000); model build {build:.1f} s",
        )
    )
    rows.append(
        (
            "seqdesign design --budget-min 15 (search, exact +-3 deg re-scoring, IPOPT), CLI wall",
            wall([str(BIN), "design", "--budget-min", "15", "-o", str(tmp / "d15.toml")], 1),
            "<= 5 min",
        )
    )
    return rows


def view_rows(tmp: Path) -> list:
    """Record a calibrated run for the viewer."""
    sim = [
        str(BIN),
        "simulate",
        "paper-9pos",
        "--table2",
        "--setup-deg",
        "1",
        "-2",
        "3",
        "--seed",
        "7",
        "-o",
        str(tmp / "v.npz"),
    ]
    subprocess.run(sim, check=True, stdout=subprocess.DEVNULL)
    subprocess.run(
        [str(BIN), "calibrate", str(tmp / "v.npz")],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    return [
        (
            "view: record the 28.2 min 200 Hz run with result and truth, CLI wall",
            wall([str(BIN), "view", str(tmp / "v.npz"), "-o", str(tmp / "v.rrd")]),
            "<= 5 s",
        ),
        (f"  .rrd size: {(tmp / 'v.rrd').stat().st_size / 1e6:.1f} MB", 0.0, "<= 100 MB"),
    ]


MC_SEQUENCES = ("paper-9pos", "paper-9pos-turns", "designed-15min", "designed-30min")


def monte_carlo(n: int, workers: int, prof, lat, sequences=MC_SEQUENCES) -> None:
    """N simulate -> calibrate trials per shipped sequence against the predicted sigmas."""
    from calib.analysis.mounting import analyze
    from calib.model import params as P
    from calib.nav.site import Site
    from calib.sequence.definition import load_sequence
    from seqdesign.montecarlo import run_trials

    for name in sequences:
        s = load_sequence(name)
        t = time.perf_counter()
        trials = run_trials(s, prof, n, seed=1000, workers=workers)
        el = time.perf_counter() - t
        pred = analyze(s, prof, Site.at(lat))
        print()
        print(
            f"Monte Carlo {name}: N = {n} (navigation profile, Table 2 errors, random "
            f"mounting within +-3 deg, flip errors within +-0.5 deg), {el:.0f} s with "
            f"{workers} workers; all converged: {bool(trials.converged.all())}"
        )
        print(
            f"mean NEES (reported covariance) {trials.nees.mean():.2f}, (predicted) "
            f"{trials.nees_against(pred.covariance).mean():.2f}; 99 % interval [18.1, 24.2]"
        )
        print()
        print("| param | RMS error | mean reported sigma | RMS/sigma | predicted sigma | RMS/predicted |")
        print("|---|---|---|---|---|---|")
        rms, ms = P.from_si(trials.rms_error), P.from_si(trials.mean_sigma)
        ps = P.from_si(pred.sigma)
        for p in P.PARAMETERS:
            i = p.index
            print(
                f"| {p.name} | {rms[i]:.4g} {p.unit} | {ms[i]:.4g} | {rms[i] / ms[i]:.2f} | "
                f"{ps[i]:.4g} | {rms[i] / ps[i]:.2f} |"
            )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mc", type=int, default=0, help="also run N Monte Carlo trials per sequence")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--mc-only",
        default="",
        help="comma-separated sequences: run only their Monte Carlo (with --mc N), no speed benchmarks",
    )
    args = ap.parse_args()

    from calib.noise.profiles import load_profile
    from calib.sequence.definition import load_sequence

    tmp = Path(tempfile.mkdtemp(prefix="seqdesign-bench-"))
    seq, prof = load_sequence("paper-9pos"), load_profile("navigation")
    lat = math.radians(40.0)
    if args.mc_only:
        monte_carlo(args.mc or 50, args.workers, prof, lat, args.mc_only.split(","))
        return
    rows = cli_rows(tmp) + analysis_rows(seq, prof, lat) + search_rows(seq, prof, lat, tmp) + view_rows(tmp)
    print(
        f"Measured {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC on "
        f"{platform.node()} ({platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}); command: python benchmarks/run_all.py"
        + (f" --mc {args.mc}" if args.mc else "")
    )
    print()
    print("| what | measured | target |")
    print("|---|---|---|")
    for what, sec, target in rows:
        shown = "" if sec == 0.0 else f"{sec * 1000:.2f} ms" if sec < 1 else f"{sec:.2f} s"
        print(f"| {what} | {shown} | {target} |")
    if args.mc:
        monte_carlo(args.mc, args.workers, prof, lat)


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    main()
