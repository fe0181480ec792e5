"""Mismatch report (issue 8, partial): what ignoring a real unit's extra terms costs.

    python benchmarks/mismatch.py [--n 30] [--sequence designed-30min]

Simulates runs with unmodelled accelerometer K2 terms and/or a gyro-accelerometer
time offset, calibrates them with the 21-parameter model (the only one the
estimator has so far), and prints per parameter the mean error over sigma (the
bias in units of the reported sigma) and the mean NEES (21 expected).
"""
from __future__ import annotations

import argparse

import numpy as np

import calib  # noqa: F401  (BLAS threads)
from calib import params as P
from calib.profiles import load_profile
from calib.sequence import load_sequence
from calib.sim import UnmodelledTerms
from seqdesign.montecarlo import run_trials

CASES = {
    "none": UnmodelledTerms.from_units((0.0, 0.0, 0.0), 0.0),
    "K2 = 20 ug/g^2 (each axis)": UnmodelledTerms.from_units((20.0, 20.0, 20.0), 0.0),
    "time offset 0.5 ms": UnmodelledTerms.from_units((0.0, 0.0, 0.0), 0.5),
    "both": UnmodelledTerms.from_units((20.0, 20.0, 20.0), 0.5),
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--sequence", default="designed-30min")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    seq, prof = load_sequence(args.sequence), load_profile("navigation")
    results = {}
    for label, terms in CASES.items():
        trials = run_trials(seq, prof, args.n, seed=2000, workers=args.workers,
                            unmodelled=terms if terms.active else None)
        sig = np.sqrt(np.einsum("nii->ni", trials.covariances))
        results[label] = (np.mean(trials.errors / sig, axis=0), trials.nees.mean())
    print(f"{args.sequence}, navigation profile, Table 2 errors, random mounting within +-3 deg, "
          f"flip errors within +-0.5 deg, N = {args.n} per case; estimator: the 21-parameter model")
    print()
    print("| param | " + " | ".join(f"mean error/sigma: {k}" for k in results) + " |")
    print("|---|" + "---|" * len(results))
    for p in P.PARAMETERS:
        print(f"| {p.name} | " + " | ".join(f"{r[0][p.index]:+.2f}" for r in results.values()) + " |")
    print("| **mean NEES** (21 expected) | " + " | ".join(f"**{r[1]:.1f}**" for r in results.values())
          + " |")


if __name__ == "__main__":
    main()
