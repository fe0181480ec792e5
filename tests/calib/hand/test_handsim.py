"""The simulator of runs placed by hand, against physics derived here.

The rests against gravity and the Earth rate; the increments of a move against the
two-sample coning rule and the strapdown navigator (third order in the sample period);
the trajectory's body rate against its attitude; the errors, the noise, the peak rate;
the plan's shape; the files and the CLI.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import (
    ARCSEC,
    DEG,
    DEG_PER_H,
    PPM,
    SPEC_NAMES,
    UG,
    W_EARTH,
    earth_rate_enu,
    log_so3,
    normal_gravity,
    rodrigues,
    sensor_model,
)

from calib.hand.plan import HandPlan, PlanShape, random_hand_plan, xsens_like_plan
from calib.hand.simulate import draw_errors, simulate_by_hand, true_increments, write_hand_run
from calib.hand.trajectory import hand_state, sensed
from calib.model.error_model import ErrorModel
from calib.nav.site import Site
from calib.nav.strapdown import coning_rotvec, navigate
from calib.nav.transform import quat_mult, quat_to_dcm, rotvec_to_quat
from calib.noise.profiles import load_profile
from calib.runlog import read_run
from calib.sequence.kinematics import SimConfig
from calib.sim.truth import read_truth

LAT = 45.4 * DEG
G = 9.81744  # the Xsens recording's local gravity


def _plan(seed: int = 3, peak_rate_dps: float | None = 1000.0, **kw) -> HandPlan:
    """A short plan: four poses, 1-2 s rests, fast turns."""
    args = dict(first_rest_s=1.0, rest_s=(1.0, 2.0), peak_rate_dps=peak_rate_dps) | kw
    return random_hand_plan(4, np.random.default_rng(seed), PlanShape(**args))


def _rest_samples(plan: HandPlan, time_s: np.ndarray, rate: float, k: int) -> np.ndarray:
    """Indices of the samples whose whole interval lies in rest ``k``."""
    start = time_s - 1.0 / rate
    return np.flatnonzero((start >= plan.rest_start_s[k] - 1e-9) & (time_s <= plan.rest_end_s[k] + 1e-9))


# (a) rests, noise-free and error-free --------------------------------------------------------


def test_rests_sense_gravity_and_earth_rate():
    plan = _plan()
    rate = 100.0
    t, dth, dv = true_increments(plan, Site(LAT, G), rate)
    up, w_ie = np.array([0.0, 0.0, G]), earth_rate_enu(LAT)
    for k in range(plan.n_poses):
        idx = _rest_samples(plan, t, rate, k)
        assert idx.size >= 90
        C = plan.C_b_n[k]
        f = dv[idx].sum(axis=0) / (idx.size / rate)
        w = dth[idx].sum(axis=0) / (idx.size / rate)
        assert np.linalg.norm(f - C.T @ up) < 1e-9 * G
        assert np.linalg.norm(w - C.T @ w_ie) < 1e-9 * W_EARTH


def test_site_gravity_is_normal_gravity_by_default():
    plan = _plan()
    run, _ = simulate_by_hand(plan, SimConfig(latitude_rad=LAT, height_m=200.0, sample_rate_hz=100.0))
    idx = _rest_samples(plan, run.time_s, 100.0, 0)
    f = np.linalg.norm(run.dv_mps[idx], axis=1) * 100.0
    assert np.allclose(f, normal_gravity(LAT, 200.0), rtol=1e-12)
    assert run.meta["motion"] == "by-hand" and "gravity_mps2" not in run.meta


# The trajectory ---------------------------------------------------------------------------------


def test_body_rate_is_the_derivative_of_the_attitude():
    """omega_nb from C^T dC/dt by central differences, Richardson-extrapolated (error O(h^4))."""
    plan = _plan(peak_rate_dps=1500.0)
    t = np.linspace(0.0, plan.duration_s, 4001)[1:-1]
    now = hand_state(plan, t)

    def central(h):
        ahead, back = hand_state(plan, t + h).C_b_n, hand_state(plan, t - h).C_b_n
        rel = np.einsum("nji,njk->nik", now.C_b_n, ahead), np.einsum("nji,njk->nik", now.C_b_n, back)
        return (np.array([log_so3(R) for R in rel[0]]) - np.array([log_so3(R) for R in rel[1]])) / (2 * h)

    estimate = (4.0 * central(5e-6) - central(1e-5)) / 3.0
    peak = np.abs(now.omega_nb_b).max()
    assert peak > math.radians(1000.0)
    assert np.abs(estimate - now.omega_nb_b).max() < 1e-7 * peak
    # Translation: v = dp/dt, a = dv/dt.
    h = 1e-5
    ahead, back = hand_state(plan, t + h), hand_state(plan, t - h)
    assert np.abs((ahead.p_n - back.p_n) / (2 * h) - now.v_n).max() < 1e-8
    assert np.abs((ahead.v_n - back.v_n) / (2 * h) - now.a_n).max() < 1e-7 * np.abs(now.a_n).max()


def test_the_turn_axis_wobbles():
    """Coning is present: the rate's direction in a move is not fixed."""
    plan = _plan()
    t = plan.turn_start_s[0] + plan.turn_s[0] * np.linspace(0.05, 0.95, 50)
    w = hand_state(plan, t).omega_nb_b
    u = w / np.linalg.norm(w, axis=1, keepdims=True)
    spread = np.degrees(np.arccos(np.clip(u @ u[25], -1.0, 1.0))).max()
    assert spread > 5.0


