"""A log's setup mistakes (calib.sim.log_mistakes) break the physics a diagnosis checks, each its own way.

On a clean simulated hand run: the rests' specific force is ``g`` in m/s^2, and across each move the
gyro's turn carries the gravity direction of one rest into the next (``f_(k+1) = R^T f_k``; the Earth
turns ~2e-4 rad meanwhile, the tolerance of the correct log). Each mistake breaks one of these.
"""

from __future__ import annotations

import numpy as np
import pytest

from calib.hand.plan import PlanShape, random_hand_plan
from calib.hand.simulate import simulate_by_hand
from calib.nav.strapdown import coning_rotvec
from calib.nav.transform import quat_mult, quat_to_dcm, rotvec_to_quat
from calib.sequence.kinematics import SimConfig
from calib.sim.log_mistakes import (
    MISTAKES,
    accel_in_g,
    axes_swapped,
    axis_flipped,
    gyro_accel_swapped,
    gyro_in_deg,
    rate_mislabelled,
)

G = 9.81
RATE = 100.0


@pytest.fixture(scope="module")
def clean():
    plan = random_hand_plan(
        6, np.random.default_rng(8), PlanShape(first_rest_s=5.0, rest_s=(3.0, 4.0), peak_rate_dps=400.0)
    )
    run, _ = simulate_by_hand(plan, SimConfig(latitude_rad=0.8, sample_rate_hz=RATE, gravity_mps2=G))
    return plan, run


def _rests(plan, run):
    """Sample indices of each rest (whole intervals, 0.2 s in from each end)."""
    t, dt = run.time_s, 1.0 / run.sample_rate_hz
    return [
        np.flatnonzero((t - dt >= a + 0.2) & (t <= b - 0.2))
        for a, b in zip(plan.rest_start_s, plan.rest_end_s, strict=True)
    ]


def _rotation(dtheta):
    q = np.array([1.0, 0.0, 0.0, 0.0])
    for r in rotvec_to_quat(coning_rotvec(dtheta)):
        q = quat_mult(q, r)
    return quat_to_dcm(q)


def _gravity_mismatch(plan, run) -> np.ndarray:
    """Per move: the angle between ``f_(k+1)`` and the gyro's turn applied to ``f_k``, rad."""
    rests = _rests(plan, run)
    out = []
    for k in range(plan.n_poses - 1):
        f0, f1 = run.dv_mps[rests[k]].mean(axis=0), run.dv_mps[rests[k + 1]].mean(axis=0)
        R = _rotation(run.dtheta_rad[rests[k][-1] + 1 : rests[k + 1][0]])
        a, b = R.T @ f0, f1
        out.append(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b))
    return np.array(out)


def _rest_force(plan, run, samples_of=None) -> np.ndarray:
    """|mean specific force| of each rest, per the log's own period (rests found in ``samples_of``)."""
    rests = _rests(plan, samples_of if samples_of is not None else run)
    return np.array([np.linalg.norm(run.dv_mps[i].mean(axis=0)) * run.sample_rate_hz for i in rests])


def test_the_correct_log_is_consistent(clean):
    plan, run = clean
    assert np.allclose(_rest_force(plan, run), G, rtol=1e-9)
    assert _gravity_mismatch(plan, run).max() < 1e-3


def test_accelerometer_in_g_reads_one_at_rest(clean):
    plan, run = clean
    wrong = accel_in_g(run)
    assert np.allclose(_rest_force(plan, wrong), G / 9.80665, rtol=1e-9)
    assert _gravity_mismatch(plan, wrong).max() < 1e-3  # directions are untouched
    assert np.array_equal(run.dv_mps[:5], clean[1].dv_mps[:5])  # the argument is left alone


@pytest.mark.parametrize("mistake", [gyro_in_deg, axes_swapped, axis_flipped])
def test_gyro_mistakes_break_the_gravity_carried_across_moves(clean, mistake):
    plan, run = clean
    wrong = mistake(run)
    assert np.allclose(_rest_force(plan, wrong), G, rtol=1e-9)  # the accelerometer is right
    assert _gravity_mismatch(plan, wrong).max() > 0.1


def test_swapped_triads_read_the_earth_rate_as_specific_force(clean):
    plan, run = clean
    wrong = gyro_accel_swapped(run)
    assert np.all(_rest_force(plan, wrong) < 1e-4)  # the Earth rate, 7.3e-5 rad/s
    assert np.array_equal(wrong.dtheta_rad, run.dv_mps) and np.array_equal(wrong.dv_mps, run.dtheta_rad)


def test_axis_mistakes_act_on_the_named_axes(clean):
    _, run = clean
    swapped = axes_swapped(run, "accel", ("x", "z"))
    assert np.array_equal(swapped.dv_mps[:, [2, 1, 0]], run.dv_mps)
    flipped = axis_flipped(run, "gyro", 1)
    assert np.array_equal(flipped.dtheta_rad * [1, -1, 1], run.dtheta_rad)
    for bad in (lambda: axes_swapped(run, "gyro", ("x", "x")), lambda: axis_flipped(run, "mag", "x")):
        with pytest.raises(ValueError):
            bad()


def test_a_rate_log_read_at_the_wrong_rate_scales_the_turns(clean):
    """A 102.4 Hz rate log read at 100 Hz: each turn reads 1.024 times its angle, rests stay g."""
    plan, run = clean
    wrong = rate_mislabelled(run, RATE / 1.024)
    assert wrong.sample_rate_hz == RATE / 1.024 and wrong.n_samples == run.n_samples
    assert np.allclose(_rest_force(plan, wrong, samples_of=run), G, rtol=1e-9)
    rests = _rests(plan, run)
    for k in range(plan.n_poses - 1):
        sl = slice(rests[k][-1] + 1, rests[k + 1][0])
        turn, turn0 = wrong.dtheta_rad[sl].sum(axis=0), run.dtheta_rad[sl].sum(axis=0)
        assert np.allclose(turn, 1.024 * turn0, rtol=1e-12)


def test_every_named_mistake_changes_the_log(clean):
    _, run = clean
    for name, mistake in MISTAKES.items():
        wrong = mistake(run)
        changed = not (
            np.array_equal(wrong.dtheta_rad, run.dtheta_rad) and np.array_equal(wrong.dv_mps, run.dv_mps)
        )
        assert changed, name
