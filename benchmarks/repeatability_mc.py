"""Two runs of one unit, many times over: is `seqdesign compare`'s chi-square what it claims?

    PYTHONPATH=. python benchmarks/repeatability_mc.py [--pairs 40] [--sequence designed-15min]
        [--workers 1] [--flip-error-deg 0.5] [--save out.npz]

One MEMS unit (its 21 errors drawn once, uniform within the MEMS sizes `verify` draws, from
``--seed``) on one base mounting (drawn once within +-3 deg) is simulated 2 x ``--pairs`` times
under the `mems` profile at 100 Hz, each run with its own noise and flip errors (seed
``--seed + 1 + i``, as `seqdesign simulate --seed` draws them), and calibrated as `calibrate`
does (`mems` profile and requirements). Runs 2k and 2k+1 are a pair, compared as `compare` does
(:class:`seqdesign.repeatability.Repeatability`).

Printed: the distribution of compare's chi-square over the pairs beside chi-square(21) (mean,
spread, Kolmogorov-Smirnov p-value), and beside the distribution it really has when the sigmas
are honest: the sum of squared normalised differences of correlated estimates is a weighted sum
of chi-square(1), the weights the eigenvalues of the difference's correlation matrix. Also the
full-covariance statistic d' (Ca + Cb)^-1 d, which is chi-square(21) for honest sigmas, and
each run's NEES against the truth.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from scipy.stats import chi2, kstest

import calib  # noqa: F401  (BLAS threads)
from calib.calibration.entry import CalibrateOptions, calibrate
from calib.errors import CalibError
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate
from seqdesign.repeatability import Repeatability, weighted_chi2_sf
from seqdesign.verify import error_half_range

SAMPLE_RATE_HZ = 100.0
LATITUDE_DEG = 40.0
SETUP_DEG = 3.0


def difference_weights(a, b) -> np.ndarray:
    """Eigenvalues of the correlation matrix of b - a for independent runs (Ca + Cb)."""
    C = a.covariance + b.covariance
    s = np.sqrt(np.diag(C))
    return np.linalg.eigvalsh(C / np.outer(s, s))


def unit(seed: int) -> tuple[ErrorModel, np.ndarray]:
    """The one unit: its 21 MEMS errors and its base mounting (rad), from ``seed``."""
    rng = np.random.default_rng(seed)
    errors = ErrorModel.from_units(rng.uniform(-1.0, 1.0, P.N_PARAMS) * error_half_range("mems"))
    return errors, np.radians(rng.uniform(-SETUP_DEG, SETUP_DEG, 3))


def one_run(args):
    """Simulate one run of the unit with its own noise and flip errors; calibrate it."""
    sequence, unit_seed, seed, flip_deg = args
    errors, setup = unit(unit_seed)
    prof = load_profile("mems")
    cfg = SimConfig(latitude_rad=math.radians(LATITUDE_DEG), sample_rate_hz=SAMPLE_RATE_HZ)
    run, truth = simulate(
        load_sequence(sequence),
        cfg,
        errors,
        prof,
        options=SimOptions(setup_rotvec=setup, flip_error_deg=flip_deg, seed=seed),
    )
    t0 = time.process_time()
    try:
        res = calibrate(run, prof, requirements="mems", options=CalibrateOptions(require_convergence=False))
    except CalibError as e:
        print(f"seed {seed}: {e}", flush=True)
        return None, seed, time.process_time() - t0
    return res, seed, time.process_time() - t0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=40)
    ap.add_argument("--sequence", default="designed-15min")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=2400)
    ap.add_argument("--flip-error-deg", type=float, default=0.5)
    ap.add_argument("--save", help="write each run's values, sigmas, correlations to this .npz")
    args = ap.parse_args()
    jobs = [(args.sequence, args.seed, args.seed + 1 + i, args.flip_error_deg) for i in range(2 * args.pairs)]
    wall = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        out = list(pool.map(one_run, jobs))
    wall = time.perf_counter() - wall
    truth = unit(args.seed)[0].values
    res = [o[0] for o in out]
    if args.save:
        ok = [r for r in res if r is not None]
        np.savez(
            args.save,
            values=np.array([r.values for r in ok]),
            sigma=np.array([r.sigma for r in ok]),
            correlation=np.array([r.correlation for r in ok]),
            converged=np.array([r.converged for r in ok]),
            seeds=np.array([o[1] for o in out if o[0] is not None]),
            truth=truth,
        )
    load = os.getloadavg()
    print(
        f"{args.sequence}, `mems` profile and requirements, {SAMPLE_RATE_HZ:g} Hz, one unit (seed "
        f"{args.seed}), {2 * args.pairs} runs (seeds {args.seed + 1}..{args.seed + 2 * args.pairs}), "
        f"flip errors +-{args.flip_error_deg:g} deg; {platform.machine()}, {args.workers} workers, wall "
        f"{wall / 60:.1f} min, calibrate CPU {np.mean([o[2] for o in out]):.1f} s/run, load "
        f"{load[0]:.1f} {load[1]:.1f} {load[2]:.1f}"
    )
    refused = [o[1] for o in out if o[0] is None]
    unconverged = [o[1] for o in out if o[0] is not None and not o[0].converged]
    print(f"refused: {refused or 'none'}; not converged: {unconverged or 'none'}")
    nees = np.array([r.nees(truth) for r in res if r is not None])
    print(f"NEES against the truth: mean {nees.mean():.2f} over {len(nees)} runs (21 if honest)")
    diag, full, pw = [], [], []
    for k in range(args.pairs):
        a, b = res[2 * k], res[2 * k + 1]
        if a is None or b is None or not (a.converged and b.converged):
            continue
        rep = Repeatability(a, b, (str(2 * k), str(2 * k + 1)))
        s, dof, p = rep.chi2()
        d = b.values - a.values
        full.append(float(d @ np.linalg.solve(a.covariance + b.covariance, d)))
        diag.append(s)
        pw.append(p)  # compare's p-value: the sum's own distribution, correlations included
    diag_a, full_a, pw_a = np.array(diag), np.array(full), np.array(pw)
    n = len(diag_a)
    print(f"pairs both converged: {n} of {args.pairs}")
    sd = math.sqrt(2 * P.N_PARAMS)
    print(
        f"compare's chi2 (diagonal): mean {diag_a.mean():.1f} +- {diag_a.std(ddof=1) / math.sqrt(n):.1f} "
        f"(21), sd {diag_a.std(ddof=1):.1f} (chi2(21): {sd:.1f}), median {np.median(diag_a):.1f}, "
        f"max {diag_a.max():.1f}; KS against chi2(21) p = {kstest(diag_a, chi2(P.N_PARAMS).cdf).pvalue:.3g}; "
        f"below p = 0.01 by chi2(21): {int(np.sum(chi2.sf(diag_a, P.N_PARAMS) < 0.01))} of {n}"
    )
    print(
        f"the same against its weighted chi2 (correlations): KS of the p-values against uniform "
        f"p = {kstest(pw_a, 'uniform').pvalue:.3g}; below p = 0.01: {int(np.sum(pw_a < 0.01))} of {n}"
    )
    ks_full = kstest(full_a, chi2(P.N_PARAMS).cdf).pvalue
    print(
        f"full covariance d'(Ca+Cb)^-1 d: mean {full_a.mean():.1f} +- "
        f"{full_a.std(ddof=1) / math.sqrt(n):.1f}, sd {full_a.std(ddof=1):.1f}, "
        f"KS against chi2(21) p = {ks_full:.3g}"
    )
    # What the diagonal sum's spread is for honest sigmas: sqrt(2 sum lambda^2) of a typical pair.
    a, b = res[0], res[1]
    if a is not None and b is not None:
        lam = difference_weights(a, b)
        print(
            f"pair 0's difference correlation: eigenvalues {lam.min():.3g}..{lam.max():.3g}, "
            f"sd of the weighted chi2 {math.sqrt(2 * np.sum(lam**2)):.1f}; "
            f"chi2 42.5 has p = {chi2.sf(42.5, 21):.3g} by chi2(21), "
            f"{weighted_chi2_sf(42.5, lam):.3g} by the weighted chi2"
        )


if __name__ == "__main__":
    main()