# (b) a move integrated with the two-sample coning rule --------------------------------------


def _move_rotation_errors(plan: HandPlan, rate: float, oversample: int = 10) -> np.ndarray:
    """Per move, the angle between the coning-integrated increments and the truth."""
    t, dth, _ = true_increments(plan, Site(LAT, G), rate, oversample)
    out = []
    for k in range(plan.n_poses - 1):
        i1 = np.flatnonzero(t <= plan.rest_end_s[k] + 1e-9)[-1]  # a rest sample: the rule's first "prev"
        i2 = np.flatnonzero(t - 1.0 / rate >= plan.rest_start_s[k + 1] - 1e-9)[0]
        q = np.array([1.0, 0.0, 0.0, 0.0])
        for r in rotvec_to_quat(coning_rotvec(dth[i1 : i2 + 1])[1:]):
            q = quat_mult(q, r)
        # Body in the inertial frame: C_b_i = R(w_ie t) C_b_n, the ENU frame turning with the Earth.
        expect = plan.C_b_n[k].T @ rodrigues(earth_rate_enu(LAT) * (t[i2] - t[i1])) @ plan.C_b_n[k + 1]
        out.append(np.linalg.norm(log_so3(expect.T @ quat_to_dcm(q))))
    return np.array(out)


def test_a_move_integrates_to_the_next_pose_at_third_order():
    plan = _plan(peak_rate_dps=1000.0)
    slow, fast = _move_rotation_errors(plan, 100.0), _move_rotation_errors(plan, 400.0)
    assert np.all(fast < 1e-6)
    # Third order: a quarter of the period gives 1/64 of the error.
    assert np.all(slow / fast > 45.0) and np.all(slow / fast < 90.0)


def test_the_oversampled_quadrature_has_converged():
    plan = _plan(peak_rate_dps=2000.0)
    _, dth10, dv10 = true_increments(plan, Site(LAT, G), 100.0, oversample=10)
    _, dth40, dv40 = true_increments(plan, Site(LAT, G), 100.0, oversample=40)
    assert np.abs(dth10 - dth40).max() < 1e-12
    assert np.abs(dv10 - dv40).max() < 1e-12


# (c) the velocity at the end of each move ---------------------------------------------------


def _end_velocities(plan: HandPlan, rate: float) -> np.ndarray:
    t, dth, dv = true_increments(plan, Site(LAT, G), rate)
    out = []
    for k in range(plan.n_poses - 1):
        i1 = np.flatnonzero(t <= plan.rest_end_s[k] + 1e-9)[-1]
        i2 = np.flatnonzero(t - 1.0 / rate >= plan.rest_start_s[k + 1] - 1e-9)[0]
        sl = slice(i1 + 1, i2 + 1)
        nav = navigate(dth[sl], dv[sl], t[sl], plan.C_b_n[k], Site(LAT, G), t0=t[i1])
        out.append(np.linalg.norm(nav.v_n[-1]))
    return np.array(out)


