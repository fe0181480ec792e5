"""Monte Carlo proof of a design for the real unit (issue 12).

Simulates a sequence with the Gauss-Markov profile and every extra term at its
typical size (``calib/model/optional_terms.py``), calibrates with the same profile and
``--with all``, and reports the mean NEES of the 21 against its 99 % band and
RMS(error)/sigma per parameter (issue 12 asks for [0.67, 1.36]).

    python benchmarks/gm_designs.py designed-30min-gm --n 50 --workers 2
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.stats import chi2

from calib.model import params as P
from calib.model.optional_terms import GROUP_NAMES, OptionalTerms, OptionalTermValues
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from seqdesign.montecarlo import TrialConfig, run_trials


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("sequence")
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--profile", default="navigation-gm")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    seq = load_sequence(args.sequence)
    prof = load_profile(args.profile)
    extras = OptionalTerms(GROUP_NAMES)
    typical = OptionalTermValues.from_units({p.name: p.scale for p in extras.parameters})
    t0 = time.perf_counter()
    config = TrialConfig(extra=typical, extras=extras, fit_profile=prof)
    trials = run_trials(seq, prof, args.n, seed=12000, config=config, workers=args.workers)
    nees = trials.nees.mean()
    lo, hi = chi2.ppf([0.005, 0.995], P.N_PARAMS * args.n) / args.n
    ratio = trials.rms_error / trials.mean_sigma
    print(
        f"{args.sequence}: {args.n} runs, profile {prof.name}, --with all, extras at typical "
        f"sizes; {time.perf_counter() - t0:.0f} s; converged {int(trials.converged.sum())}"
    )
    print(
        f"mean NEES {nees:.2f}, 99 % band [{lo:.2f}, {hi:.2f}]: {'inside' if lo <= nees <= hi else 'OUTSIDE'}"
    )
    print(
        f"RMS(error)/sigma {ratio.min():.2f} ({P.NAMES[int(np.argmin(ratio))]}) to "
        f"{ratio.max():.2f} ({P.NAMES[int(np.argmax(ratio))]}); "
        f"{'all inside' if ratio.min() >= 0.67 and ratio.max() <= 1.36 else 'NOT all inside'}"
        " [0.67, 1.36]"
    )


if __name__ == "__main__":
    main()
