"""`seqdesign calibrate` of one run against an older checkout, side by side (issue 18).

    python benchmarks/calibrate_speed.py --base ../wt-base [--minutes 28.2] [--rate 200]
                                         [--rounds 5] [--run FILE.npz]

Simulates the paper's 9 positions stretched to ``--minutes`` at ``--rate``
(as :mod:`benchmarks.scaling` does: Table 2 errors, mounting (1, -2, 3) deg,
seed 7), unless ``--run`` gives a log, then runs ``seqdesign calibrate`` on it
from this checkout and from ``--base`` alternately, ``--rounds`` times each,
under ``/usr/bin/time -v``. It prints the best wall and CPU (user + system)
time of each, their ratios, the load average before and after (the machine
is shared: the CPU ratio is the fairer figure) and the largest difference of
the 21 estimates in units of the base's sigma. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling import ROOT, calibrate, max_difference_sigma, simulate, stretched_sequence  # noqa: E402


def side_by_side(run: Path, base: Path, rounds: int, folder: Path) -> dict:
    """Best wall and CPU of ``rounds`` alternating runs of each checkout on the same file."""
    new, old = [], []
    for _ in range(rounds):
        new.append(calibrate(ROOT, run, folder / "new.result.toml"))
        old.append(calibrate(base, run, folder / "base.result.toml"))
    best = {
        name: {key: min(r[key] for r in runs) for key in ("wall_s", "cpu_s", "rss_mb")}
        for name, runs in (("new", new), ("base", old))
    }
    best["diff_sigma"] = max_difference_sigma(folder / "new.result.toml", folder / "base.result.toml")
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", type=Path, required=True, help="checkout of the code to compare with")
    ap.add_argument("--minutes", type=float, default=28.2)
    ap.add_argument("--rate", type=float, default=200.0)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--run", type=Path, help="an existing run log instead of a new simulation")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="calspeed-") as tmp:
        folder = Path(tmp)
        run = a.run
        if run is None:
            run = folder / "run.npz"
            simulate(stretched_sequence(a.minutes, folder), a.rate, run)
        load_before = os.getloadavg()
        best = side_by_side(run.resolve(), a.base.resolve(), a.rounds, folder)
        load_after = os.getloadavg()
    n, b = best["new"], best["base"]
    print(f"run {run} ({a.minutes:g} min at {a.rate:g} Hz unless given), best of {a.rounds}")
    print(f"  wall  new {n['wall_s']:.2f} s  base {b['wall_s']:.2f} s  ratio {n['wall_s'] / b['wall_s']:.3f}")
    print(f"  CPU   new {n['cpu_s']:.2f} s  base {b['cpu_s']:.2f} s  ratio {n['cpu_s'] / b['cpu_s']:.3f}")
    print(f"  peak  new {n['rss_mb']:.0f} MB  base {b['rss_mb']:.0f} MB")
    print(f"  largest |new - base| / sigma over the 21: {best['diff_sigma']:.2e}")
    print(f"  load average (1 min) before {load_before[0]:.2f}, after {load_after[0]:.2f}")


if __name__ == "__main__":
    main()