def test_carried_out_and_back_the_velocity_returns_to_zero():
    """The strapdown navigator (coning, sculling, gravity, Coriolis) finds the unit still again."""
    plan = _plan(peak_rate_dps=1000.0, translation_m=0.4)
    assert np.all(np.linalg.norm(plan.translation_m, axis=1) >= 0.2)
    coarse, fine = _end_velocities(plan, 200.0), _end_velocities(plan, 800.0)
    assert np.all(fine < 2e-6)
    assert np.all(coarse / fine > 4.0)


def test_a_fine_grid_integration_of_the_truth_returns_to_rest():
    """int (C f - g - 2 w_ie x v) dt over a move, with f from the sensed model: zero."""
    plan = _plan(translation_m=0.4)
    for k in range(plan.n_poses - 1):
        t = np.linspace(plan.rest_end_s[k], plan.rest_start_s[k + 1], 20001)
        state = hand_state(plan, t)
        _, f = sensed(state, Site(LAT, G))
        acc = np.einsum("nij,nj->ni", state.C_b_n, f) - [0.0, 0.0, G]
        acc -= 2.0 * np.cross(earth_rate_enu(LAT), state.v_n)
        h = t[1] - t[0]
        v_end = h / 3.0 * (acc[0] + acc[-1] + 4.0 * acc[1:-1:2].sum(axis=0) + 2.0 * acc[2:-1:2].sum(axis=0))
        assert np.linalg.norm(v_end) < 1e-9
        assert np.abs(state.p_n).max() > 0.1  # it did move


# (d) errors at rest ---------------------------------------------------------------------------

MEMS_HALF_RANGE = np.array(
    [1000.0] * 3 + [5000.0] * 3 + [1000.0] * 6 + [20000.0] * 3 + [5000.0] * 3 + [1000.0] * 3
)
SI = {"bg": DEG_PER_H, "sg": PPM, "mg": ARCSEC, "ba": UG, "sa": PPM, "ma": ARCSEC}


def test_rest_means_are_the_error_model_of_the_truth():
    plan = _plan()
    errors = draw_errors(MEMS_HALF_RANGE, np.random.default_rng(11))
    units = errors.in_units()
    assert np.all(np.abs(units) <= MEMS_HALF_RANGE) and np.abs(units).max() > 0.5 * 1000.0
    values = {n: u * SI[n[:2]] for n, u in zip(SPEC_NAMES, units, strict=True)}
    Mg, bg = sensor_model(values, "gyro")
    Ma, ba = sensor_model(values, "accel")
    run, truth = simulate_by_hand(plan, SimConfig(LAT, sample_rate_hz=100.0, gravity_mps2=G), errors)
    assert truth.errors is errors and not truth.noise
    for k in range(plan.n_poses):
        idx = _rest_samples(plan, run.time_s, 100.0, k)
        C = plan.C_b_n[k]
        w = run.dtheta_rad[idx].mean(axis=0) * 100.0
        f = run.dv_mps[idx].mean(axis=0) * 100.0
        assert np.linalg.norm(w - (Mg @ C.T @ earth_rate_enu(LAT) + bg)) < 1e-12
        assert np.linalg.norm(f - (Ma @ C.T @ [0.0, 0.0, G] + ba)) < 1e-12


# (e) noise -----------------------------------------------------------------------------------


def test_noise_at_rest_has_the_profile_s_density():
    plan = _plan(first_rest_s=200.0)
    profile = load_profile("mems")
    rate = 100.0
    run, truth = simulate_by_hand(plan, SimConfig(LAT, sample_rate_hz=rate), profile=profile, seed=5)
    assert truth.noise and truth.profile == "mems"
    idx = _rest_samples(plan, run.time_s, rate, 0)
    arw = 2.6 * DEG / 60.0  # the mems profile's 2.6 deg/sqrt(h), rad/sqrt(s)
    vrw = 460.0 * UG  # 460 ug/sqrt(Hz)
    std_th = run.dtheta_rad[idx].std(axis=0, ddof=1)
    std_v = run.dv_mps[idx].std(axis=0, ddof=1)
    assert np.allclose(std_th, arw * math.sqrt(1.0 / rate), rtol=0.03)
    assert np.allclose(std_v, vrw * math.sqrt(1.0 / rate), rtol=0.03)


