"""Monte Carlo on accelerating moves (issue 13): are the sigmas still honest when flips ramp up?

    python benchmarks/accelerating_moves.py [--n 50] [--sequence designed-15min]
        [--accel-dps2 5] [--jerk-dps3 10] [--workers 1]

Every move of the sequence becomes an S-curve (or a trapezoid with
``--jerk-dps3 0``) with the given limits; the cruise rate stays the file's.
Each trial simulates a noisy run (navigation profile, Table 2 errors, random
mounting within +-3 deg, flip errors within +-0.5 deg) and calibrates it with
the estimator, which navigates the measured increments. Prints the mean NEES
of the 21 against the reported and the analyser's predicted covariance, with
the 99 % interval of the mean of N chi-square(21) draws, and RMS(error)/sigma
per parameter.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace

import numpy as np
from scipy.stats import chi2

import calib  # noqa: F401  (BLAS threads)
from calib.analysis.mounting import analyze
from calib.model import params as P
from calib.nav.site import Site
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from seqdesign.montecarlo import run_trials


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--sequence", default="designed-15min")
    ap.add_argument("--accel-dps2", type=float, default=5.0)
    ap.add_argument("--jerk-dps3", type=float, default=10.0, help="0: trapezoid")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args()
    base = load_sequence(args.sequence)
    jerk = args.jerk_dps3 if args.jerk_dps3 > 0 else None
    seq = replace(
        base,
        name=base.name + "-accelerating",
        steps=tuple(replace(s, accel_dps2=args.accel_dps2, jerk_dps3=jerk) for s in base.steps),
    )
    prof = load_profile("navigation")
    t = time.perf_counter()
    trials = run_trials(seq, prof, args.n, seed=2000, workers=args.workers)
    elapsed = time.perf_counter() - t
    pred = analyze(seq, prof, Site.at(math.radians(40.0)))
    lo, hi = chi2.ppf([0.005, 0.995], P.N_PARAMS * args.n) / args.n
    kind = "S-curve" if jerk else "trapezoid"
    print(
        f"{seq.name}: {base.duration_s:.0f} s -> {seq.duration_s:.0f} s with {kind} moves "
        f"(accel {args.accel_dps2:g} deg/s^2"
        + (f", jerk {jerk:g} deg/s^3" if jerk else "")
        + f"); N = {args.n}, {elapsed:.0f} s, {args.workers} worker(s); "
        f"all converged: {bool(trials.converged.all())}"
    )
    print(
        f"mean NEES (reported covariance) {trials.nees.mean():.2f}, (predicted) "
        f"{trials.nees_against(pred.covariance).mean():.2f}; 99 % interval [{lo:.1f}, {hi:.1f}]"
    )
    rms, ms, ps = (P.from_si(x) for x in (trials.rms_error, trials.mean_sigma, pred.sigma))
    ratio, ratio_pred = rms / ms, rms / ps
    print(
        f"RMS(error)/reported sigma: {ratio.min():.2f}-{ratio.max():.2f}; "
        f"RMS(error)/predicted sigma: {ratio_pred.min():.2f}-{ratio_pred.max():.2f}"
    )
    print("| param | RMS error | mean reported sigma | RMS/sigma | predicted sigma | RMS/predicted |")
    print("|---|---|---|---|---|---|")
    for p in P.PARAMETERS:
        i = p.index
        print(
            f"| {p.name} | {rms[i]:.4g} {p.unit} | {ms[i]:.4g} | {ratio[i]:.2f} | "
            f"{ps[i]:.4g} | {ratio_pred[i]:.2f} |"
        )
    worst = np.argmax(pred.sigma * 3 / P.REQUIREMENTS_SI)
    print(
        f"analyser: worst 3 sigma/requirement at the nominal mounting "
        f"{3 * pred.sigma[worst] / P.REQUIREMENTS_SI[worst]:.2f} ({P.NAMES[worst]})"
    )


if __name__ == "__main__":
    main()
