"""Designing runs placed by hand: the Xsens recording's own poses against a design of its length.

    PYTHONPATH=. python benchmarks/by_hand_design.py [--runs 20]

1. imu_tk's Xsens recording (tests/data/realdata) is calibrated by hand; its rests become a pose
   list (each rest's up vector, its length, the moves' lengths) and ``analyze_hand`` predicts it
   with each pose placed within 15 deg.
2. ``design_hand`` for the same length (512 s, the same 52 s start), predicted the same way.
3. A Monte Carlo of noisy simulated runs of each plan (MEMS errors, ``mems`` noise): the worst
   over the 21 of RMS(error) * 3 / requirement, the figure the predictions claim.
Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from calib.calibration.entry import calibrate
from calib.hand.calibrate import hand_fit_of
from calib.hand.poses import PoseList
from calib.hand.simulate import HandStreams, draw_errors, simulate_by_hand
from calib.model.optional_terms import load_optional_terms
from calib.model.requirements import load_requirements
from calib.nav.site import site_of
from calib.noise.profiles import load_profile
from calib.runlog import read_run
from calib.sequence.kinematics import SimConfig
from seqdesign.hand.pose_search import HandDesignOptions, design_hand
from seqdesign.hand.prediction import Placement, analyze_hand
from seqdesign.verify import error_half_range

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "realdata" / "imu_tk-xsens"
MEMS = load_profile("mems")
REQ = load_requirements("mems")
PLACEMENT_DEG = 15.0


def recording_poses() -> PoseList:
    run = read_run(
        DATA / "xsens_acc.mat.gz",
        gyro_path=DATA / "xsens_gyro.mat.gz",
        conversion=DATA / "xsens-nominal-values.txt",
        latitude_deg=45.4,
        height_m=0.0,
    )
    fit, _, _ = hand_fit_of(
        run,
        site_of(run, 9.81744),
        MEMS,
        load_optional_terms(None, by_hand=True),
        False,
        REQ,
        ("g-sensitivity",),
        False,
    )
    rests = fit.data.rests
    period = float(np.median(np.diff(run.time_s)))
    up = np.einsum("kji,j->ki", fit.C_rest, [0.0, 0.0, 1.0])
    holds = (rests.end - rests.start) * period
    moves = (rests.start[1:] - rests.end[:-1]) * period
    return PoseList("xsens-recording", up, holds, moves)


def monte_carlo(poses: PoseList, runs: int) -> float:
    """Worst over the 21 of 3 RMS(error) / requirement over ``runs`` noisy runs of the plan."""
    config = SimConfig(latitude_rad=math.radians(45.4), height_m=0.0, sample_rate_hz=100.0)
    errors = []
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        truth = draw_errors(error_half_range("mems"), rng)
        run, _ = simulate_by_hand(poses.plan(), config, truth, MEMS, streams=HandStreams(noise=rng))
        result = calibrate(run, MEMS, by_hand=True, requirements=REQ)
        errors.append(result.values - truth.values)
    return float(np.max(REQ.ratio(np.sqrt(np.mean(np.square(errors), axis=0)))))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args()
    rows = []
    t0 = time.time()
    own = recording_poses()
    design = design_hand(
        own.duration_s, MEMS, REQ, HandDesignOptions(first_rest_s=float(own.hold_s[0])), name="xsens-length"
    )
    t_design = time.time() - t0
    for label, poses in (("the recording's own poses", own), ("design of its length", design.poses)):
        planned = analyze_hand(poses, MEMS, REQ, latitude_deg=45.4, cure=False)
        placed = analyze_hand(
            poses, MEMS, REQ, latitude_deg=45.4, placement=Placement(PLACEMENT_DEG), cure=False
        )
        mc = monte_carlo(poses, args.runs)
        rows.append(
            (
                label,
                len(poses.up),
                poses.duration_s,
                planned.to_json()["worst"],
                placed.to_json()["worst"],
                mc,
            )
        )
    print(
        f"design search {t_design:.0f} s; bias bound of {own.duration_s:.0f} s: {design.bias_bound_ratio:.3f}"
    )
    print()
    print("| plan | poses | s | worst 3σ/req as planned | placed within 15° | Monte Carlo worst 3 RMS/req |")
    print("|---|---:|---:|---|---|---:|")
    for label, n, dur, w0, w1, mc in rows:
        print(
            f"| {label} | {n} | {dur:.0f} | {w0['ratio']:.3f} ({w0['name']}) "
            f"| {w1['ratio']:.3f} ({w1['name']}) | {mc:.3f} |"
        )
    print()
    placed = rows[0][4]["ratio"] / rows[1][4]["ratio"]
    print(f"own / design, placed: {placed:.2f}x; Monte Carlo: {rows[0][5] / rows[1][5]:.2f}x")


if __name__ == "__main__":
    main()