def test_the_same_seed_gives_the_same_run():
    plan = _plan()
    cfg = SimConfig(LAT, sample_rate_hz=100.0)
    a, _ = simulate_by_hand(plan, cfg, profile=load_profile("tactical"), seed=9)
    b, _ = simulate_by_hand(plan, cfg, profile=load_profile("tactical"), seed=9)
    assert np.array_equal(a.dtheta_rad, b.dtheta_rad) and np.array_equal(a.dv_mps, b.dv_mps)


# (f) the peak rate ---------------------------------------------------------------------------


@pytest.mark.parametrize("peak_dps", [1000.0, 2000.0])
def test_the_peak_rate_reaches_the_requested_peak(peak_dps):
    plan = random_hand_plan(12, np.random.default_rng(4), PlanShape(first_rest_s=2.0, peak_rate_dps=peak_dps))
    s = np.linspace(0.0, 1.0, 100001)
    t = (plan.turn_start_s[:, None] + plan.turn_s[:, None] * s[None, :]).ravel()
    true_peak = np.degrees(np.linalg.norm(hand_state(plan, t).omega_nb_b, axis=1).max())
    assert true_peak == pytest.approx(peak_dps, rel=1e-6)
    rate = 100.0
    _, dth, _ = true_increments(plan, Site(LAT, G), rate)
    sampled = np.degrees(np.linalg.norm(dth, axis=1).max() * rate)
    # A sample's mean rate cannot exceed the peak; a 100 Hz sample of a 0.1-0.3 s turn loses < 1 %.
    assert peak_dps * 0.99 < sampled <= peak_dps * (1 + 1e-6) + np.degrees(W_EARTH)


# The plans ---------------------------------------------------------------------------------


def test_random_poses_are_apart_and_moves_end_still():
    plan = random_hand_plan(30, np.random.default_rng(1))
    rel = plan.C_b_n[:-1].transpose(0, 2, 1) @ plan.C_b_n[1:]
    angles = np.degrees([np.linalg.norm(log_so3(R)) for R in rel])
    assert angles.min() >= 30.0
    assert plan.rest_s[0] == 50.0 and np.all((plan.rest_s[1:] >= 5.0) & (plan.rest_s[1:] <= 12.0))
    assert np.all((plan.move_s >= 1.0) & (plan.move_s <= 3.0))
    # Still on the rest's side; on the move's side rate and velocity grow as dt^2 (zero
    # rate, velocity and acceleration where each rest begins and ends).
    for edges, side in ((plan.rest_end_s[:-1], 1.0), (plan.rest_start_s[1:], -1.0)):
        assert np.all(hand_state(plan, edges - side * 1e-4).omega_nb_b == 0.0)
        one, two = hand_state(plan, edges + side * 1e-4), hand_state(plan, edges + side * 2e-4)
        ratio = np.linalg.norm(two.v_n, axis=1) / np.linalg.norm(one.v_n, axis=1)
        assert np.allclose(ratio, 4.0, rtol=0.01)
        turn_edges = plan.turn_start_s + (0.0 if side > 0 else plan.turn_s)
        one = hand_state(plan, turn_edges + side * 1e-4).omega_nb_b
        two = hand_state(plan, turn_edges + side * 2e-4).omega_nb_b
        assert np.allclose(np.linalg.norm(two, axis=1) / np.linalg.norm(one, axis=1), 4.0, rtol=0.01)
    # The attitude at a move's end is the next pose.
    end = hand_state(plan, plan.rest_start_s[1:] - 1e-12).C_b_n
    assert np.abs(end - plan.C_b_n[1:]).max() < 1e-12


def test_translation_off_and_no_wobble():
    plan = random_hand_plan(5, np.random.default_rng(2), PlanShape(translation_m=0.0, wobble_deg=0.0))
    t = np.linspace(0.0, plan.duration_s, 5001)
    s = hand_state(plan, t)
    assert np.abs(s.p_n).max() == 0.0 and np.abs(s.a_n).max() == 0.0
    # No wobble: each turn is about one fixed body axis, the move's rotation vector.
    k = 1
    tm = plan.turn_start_s[k] + plan.turn_s[k] * np.linspace(0.1, 0.9, 9)
    w = hand_state(plan, tm).omega_nb_b
    u = plan.rotvec[k] / np.linalg.norm(plan.rotvec[k])
    assert np.allclose(w / np.linalg.norm(w, axis=1, keepdims=True), u, atol=1e-12)


