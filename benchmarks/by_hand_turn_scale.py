"""Moves that do not fit, on a recording of few rests: are good rests weighted out?

Simulates ``--runs`` hand runs of 12 rests (random poses, MEMS-sized errors, the mems
profile's noise), each move's gyro scaled by its own ``1 + 0.5 % N(0, 1)``
(:func:`calib.hand.troubles.scale_each_turn`: a model the fit lacks; the rests are exactly
still), calibrates each as a user would (``calibrate(run, "mems", by_hand=True)``) and counts
the runs where a rest's specific force was weighted out as an outlier (none is one) and the
accelerometer's errors over their sigmas.

    PYTHONPATH=. .venv/bin/python benchmarks/by_hand_turn_scale.py [--runs 30] [--sd 0.005]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from calib.calibration.entry import calibrate
from calib.hand.plan import random_hand_plan
from calib.hand.simulate import simulate_by_hand
from calib.hand.troubles import scale_each_turn
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.sequence.kinematics import SimConfig

POSES = 12
ACCEL = slice(12, 21)


def errors() -> np.ndarray:
    """MEMS-sized errors (SI): gyro bias and scale, accelerometer bias and scale."""
    values = np.zeros(21)
    values[0:3] = np.radians([0.2, -0.3, 0.1])
    values[3:6] = [3e-3, -2e-3, 4e-3]
    values[12:15] = [0.05, -0.03, 0.08]
    values[15:18] = [2e-3, 3e-3, -1e-3]
    return values


def one_run(seed: int, sd: float, values: np.ndarray) -> tuple[list, np.ndarray]:
    """The force blocks weighted out and the 21 errors over their sigmas of one run."""
    profile = load_profile("mems")
    cfg = SimConfig(latitude_rad=math.radians(45.0), height_m=0.0, sample_rate_hz=100.0)
    plan = random_hand_plan(POSES, np.random.default_rng(seed))
    run, _ = simulate_by_hand(plan, cfg, ErrorModel(values), profile, seed=seed + 1000)
    result = calibrate(scale_each_turn(run, sd, np.random.default_rng(seed + 2000)), profile, by_hand=True)
    outliers = result.by_hand.choices["weights"]["outliers"]
    forces = [(o["index"], round(o["sigma_scale"], 1)) for o in outliers if o["kind"] == "force"]
    return forces, (result.values - values) / result.sigma


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--sd", type=float, default=0.005, help="each turn's scale spread (0.005: 0.5 %%)")
    args = ap.parse_args()
    values = errors()
    flagged, z_runs = 0, []
    print("| seed | rest forces weighted out (rest, x) | accelerometer max \\|error\\|/sigma |")
    print("|---:|---|---:|")
    for seed in range(args.runs):
        forces, z = one_run(seed, args.sd, values)
        flagged += bool(forces)
        z_runs.append(z)
        print(f"| {seed} | {forces or '-'} | {np.abs(z[ACCEL]).max():.2f} |", flush=True)
    z_all = np.array(z_runs)[:, ACCEL]
    print()
    print(
        f"- {flagged} of {args.runs} runs weighted out a rest's specific force; the accelerometer's nine: "
        f"RMS(error/sigma) {math.sqrt(float(np.mean(z_all**2))):.2f}, largest {np.abs(z_all).max():.2f}, "
        f"runs with one beyond 3 sigma {int((np.abs(z_all).max(axis=1) > 3).sum())}"
    )
    rms = np.sqrt(np.mean(np.square(z_runs), axis=0))
    print(
        "- RMS(error/sigma) of each of the 21: "
        + ", ".join(f"{n} {r:.2f}" for n, r in zip(P.NAMES, rms, strict=True))
    )


if __name__ == "__main__":
    main()
