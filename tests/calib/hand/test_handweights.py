"""Weights the data earn and a model the data choose (calib.hand.weights, calib.hand.calibrate).

Simulated hand runs whose truth is known: noise the profile states keeps the profile's
weights and the 21 alone; noise twice the profile's earns a white factor of 2, and five
times earns its own (most of a group beyond the profile is no outlier); a move that does
not fit is weighted by its own residual and spoils nothing, nor makes a good rest an
outlier (a rest's specific force is one only where the rests alone say so); a gyro g-sensitivity is fitted
when it is there and not when it is not.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.stats import chi2

from calib.calibration.entry import calibrate
from calib.hand import weights as W
from calib.hand.plan import HAND_POSES, random_hand_plan, xsens_like_plan
from calib.hand.simulate import simulate_by_hand
from calib.hand.troubles import HandTroubles, g_sensitivity_from_dphg, scale_each_turn
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.nav.strapdown import sample_intervals
from calib.noise.profiles import load_profile
from calib.sequence.kinematics import SimConfig

MEMS = load_profile("mems")
CFG = SimConfig(latitude_rad=math.radians(45.0), height_m=0.0, sample_rate_hz=100.0)
VALUES = np.zeros(21)
VALUES[0:3] = np.radians([0.2, -0.3, 0.1])
VALUES[3:6] = [3e-3, -2e-3, 4e-3]
VALUES[12:15] = [0.05, -0.03, 0.08]
VALUES[15:18] = [2e-3, 3e-3, -1e-3]


def _run(seed: int, profile=MEMS, troubles=None):
    plan = xsens_like_plan(np.random.default_rng(seed))
    run, _ = simulate_by_hand(plan, CFG, ErrorModel(VALUES), profile, seed=seed + 1000, troubles=troubles)
    return run


def test_noise_the_profile_states_keeps_its_weights_and_the_21_alone():
    result = calibrate(_run(1), MEMS, by_hand=True)
    doc = result.by_hand.choices
    assert doc["weights"]["white_factor"] == {"force": 1.0, "rate": 1.0, "move": 1.0}
    assert doc["model"][0]["fitted"] is False and doc["model"][0]["how"] == "tested"
    # chi2/dof of white noise: 1 within a few sqrt(2/dof) (dof about 300).
    assert 0.75 < result.chi2_per_dof < 1.25


# Slow (tens of seconds: several hand fits, each now testing the bias drift too); run in CI.
@pytest.mark.slow
def test_noise_twice_the_profiles_earns_a_factor_of_two():
    loud = dataclasses.replace(
        MEMS, gyro_arw_dph=2.0 * MEMS.gyro_arw_dph, accel_vrw_ug=2.0 * MEMS.accel_vrw_ug, name="loud"
    )
    result = calibrate(_run(2, profile=loud), MEMS, by_hand=True)
    white = result.by_hand.choices["weights"]["white_factor"]
    # Each group earns the 2 (a rest's own wander beyond white noise, calib.hand.data, is a trembling
    # pose's, not a louder white noise). A factor is known to about 1/sqrt(2 r) of itself (r its
    # redundancy, 70-110 per group here: 7-9 %); 25 % is about three of those.
    for group in ("force", "rate", "move"):
        assert white[group] == pytest.approx(2.0, rel=0.25), (group, white)
    assert 0.75 < result.chi2_per_dof < 1.25
    # The sigmas carry it: every error within 4 of them (21 normal draws stay within 4 with 99.9 %;
    # at the profile's weights the moves' sigmas would be half what they are).
    assert np.all(np.abs(result.values - VALUES) < 4 * result.sigma)


def test_noise_five_times_the_profiles_is_the_profiles_fault_not_a_majority_of_outliers():
    # An uncalibrated consumer MEMS (scale factors of 2-3 %, misalignments of 1-1.5 deg) five
    # times noisier than the profile the user names. Judged at the profile's level, 11 of this
    # run's blocks were called outliers, the quietest moves left then "confirmed" the profile
    # (move white factor 1.0), and the errors came out at up to 8 of their sigmas.
    big = P.to_si(np.array(
        [3500, -3000, 2000, 30000, -25000, 20000, 5400, -3600, 4000, -5000, 3000, -4500,
         45000, -40000, 48000, 30000, -20000, 25000, 5000, -4000, 3500.0]
    ))  # fmt: skip
    loud = dataclasses.replace(
        MEMS, gyro_arw_dph=5.0 * MEMS.gyro_arw_dph, accel_vrw_ug=5.0 * MEMS.accel_vrw_ug, name="loud"
    )
    plan = random_hand_plan(HAND_POSES, np.random.default_rng(3))
    run, _ = simulate_by_hand(plan, CFG, ErrorModel(big), loud, seed=1003)
    result = calibrate(run, MEMS, by_hand=True)
    weights = result.by_hand.choices["weights"]
    # Honest blocks are outliers one time in 10^4 each (about 75 blocks here).
    assert len(weights["outliers"]) <= 1, weights["outliers"]
    # A move's residual is its turn's gyro white noise alone, so the moves earn the 5 (known to
    # 7-9 % of itself, as in the factor-of-two test; 30 % is more than three of those). The rests
    # share their 5 with the floor each rest may have (a wandering bias), so only more than 1
    # is theirs to show.
    assert weights["white_factor"]["move"] == pytest.approx(5.0, rel=0.3), weights
    assert min(weights["white_factor"].values()) > 1.2, weights
    # 21 normal draws stay within 4 sigma with 99.9 %.
    z = (result.values - big) / result.sigma
    assert np.all(np.abs(z) < 4), np.round(z, 2)


# Slow (tens of seconds: several hand fits, each now testing the bias drift too); run in CI.
@pytest.mark.slow
def test_a_move_that_does_not_fit_is_weighted_by_its_own_residual_and_spoils_nothing():
    run = _run(3)
    clean = calibrate(run, MEMS, by_hand=True)
    # A 2 deg turn about x slipped into the middle of move 10 (a logger glitch, a bump).
    start, end = clean.by_hand.move_s[9]
    k = int(np.searchsorted(run.time_s, 0.5 * (start + end)))
    dtheta = run.dtheta_rad.copy()
    dtheta[k, 0] += math.radians(2.0)
    bent = dataclasses.replace(run, dtheta_rad=dtheta)
    earned = calibrate(bent, MEMS, by_hand=True)
    outliers = earned.by_hand.choices["weights"]["outliers"]
    assert [o["index"] for o in outliers if o["kind"] == "move"] == [10]
    # The accelerometer's nine stay where the clean run put them (a tenth of a sigma); at the
    # profile's weights the bent move pulls them further.
    accel = slice(12, 21)
    moved = np.abs(earned.values[accel] - clean.values[accel]) / clean.sigma[accel]
    assert moved.max() < 0.1, np.round(moved, 3)


@pytest.mark.parametrize("seed", [9, 16])
def test_moves_that_do_not_fit_do_not_make_a_good_rest_an_outlier(seed):
    # Twelve rests, every one truly still (nothing was injected into them), and moves whose gyro
    # scale is off by its own 0.5 % each. The moves bend the chained attitudes and, with so few
    # rests, pull the accelerometer until one rest's |f| misses: judged in the joint fit, that
    # rest was called an outlier (x15 on both seeds), its weight went and the pull grew (an
    # accelerometer error of 3.6 sigma on seed 16). The rests alone confirm every rest's |f|, so
    # none is an outlier now, and the moves carry their own misfit.
    plan = random_hand_plan(12, np.random.default_rng(seed))
    run, _ = simulate_by_hand(plan, CFG, ErrorModel(VALUES), MEMS, seed=seed + 1000)
    bent = scale_each_turn(run, 0.005, np.random.default_rng(seed + 2000))
    result = calibrate(bent, MEMS, by_hand=True)
    outliers = result.by_hand.choices["weights"]["outliers"]
    assert not [o for o in outliers if o["kind"] == "force"], outliers
    # The nine accelerometer errors within 3 of their sigmas (nine normal draws do so with 97.6 %).
    accel = slice(12, 21)
    z = (result.values[accel] - VALUES[accel]) / result.sigma[accel]
    assert np.all(np.abs(z) < 3.0), np.round(z, 2)


def test_a_rest_whose_magnitude_is_off_is_still_an_outlier():
    # The unit pressed down while it rests: its specific force reads 0.05 m/s^2 more along gravity
    # there (60 of the rest's white-noise sigmas). The rests alone see that |f| is not g, so the
    # block is an outlier, weighted by its own residual, and the accelerometer keeps to its truth.
    run = _run(4)
    clean = calibrate(run, MEMS, by_hand=True)
    start, end = clean.by_hand.rest_s[7]
    inside = (run.time_s > start - 1.0) & (run.time_s <= end + 1.0)
    dt = np.diff(np.r_[0.0, run.time_s])
    f = run.dv_mps[inside] / dt[inside, None]
    up = f.mean(axis=0) / np.linalg.norm(f.mean(axis=0))
    dv = run.dv_mps.copy()
    dv[inside] += 0.05 * up * dt[inside, None]
    pressed = calibrate(dataclasses.replace(run, dv_mps=dv), MEMS, by_hand=True)
    outliers = pressed.by_hand.choices["weights"]["outliers"]
    assert {(o["kind"], o["index"]) for o in outliers} == {("force", 8)}, outliers
    # 21 normal draws stay within 4 sigma with 99.9 %.
    assert np.all(np.abs(pressed.values - VALUES) < 4 * pressed.sigma)


def test_two_recordings_spliced_leave_the_second_a_loose_block_named_in_rests_not_states():
    # Two runs of the same unit spliced end to end: the "move" across the seam jumps between
    # unrelated attitudes, so it is weighted out by its own residual and nothing ties the second
    # run's heading to the first's (gravity cannot see a turn about the vertical). That block is
    # named by its rests; the 21 do not depend on it (none unobserved, each within 4 sigma of the
    # truth: 21 normal draws stay within 4 with 99.9 %), and no line names a fitted state.
    from calib.hand.plan import random_hand_plan

    parts = []
    for seed in (5, 6):
        plan = random_hand_plan(10, np.random.default_rng(seed))
        parts.append(simulate_by_hand(plan, CFG, ErrorModel(VALUES), MEMS, seed=seed + 1000)[0])
    a, b = parts
    period = float(np.median(np.diff(a.time_s)))
    spliced = dataclasses.replace(
        a,
        time_s=np.concatenate([a.time_s, b.time_s - b.time_s[0] + a.time_s[-1] + period]),
        dtheta_rad=np.vstack([a.dtheta_rad, b.dtheta_rad]),
        dv_mps=np.vstack([a.dv_mps, b.dv_mps]),
    )
    result = calibrate(spliced, MEMS, by_hand=True)
    seam = [o["index"] for o in result.by_hand.choices["weights"]["outliers"] if o["kind"] == "move"]
    assert seam == [10]
    assert result.by_hand.choices["loose_rests"] == [
        "rests 11-20 turn together about the vertical: no move that fits ties them to the others, "
        "so their common heading is free (the 21 parameters do not depend on it)"
    ]
    assert not result.null_directions and not result.not_estimable
    assert np.all(np.abs(result.values - VALUES) < 4 * result.sigma)
    said = " ".join([*result.by_hand.lines(), *result.warnings()])
    assert "rest11_" not in said and "_U" not in said, said


@pytest.mark.slow
@pytest.mark.parametrize("log", ["imu0.log.gz", "imu1.log.gz"])
def test_a_real_recording_with_its_halves_swapped_calibrates_as_the_recording_does(log):
    # mikoff's MPU-9150 log written second half first: the same samples, but the "move" across
    # the seam jumps tens of degrees between unrelated attitudes. Chaining the start through it
    # used to drag the first rounds so far that good rests were weighted out as outliers and the
    # sigmas came out 0.7-1.3x the recording's. Only the seam move (and the move cut at the old
    # end) is lost, so every sigma stays within 20 % of the recording's (one move of ~30), no rest
    # is an outlier, and each estimate stays within 0.6 sigma of the recording's (their difference
    # is the information of the lost moves: sigma*sqrt(1.2^2 - 1) = 0.66 sigma at most).
    from realdata import MIKOFF

    from calib.runlog import read_run

    columns = "1=accel_x_mps2,2=accel_y_mps2,3=accel_z_mps2,4=gyro_x_radps,5=gyro_y_radps,6=gyro_z_radps"
    run = read_run(MIKOFF / log, columns=columns, sample_rate_hz=100.0, latitude_deg=55.0, height_m=100.0)
    half = len(run.time_s) // 2
    swapped = dataclasses.replace(
        run,
        dtheta_rad=np.vstack([run.dtheta_rad[half:], run.dtheta_rad[:half]]),
        dv_mps=np.vstack([run.dv_mps[half:], run.dv_mps[:half]]),
    )
    base = calibrate(run, MEMS, by_hand=True)
    result = calibrate(swapped, MEMS, by_hand=True)
    kinds = {o["kind"] for o in result.by_hand.choices["weights"]["outliers"]}
    assert kinds == {"move"}
    assert len(result.by_hand.choices["loose_rests"]) == 1
    assert not result.null_directions and not result.not_estimable
    ratio = result.sigma / base.sigma
    assert np.all((ratio > 0.8) & (ratio < 1.2)), ratio
    assert np.all(np.abs(result.values - base.values) < 0.6 * base.sigma)


@pytest.mark.slow
def test_a_g_sensitivity_that_is_there_is_fitted_and_recovered():
    G = g_sensitivity_from_dphg([300, -200, 150, 100, -250, 200, -150, 120, 280])
    result = calibrate(_run(4, troubles=HandTroubles(g_sensitivity=G)), MEMS, by_hand=True)
    model = result.by_hand.choices["model"][0]
    assert model["fitted"] is True and model["p"] < 1e-3
    part = result.extras.index("g-sensitivity")
    fitted = np.asarray(result.extra_values)[part]
    sigma = np.asarray(result.extra_sigma)[part]
    # Each of the nine within 4 sigma of the truth (36 draws of a normal stay within 4 with 99.8 %).
    assert np.all(np.abs(fitted - G.reshape(9)) < 4 * sigma)


@pytest.mark.slow
def test_monte_carlo_of_trembling_jittering_g_sensitive_hand_runs_is_honest():
    # Eight Xsens-shaped hand runs, each with its own MEMS errors, poses held in a trembling hand
    # (0.2 deg), a g-sensitivity of up to 300 deg/h/g and host stamps up to 12 ms late (read back
    # from a file as a user's log is), calibrated with the defaults (the model and the weights the
    # data choose). The mean NEES of 8 honest runs of 21 parameters lies in the 99 % band of
    # chi2(168)/8; the 50-run figures are in BENCHMARKS.md.
    from click.testing import CliRunner

    from seqdesign.cli import main

    args = ["verify", "--by-hand", "--like", "xsens", "--profile", "mems", "--requirements", "mems"]
    args += ["--runs", "8", "--workers", "1", "--sample-rate-hz", "100", "--seed", "1", "--json"]
    args += ["--tremor-deg", "0.2", "--g-sensitivity-dphg", "300", "--stamp-jitter-ms", "12"]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["converged"] == 8 and not doc["refused"]
    lo, hi = chi2.ppf([0.005, 0.995], 8 * 21) / 8
    assert lo < doc["nees"]["mean"] < hi, doc["nees"]


def _turning_bias(run, rate_dps: float):
    """The run with a constant rate about x added while the unit turns (a response the model lacks)."""
    dt = sample_intervals(run.time_s)
    turning = np.linalg.norm(run.dtheta_rad, axis=1) / dt > 0.1
    dtheta = run.dtheta_rad.copy()
    dtheta[turning, 0] += math.radians(rate_dps) * dt[turning]
    return dataclasses.replace(run, dtheta_rad=dtheta)


def test_a_quiet_gyro_earns_its_weights_once_the_moves_that_hid_it_are_weighted():
    # A gyro five times quieter than the profile, whose turns carry 0.2 deg/s the model lacks.
    # At the profile's weights those moves drag the gyro biases, and the rests' rates then
    # look as noisy as the profile says; weighted by their own, they no longer do. Judged at
    # the first look only, the rates kept the profile's weights: chi2/dof 0.47 and gyro bias
    # sigmas five times what the rests show (measured). Judged again once the moves are
    # weighted, they earn theirs.
    quiet = dataclasses.replace(MEMS, gyro_arw_dph=MEMS.gyro_arw_dph / 5.0, name="quiet")
    result = calibrate(_turning_bias(_run(4, profile=quiet), 0.2), MEMS, by_hand=True)
    white = result.by_hand.choices["weights"]["white_factor"]
    # The rests' rates share their 1/5 with a floor per rest, so less than half is theirs to show.
    assert white["rate"] < 0.5 and white["move"] > 2.0, white
    assert 0.75 < result.chi2_per_dof < 1.25  # as for white noise, above
    # The gyro biases come from the rests, their sigmas now the rests' own: within 4 of them.
    bias = slice(0, 3)
    assert np.all(np.abs(result.values[bias] - VALUES[bias]) < 4 * result.sigma[bias])


def _second_look(rate_power: float):
    """refuted_later on groups of 10 three-axis blocks of redundancy 1 per row, the moves earning,
    the rest specific force at its chi2's mean and the rest rates at ``rate_power``."""
    labels = [(g, i) for g in ("force", "rate", "move") for i in range(10) for _ in range(3)]
    e = np.ones(len(labels))
    rates = np.array([lab[0] == "rate" for lab in labels])
    e[rates] = math.sqrt(rate_power / rates.sum())  # the group's whitened power, shared evenly
    return W.refuted_later(
        W.Weights(earning=("move",)), e, np.ones(len(labels)), labels, np.ones(len(labels))
    )


def test_the_second_look_calls_a_group_quieter_only_on_strong_evidence():
    # Rates that passed the first look, now at the 0.4 % quantile of a chi2 on 30: honest noise
    # does that one time in 250, and weights moving elsewhere bring such a group there (simulated
    # runs of the profile's noise: 18 on 30 at the first look, 13 on 29 once the rest earned
    # theirs). Called quieter at the first look's one-sided 0.5 %, its sigmas shrank below the
    # noise's: the hand Monte Carlo's mean NEES rose from 22.86 to 23.26 of a band ending at 23.44.
    assert _second_look(float(chi2.ppf(0.004, 30))) is None
    # At one in twenty thousand (a real phone's gyro: 7.2 on 27 once its moves were weighted) it is.
    later = _second_look(float(chi2.ppf(5e-5, 30)))
    assert later is not None and later.earning == ("move", "rate")
