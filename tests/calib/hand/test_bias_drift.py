"""Biases that drift over a hand run (a unit still warming up) are chosen and fitted.

The drift is linear in time, ``b_a + d (t - t_last)``: the fit chooses it only when the
likelihood ratio and the term's own size both pass 0.001 (:mod:`calib.hand.calibrate`), and
then gives the biases at the last rest. A run without drift keeps the 21 alone. The gyros'
bias drift alike (``b_g + d_g (t - t_last)``), each move's increments reading the bias of its
own time.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.calibration.correction import correction_of_result
from calib.calibration.entry import CalibrateOptions, calibrate
from calib.hand.plan import xsens_like_plan
from calib.hand.simulate import simulate_by_hand
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.model.optional_terms import (
    ACCEL_BIAS_DRIFT,
    BIAS_DRIFT_SI_PER_UNIT,
    GYRO_BIAS_DRIFT,
    GYRO_DRIFT_SI_PER_UNIT,
)
from calib.noise.profiles import load_profile
from calib.runlog.run import Run
from calib.sequence.kinematics import SimConfig

MEMS = load_profile("mems")
CFG = SimConfig(latitude_rad=math.radians(45.0), height_m=0.0, sample_rate_hz=100.0)
VALUES = np.zeros(21)
VALUES[0:3] = np.radians([0.2, -0.3, 0.1])
VALUES[3:6] = [3e-3, -2e-3, 4e-3]
VALUES[12:15] = [0.05, -0.03, 0.08]  # the biases at the run's end, m/s^2
VALUES[15:18] = [2e-3, 3e-3, -1e-3]
DRIFT_UG_MIN = np.array([-700.0, 250.0, 0.0])  # a RealSense T265's, measured (BENCHMARKS.md)
GYRO_DRIFT_DPH_MIN = np.array([-43.5, 6.7, 0.0])  # a wireless IMU's BMI160, measured (BENCHMARKS.md)


def _run(seed: int, drift_ug_min: np.ndarray, gyro_dph_min=(0.0, 0.0, 0.0)) -> tuple[Run, np.ndarray]:
    """A hand run whose accelerometer (and gyro) biases move linearly, reaching VALUES at its last
    sample; returns the run and the accelerometers' drift (SI).
    """
    plan = xsens_like_plan(np.random.default_rng(seed))
    run, _ = simulate_by_hand(plan, CFG, ErrorModel(VALUES), MEMS, seed=seed + 1000)
    drift = drift_ug_min * BIAS_DRIFT_SI_PER_UNIT
    dt = np.diff(np.concatenate([[run.time_s[0] - 0.01], run.time_s]))
    since_end = run.time_s - 0.5 * dt - run.time_s[-1]  # each sample's interval's middle
    dv = run.dv_mps + np.outer(since_end, drift) * dt[:, None]
    gyro_drift = np.asarray(gyro_dph_min) * GYRO_DRIFT_SI_PER_UNIT
    dtheta = run.dtheta_rad + np.outer(since_end, gyro_drift) * dt[:, None]
    return Run(run.time_s, dtheta, dv, run.meta), drift


def _model(result, term: str) -> dict:
    return next(m for m in result.by_hand.choices["model"] if m["term"] == term)


@pytest.mark.slow
def test_a_drifting_accelerometer_bias_is_chosen_and_recovered_at_the_last_rest():
    run, drift = _run(3, DRIFT_UG_MIN)
    run.meta["time_origin_s"] = repr(1.7e9)  # stamped in UNIX time: the correction's times are absolute
    result = calibrate(run, MEMS, by_hand=True)
    choice = _model(result, ACCEL_BIAS_DRIFT)
    assert choice["fitted"] is True and choice["p"] < 1e-3 and choice["p_wald"] < 1e-3
    part = result.extras.index(ACCEL_BIAS_DRIFT)
    fitted, sigma = np.asarray(result.extra_values)[part], np.asarray(result.extra_sigma)[part]
    # Three draws of a normal stay within 4 sigma with 99.98 %.
    assert np.all(np.abs(fitted - drift) < 4 * sigma), (fitted / BIAS_DRIFT_SI_PER_UNIT, sigma)
    # The biases are the last rest's: the truth there is VALUES less the drift to the run's end.
    at = float(np.mean(result.by_hand.rest_s[-1]))
    assert any(f"the last rest's, at {at:.1f} s" in note for note in result.by_hand.notes)
    last_rest_middle = at + float(run.time_s[0] - 0.01)
    truth = VALUES[P.ACCEL_BIAS] + drift * (last_rest_middle - float(run.time_s[-1]))
    z = (result.values[P.ACCEL_BIAS] - truth) / result.sigma[P.ACCEL_BIAS]
    assert np.all(np.abs(z) < 4), z
    # The scale factors and misalignments are the drift-free truth's (the drift absorbed).
    others = np.r_[P.ACCEL_SCALE, P.ACCEL_MISALIGNMENT]
    assert np.all(np.abs((result.values[others] - VALUES[others]) / result.sigma[others]) < 4)
    # The correction carries the drift on the run's own time: at the first rest, five minutes
    # before the last, its bias is the truth there within 4 sigma (the last rest's sigma and the
    # drift's times the lag, added as if independent: their positive correlation only makes
    # the true sigma smaller), where the one bias is 3.5 mg (tens of sigma) away.
    c = correction_of_result(result, run=run)
    first = float(np.mean(result.by_hand.rest_s[0])) + float(run.time_s[0] - 0.01)
    lag = first - (c.bias_time_s - 1.7e9)
    truth_first = VALUES[P.ACCEL_BIAS] + drift * (first - float(run.time_s[-1]))
    sigma_first = np.hypot(c.accel.sigma_b, c.accel.sigma_drift * lag)
    assert np.all(np.abs(c.accel.bias_at(np.array([lag]))[0] - truth_first) < 4 * sigma_first)
    assert np.abs(c.accel.b[0] - truth_first[0]) > 10 * sigma_first[0]


@pytest.mark.slow
def test_a_steady_bias_keeps_the_21_alone_and_the_drift_can_be_forced():
    run, _ = _run(3, np.zeros(3))
    result = calibrate(run, MEMS, by_hand=True)
    choice = _model(result, ACCEL_BIAS_DRIFT)
    assert choice["fitted"] is False and choice["how"] == "tested"
    assert ACCEL_BIAS_DRIFT not in result.extras.groups
    forced = calibrate(run, MEMS, by_hand=True, extras=ACCEL_BIAS_DRIFT)
    assert _model(forced, ACCEL_BIAS_DRIFT)["how"] == "forced in"
    part = forced.extras.index(ACCEL_BIAS_DRIFT)
    # No drift in the data: the fitted one is zero within 4 sigma.
    assert np.all(np.abs(np.asarray(forced.extra_values)[part]) < 4 * np.asarray(forced.extra_sigma)[part])


@pytest.mark.slow
def test_a_drifting_gyro_bias_is_chosen_and_recovered_at_the_last_rest():
    run, _ = _run(4, np.zeros(3), GYRO_DRIFT_DPH_MIN)
    drift = GYRO_DRIFT_DPH_MIN * GYRO_DRIFT_SI_PER_UNIT
    result = calibrate(run, MEMS, by_hand=True)
    choice = _model(result, GYRO_BIAS_DRIFT)
    assert choice["fitted"] is True and choice["p"] < 1e-3 and choice["p_wald"] < 1e-3
    assert _model(result, ACCEL_BIAS_DRIFT)["fitted"] is False  # the accelerometers' holds still
    part = result.extras.index(GYRO_BIAS_DRIFT)
    fitted, sigma = np.asarray(result.extra_values)[part], np.asarray(result.extra_sigma)[part]
    assert np.all(np.abs(fitted - drift) < 4 * sigma), (fitted / GYRO_DRIFT_SI_PER_UNIT, sigma)  # as above
    # The gyro biases are the last rest's: VALUES less the drift from there to the run's end.
    at = float(np.mean(result.by_hand.rest_s[-1]))
    truth = VALUES[P.GYRO_BIAS] + drift * (at + float(run.time_s[0] - 0.01) - float(run.time_s[-1]))
    z = (result.values[P.GYRO_BIAS] - truth) / result.sigma[P.GYRO_BIAS]
    assert np.all(np.abs(z) < 4), z
    # Unfitted, the drift would leave the x bias the run's mean: 170 deg/h (20 sigma) from its end.
    steady = calibrate(run, MEMS, by_hand=True, options=CalibrateOptions(without=GYRO_BIAS_DRIFT))
    assert _model(steady, GYRO_BIAS_DRIFT)["how"] == "forced out"
    assert abs(steady.values[0] - truth[0]) > 4 * steady.sigma[0]