def test_xsens_like_plan_has_the_recording_s_shape():
    plan = xsens_like_plan(np.random.default_rng(0))
    assert plan.n_poses == 38 and plan.rest_s[0] == 52.0
    assert plan.duration_s == pytest.approx(512.0, abs=1e-9)
    assert np.all((plan.rest_s[1:] > 4.5) & (plan.rest_s[1:] < 13.0))


def test_a_plan_refuses_a_wobble_along_the_turn():
    plan = _plan()
    with pytest.raises(ValueError, match="perpendicular"):
        HandPlan(
            plan.C_b_n,
            plan.rest_s,
            plan.move_s,
            plan.turn_s,
            plan.translation_m,
            plan.wobble_rad,
            plan.rotvec / np.linalg.norm(plan.rotvec, axis=1, keepdims=True),
        )


# Files and the CLI --------------------------------------------------------------------------


def test_run_and_truth_files_round_trip(tmp_path):
    from calib.hand.simulate import plan_from_table
    from calib.io.files import load_toml

    plan = _plan()
    errors = ErrorModel.from_table2()
    run, truth = simulate_by_hand(plan, SimConfig(LAT, sample_rate_hz=100.0, gravity_mps2=G), errors)
    path = tmp_path / "hand.npz"
    truth_path = write_hand_run(path, run, truth)
    back = read_run(path)
    assert np.array_equal(back.dv_mps, run.dv_mps) and back.meta["motion"] == "by-hand"
    assert back.gravity_mps2 == G
    common = read_truth(truth_path)  # the common truth reader takes it as is
    assert np.allclose(common.errors.values, errors.values, rtol=1e-12)
    again = plan_from_table(load_toml(truth_path)["hand"])
    assert np.array_equal(again.C_b_n, plan.C_b_n) and np.array_equal(again.turn_s, plan.turn_s)
    for name in ("rest_s", "move_s", "translation_m", "wobble_axis"):
        assert np.array_equal(getattr(again, name), getattr(plan, name)), name
    assert np.allclose(again.wobble_rad, plan.wobble_rad, rtol=1e-15, atol=0)


def test_cli_simulate_by_hand(tmp_path):
    from seqdesign.cli import main

    out = tmp_path / "hand.csv"
    res = CliRunner().invoke(
        main,
        ["simulate", "--by-hand", "--poses", "4", "--seed", "3", "--random-errors", "mems",
         "--profile", "mems", "--sample-rate-hz", "100", "--peak-rate-dps", "1200", "-o", str(out), "--json"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["poses"] == 4 and doc["motion"] == "by-hand"
    run = read_run(out)
    assert run.sample_rate_hz == 100.0 and run.meta["motion"] == "by-hand"
    truth = load_truth_doc(tmp_path / "hand.truth.toml")
    assert len(truth["hand"]["rest_start_s"]) == 4
    assert np.abs(truth["errors"]["bgx"]) <= 1000.0
    peak = np.degrees(np.linalg.norm(run.dtheta_rad, axis=1).max() * 100.0)
    assert 1100.0 < peak < 1300.0  # noise aside, within a few per cent of the requested peak


def load_truth_doc(path):
    from calib.io.files import load_toml

    return load_toml(path)


def test_cli_by_hand_refusals(tmp_path):
    from seqdesign.cli import main

    runner = CliRunner()
    res = runner.invoke(main, ["simulate", "-o", str(tmp_path / "x.npz")])
    assert res.exit_code == 2 and "SEQUENCE" in res.output
    res = runner.invoke(main, ["simulate", "paper-9pos", "--by-hand", "-o", str(tmp_path / "x.npz")])
    assert res.exit_code == 2 and "--by-hand" in res.output
    res = runner.invoke(main, ["simulate", "paper-9pos", "--poses", "4", "-o", str(tmp_path / "x.npz")])
    assert res.exit_code == 2 and "--poses" in res.output and "--by-hand" in res.output
    res = runner.invoke(main, ["simulate", "--by-hand", "--stream", "-o", str(tmp_path / "x.npz")])
    assert res.exit_code == 2 and "--stream" in res.output
    assert not (tmp_path / "x.npz").exists()
