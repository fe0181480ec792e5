"""MEMS Monte Carlo (issue 14): does a MEMS unit calibrate, with honest sigmas?

    python benchmarks/mems_mc.py [--n 50] [--workers 2] [--sequence paper-9pos]

Each run draws its own MEMS errors of the sizes of issue 14 point 4 (gyro
biases within +-1000 deg/h, accelerometer biases within +-20 mg, scale
factors within +-0.5 %, misalignments within +-1000 arcsec, all uniform),
its base mounting within +-3 deg, flip errors within +-0.5 deg and the white
noise of the `mems` profile (ARW 2.6 deg/sqrt(h), VRW 460 ug/sqrt(Hz)) at
100 Hz, from seed ``--seed + i``. Every run is calibrated with
:func:`calib.calibration.entry.calibrate` (what ``seqdesign calibrate`` calls)
with the `mems` profile and requirements. Prints the mean NEES of the 21
against the 99 % band of its chi-square distribution (21 N degrees of
freedom, divided by N) and, per parameter, RMS(error / sigma) over the runs
(1 when the reported sigmas are honest; the issue asks for [0.67, 1.36]).
"""

from __future__ import annotations

import argparse
import math
import platform
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from scipy.stats import chi2

import calib  # noqa: F401  (BLAS threads)
from calib.calibration.entry import CalibrateOptions, calibrate
from calib.errors import CalibError
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate
from seqdesign.verify import error_half_range

SAMPLE_RATE_HZ = 100.0  # the rate of the ADIS16405 log in the shared realdata folder
LATITUDE_DEG = 40.0
SETUP_DEG = 3.0
FLIP_ERROR_DEG = 0.5


def draw_errors(rng: np.random.Generator) -> ErrorModel:
    """One MEMS unit's 21 errors, uniform within the MEMS sizes `seqdesign verify` draws."""
    return ErrorModel.from_units(rng.uniform(-1.0, 1.0, P.N_PARAMS) * error_half_range("mems"))


def one_run(args):
    """Simulate one MEMS run and calibrate it as the CLI does; errors, sigmas, convergence."""
    sequence, seed = args
    rng = np.random.default_rng(seed)
    errors = draw_errors(rng)
    prof = load_profile("mems")
    cfg = SimConfig(latitude_rad=math.radians(LATITUDE_DEG), sample_rate_hz=SAMPLE_RATE_HZ)
    run, truth = simulate(
        load_sequence(sequence),
        cfg,
        errors,
        prof,
        options=SimOptions(flip_error_deg=FLIP_ERROR_DEG, noise=True, seed=seed, random_setup_deg=SETUP_DEG),
    )
    t0 = time.process_time()
    try:
        res = calibrate(run, prof, requirements="mems", options=CalibrateOptions(require_convergence=False))
    except CalibError as e:  # a refusal is a failed run, counted and named, not a crash
        print(f"seed {seed}: {e}", flush=True)
        return None, None, False, 0, time.process_time() - t0, seed
    return (
        res.values - truth.errors.values,
        res.covariance,
        res.converged,
        res.iterations,
        time.process_time() - t0,
        seed,
    )


def band(n: int, dof: int = P.N_PARAMS) -> tuple[float, float]:
    """99 % band of the mean NEES of n runs: chi-square of n * dof degrees of freedom, over n."""
    lo, hi = chi2.ppf([0.005, 0.995], n * dof)
    return float(lo / n), float(hi / n)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--sequence", default="paper-9pos")
    ap.add_argument("--seed", type=int, default=1400)
    ap.add_argument("--save", help="write each run's errors, covariance and seed to this .npz")
    args = ap.parse_args()
    jobs = [(args.sequence, args.seed + i) for i in range(args.n)]
    wall = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        out = list(pool.map(one_run, jobs))
    wall = time.perf_counter() - wall
    failed = [o[5] for o in out if o[0] is None]
    unconverged = [o[5] for o in out if o[0] is not None and not o[2]]
    out = [o for o in out if o[0] is not None]
    err = np.array([o[0] for o in out])
    cov = np.array([o[1] for o in out])
    if args.save:
        np.savez(args.save, err=err, cov=cov, seeds=np.array([o[5] for o in out]))
    nees = np.array([e @ np.linalg.solve(C, e) for e, C in zip(err, cov, strict=True)])
    ratio = np.sqrt(np.mean(err**2 / np.einsum("nii->ni", cov), axis=0))
    lo, hi = band(len(out))
    iters = np.array([o[3] for o in out])
    print(
        f"{args.sequence}, `mems` profile and requirements, {SAMPLE_RATE_HZ:g} Hz, N = {args.n} "
        f"runs (seeds {args.seed}..{args.seed + args.n - 1}); {platform.machine()}, "
        f"{args.workers} workers, wall {wall / 60:.1f} min, calibrate CPU "
        f"{np.mean([o[4] for o in out]):.1f} s/run"
    )
    print(f"refused (diverged): {failed or 'none'}; not converged: {unconverged or 'none'}")
    print(
        f"converged: {sum(o[2] for o in out)}/{args.n}; iterations median "
        f"{np.median(iters):.0f}, max {iters.max()}"
    )
    verdict = "in" if lo <= nees.mean() <= hi else "OUTSIDE"
    print(
        f"mean NEES {nees.mean():.2f} (99 % band [{lo:.2f}, {hi:.2f}]: {verdict}); "
        f"median {np.median(nees):.1f}, max {nees.max():.1f}"
    )
    print()
    # The standard error of a mean of error/sigma over n runs is its sample spread over sqrt(n):
    # a mean beyond 2 of them is a bias the sigmas do not carry (5 % of parameters by chance).
    print("| parameter | RMS(error/sigma) | mean(error/sigma) | its standard error | in [0.67, 1.36] |")
    print("|---|---|---|---|---|")
    z = err / np.sqrt(np.einsum("nii->ni", cov))
    mean = np.mean(z, axis=0)
    se = np.std(z, axis=0, ddof=1) / math.sqrt(len(z))
    for name, r, m, s in zip(P.NAMES, ratio, mean, se, strict=True):
        print(
            f"| {name} | {r:.2f} | {m:+.2f} | {s:.2f} ({m / s:+.1f} SE) | "
            f"{'yes' if 0.67 <= r <= 1.36 else 'NO'} |"
        )


if __name__ == "__main__":
    main()
