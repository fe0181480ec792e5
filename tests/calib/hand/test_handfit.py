"""The fit of runs placed by hand: its move rule, its Jacobian, its rests, and exact recovery.

The synthetic runs here are built from closed forms independent of the fit:
rests at chosen attitudes (gravity and the Earth rate projected exactly), and
moves that turn at a constant rate about a fixed body axis (then the gyro
increments are exactly ``omega h`` and the rotation is ``exp(omega T)``, which
coning does not touch), with the 21-parameter errors applied to the true
increments and the specific force during a move set by a carried translation.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from calib.errors import CalibError
from calib.hand.fit_options import HandFitOptions, HandSamples
from calib.hand.joint_fit import FitState, Layout, fit_by_hand, hand_data, linearise
from calib.hand.moves import move_rotation, move_sensitivity
from calib.hand.rests import brief_pose_lines, find_rests
from calib.hand.rounding import rounding_floor
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.model.requirements import load_requirements
from calib.nav import earth
from calib.nav.site import Site
from calib.nav.transform import dcm_to_rotvec, rotvec_to_dcm
from calib.noise.profiles import NoiseProfile
from calib.runlog.coarse import reading_step
from seqdesign.cli import main

LAT = math.radians(45.0)
G = 9.80
RATE_HZ = 100.0
PROFILE = NoiseProfile("test", 2.6, 460.0)
MEMS_REQUIREMENTS = load_requirements("mems")  # a MEMS unit's (the paper's would call every sigma weak)


def _random_rotation(rng) -> np.ndarray:
    return rotvec_to_dcm(rng.normal(size=3) * 2.0)


def synthetic_hand_run(
    rng, errors: ErrorModel, n_poses: int = 14, g_sens=None, carry: bool = True, rest_s: float = 4.0
):
    """Rests of ``rest_s`` at random attitudes, joined by constant-rate turns about fixed body axes.

    Returns time, dtheta, dv, dt and the true rest attitudes (Earth-fixed: the turn
    is relative to the Earth, the gyros sense it plus the Earth rate).
    """
    h = 1.0 / RATE_HZ
    omega_n = earth.omega_ie_n(LAT)
    f_n = earth.specific_force_n(G)
    C = _random_rotation(rng)
    dth, dvs, Cs = [], [], [C]
    for k in range(n_poses):
        n_rest = int(round(rest_s * RATE_HZ))
        dth.append(np.tile(C.T @ omega_n * h, (n_rest, 1)))
        dvs.append(np.tile(C.T @ f_n * h, (n_rest, 1)))
        if k == n_poses - 1:
            break
        # A turn of 60-150 deg about a random body axis in 0.5 s (fast, like a hand's).
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = math.radians(rng.uniform(60, 150))
        n_move = 50
        w_b = axis * angle / (n_move * h)
        # The specific force in the body while turning: gravity seen in the turning attitude,
        # plus a carried translation (out and back, zero velocity at both ends). The gyros add
        # the Earth rate seen in that attitude (midpoint rule: h^3 w^2 Omega ~ 1e-12 rad).
        tt = (np.arange(n_move) + 0.5) * h
        Ct = C @ rotvec_to_dcm(np.outer(tt, w_b))
        steps = (w_b + np.einsum("nji,j->ni", Ct, omega_n)) * h
        a_n = np.zeros((n_move, 3))
        if carry:
            T = n_move * h
            a_n[:, 0] = 2.0 * (2 * np.pi / T) ** 2 * 0.05 * np.cos(2 * np.pi * tt / T)
        dv_move = np.einsum("nji,nj->ni", Ct, a_n + f_n) * h
        dth.append(steps)
        dvs.append(dv_move)
        C = C @ rotvec_to_dcm(w_b * n_move * h)
        Cs.append(C)
    dtheta = np.vstack(dth)
    dv = np.vstack(dvs)
    dt = np.full(len(dtheta), h)
    dtheta_m, dv_m = errors.apply(dtheta, dv, dt)
    if g_sens is not None:  # w_meas = A_g w + b_g + G f, with f the true specific force
        dtheta_m = dtheta_m + dv @ g_sens.T
    return np.cumsum(dt), dtheta_m, dv_m, dt, np.array(Cs)


def test_a_constant_rate_turn_is_integrated_exactly():
    # About a fixed axis the coning term vanishes and the product of exp(w h) is exp(w T).
    w = np.array([3.0, -7.0, 5.0])  # rad/s: 500 deg/s, fast as a hand
    h = 0.01
    R, _, _ = move_rotation(np.tile(w * h, (40, 1)), w * h)
    assert np.allclose(dcm_to_rotvec(R.T @ rotvec_to_dcm(w * 40 * h)), 0.0, atol=1e-12)


def test_move_sensitivity_matches_finite_differences():
    # A coning move (the axis itself turns): the first-order sensitivity of the move's end to
    # the gyro bias, matrix and g-sensitivity equals central differences of the exact rule.
    rng = np.random.default_rng(3)
    n, h = 120, 0.01
    t = np.arange(n) * h
    dtheta = np.column_stack([4 * np.sin(3 * t), 3 * np.cos(2 * t), 2 + np.sin(5 * t)]) * h
    dv = rng.normal(size=(n, 3)) * h
    A = np.eye(3) + rng.normal(size=(3, 3)) * 0.02
    b = rng.normal(size=3) * 0.01
    Gs = rng.normal(size=(3, 3)) * 1e-3
    dt = np.full(n, h)

    def end(A, b, Gs):
        A_inv = np.linalg.inv(A)
        c = (dtheta - b * h - dv @ Gs.T) @ A_inv.T
        prev = (dtheta[0] - b * h - dv[0] @ Gs.T) @ A_inv.T
        return move_rotation(c, prev)[0]

    A_inv = np.linalg.inv(A)
    c = (dtheta - b * h - dv @ Gs.T) @ A_inv.T
    prev = (dtheta[0] - b * h - dv[0] @ Gs.T) @ A_inv.T
    R, Q, phi = move_rotation(c, prev)
    G_b, G_A, G_G = move_sensitivity(c, dt, A_inv, R, Q, phi, dv)
    eps = 1e-6
    for j in range(3):
        d = np.zeros(3)
        d[j] = eps
        num = (dcm_to_rotvec(R.T @ end(A, b + d, Gs)) - dcm_to_rotvec(R.T @ end(A, b - d, Gs))) / (2 * eps)
        # The coning term's own derivative is left out of the sensitivity: it is second order
        # in the angle per sample (0.05 rad here), so agreement to 1e-3 relative is the physics.
        assert np.allclose(num, -G_b[:, j], rtol=2e-3, atol=2e-3 * np.abs(G_b).max())
        for k in range(3):
            dA = np.zeros((3, 3))
            dA[j, k] = eps
            num = (dcm_to_rotvec(R.T @ end(A + dA, b, Gs)) - dcm_to_rotvec(R.T @ end(A - dA, b, Gs))) / (
                2 * eps
            )
            assert np.allclose(num, -G_A[:, j, k], atol=2e-3 * np.abs(G_A).max())
            num = (dcm_to_rotvec(R.T @ end(A, b, Gs + dA)) - dcm_to_rotvec(R.T @ end(A, b, Gs - dA))) / (
                2 * eps
            )
            assert np.allclose(num, -G_G[:, j, k], atol=2e-3 * np.abs(G_G).max())


def test_the_fit_jacobian_matches_finite_differences():
    rng = np.random.default_rng(5)
    errors = ErrorModel(_mems_errors(rng))
    time_s, dtheta, dv, dt, C_true = synthetic_hand_run(rng, errors, n_poses=5)
    data = hand_data(dtheta, dv, dt, PROFILE)
    layout = Layout(data.count, True)
    # Near the truth, as a Gauss-Newton iterate is (the moves' rows are linearised about a small residual).
    C0 = np.array([rotvec_to_dcm(rng.normal(size=3) * 0.01) @ C for C in C_true])
    state = FitState(errors.values * 0.9, rng.normal(size=(3, 3)) * 1e-4, np.array([1e-5, 2e-5]), C0)
    samples, site = HandSamples(dtheta, dv, dt), Site(LAT, G)
    e, s, J, _ = linearise(data, samples, state, layout, site, PROFILE)
    scale = np.concatenate([np.abs(errors.values) + 1e-6, np.full(layout.n - 21, 1e-4)])
    for i in rng.choice(layout.n, 25, replace=False):
        step = np.zeros(layout.n)
        step[i] = 1e-4 * scale[i]
        plus = FitState(state.values.copy(), state.G.copy(), state.h.copy(), state.C.copy())
        minus = FitState(state.values.copy(), state.G.copy(), state.h.copy(), state.C.copy())
        plus.update(step, layout)
        minus.update(-step, layout)
        ep = linearise(data, samples, plus, layout, site, PROFILE)[0]
        em = linearise(data, samples, minus, layout, site, PROFILE)[0]
        numeric = -(ep - em) / (2 * step[i])
        # The Jacobian is the prediction's (residual = data - prediction); the moves' rows drop the
        # coning term's derivative and the residual's own rotation (both second order): 1 %.
        assert np.allclose(numeric, J[:, i], rtol=0.0, atol=0.01 * np.abs(J[:, i]).max() + 1e-12), i


def _mems_errors(rng) -> np.ndarray:
    """Errors of MEMS size (biases 0.3 deg/s and 30 mg, scale factors 1 %, misalignments 0.5 deg)."""
    v = np.zeros(21)
    v[P.GYRO_BIAS] = rng.uniform(-1, 1, 3) * math.radians(0.3)
    v[P.GYRO_SCALE] = rng.uniform(-1, 1, 3) * 0.01
    v[P.GYRO_MISALIGNMENT] = rng.uniform(-1, 1, 6) * math.radians(0.5)
    v[P.ACCEL_BIAS] = rng.uniform(-1, 1, 3) * 0.3
    v[P.ACCEL_SCALE] = rng.uniform(-1, 1, 3) * 0.01
    v[P.ACCEL_MISALIGNMENT] = rng.uniform(-1, 1, 3) * math.radians(0.5)
    return v


@pytest.mark.parametrize("g_sensitivity", [False, True])
def test_a_noise_free_hand_run_is_recovered_exactly(g_sensitivity):
    rng = np.random.default_rng(11)
    errors = ErrorModel(_mems_errors(rng))
    G_true = rng.uniform(-1, 1, (3, 3)) * 300 * P.DEG_PER_HOUR / 9.8 if g_sensitivity else None
    time_s, dtheta, dv, dt, C_true = synthetic_hand_run(rng, errors, g_sens=G_true)
    # Without the heading prior: a prior is information, and pulls a noise-free estimate by a little.
    options = HandFitOptions(g_sensitivity=g_sensitivity, heading_prior=False, requirements=MEMS_REQUIREMENTS)
    fit = fit_by_hand(HandSamples(dtheta, dv, dt), Site(LAT, G), PROFILE, options, where="synthetic")
    assert fit.converged and fit.data.count == len(C_true)
    sigma = np.sqrt(np.diag(fit.covariance))[:21]
    # Noise free, what is left is the midpoint rules of the synthetic run (1e-8 rad per move
    # against sigmas of 1e-3 rad): far below a hundredth of a sigma.
    assert np.all(np.abs(fit.values - errors.values) < 0.01 * sigma)
    if g_sensitivity:
        assert np.allclose(
            fit.g_sensitivity, G_true, atol=0.01 * np.sqrt(np.diag(fit.covariance))[21:30].min()
        )
    # The rests' attitudes up to the first rest's heading (the frame's).
    tilt = [
        np.degrees(np.arccos(np.clip((a.T @ [0, 0, 1]) @ (b.T @ [0, 0, 1]), -1, 1)))
        for a, b in zip(fit.C_rest, C_true, strict=True)
    ]
    assert max(tilt) < 1e-3


def _noisy_poses(rng, n_poses: int, rest_s: float):
    """A synthetic hand run of error-free sensors with the profile's white noise: dtheta, dv, dt."""
    _, dtheta, dv, dt, _ = synthetic_hand_run(rng, ErrorModel.zero(), n_poses=n_poses, rest_s=rest_s)
    dtheta = dtheta + PROFILE.arw * np.sqrt(dt)[:, None] * rng.normal(size=dtheta.shape)
    dv = dv + PROFILE.vrw * np.sqrt(dt)[:, None] * rng.normal(size=dv.shape)
    return dtheta, dv, dt


def test_rests_are_found_with_a_bump_and_short_poses():
    dtheta, dv, dt = _noisy_poses(np.random.default_rng(2), n_poses=6, rest_s=4.0)
    # A bump (0.1 s tap of 1 m/s^2) in the middle of the third rest.
    i = 2 * (400 + 50) + 200
    dv[i : i + 10] += np.array([1.0, 0.0, 0.0]) * dt[0]
    rests = find_rests(dtheta, dv, dt, PROFILE.arw, PROFILE.vrw)
    # Six poses, the third split by the bump into two rests of ~1.1 s each (each side of a
    # disturbance loses the detector's reach, about 0.4 s), both kept.
    assert rests.count == 7
    lengths = (rests.end - rests.start) * dt[0]
    assert np.all(lengths > 0.5) and np.all(lengths <= 4.0)


def test_poses_held_a_second_and_a_fifth_are_each_a_rest_of_still_samples():
    # A quick hand holds each pose 1.2 s. Every verdict of the finder clears a motion it sees by
    # at most half its 0.25 s window (centred, or the drift's windows a window and a half out
    # less the window they average) plus a window and the 0.05 s margin: 0.425 s each side,
    # leaving 0.35 s of each pose, above the 0.15 s a rest needs. No turning sample may be in one.
    n_poses, rest_s = 8, 1.2
    dtheta, dv, dt = _noisy_poses(np.random.default_rng(5), n_poses, rest_s)
    rests = find_rests(dtheta, dv, dt, PROFILE.arw, PROFILE.vrw)
    assert rests.count == n_poses and len(rests.brief_start) == 0
    pose, turn = int(round(rest_s * RATE_HZ)), 50  # samples, as synthetic_hand_run lays them
    for k, (a, b) in enumerate(zip(rests.start, rests.end, strict=True)):
        first = k * (pose + turn)
        assert first <= a and b <= first + pose  # wholly inside its own pose
        assert (b - a) * dt[0] >= 0.15


def test_poses_held_under_a_second_give_no_rest_and_are_said_to_be_brief():
    # Poses of 0.7 s between two moves: the finder's reach (0.425 s each side) leaves nothing of
    # them, so none may give a rest; but their windows see no motion for 0.45 s (the pose less
    # half a window each side), so each is a brief pose, named at its own time. The first and
    # last poses meet a move on one side only and keep a rest (0.7 - 0.425 s).
    n_poses, rest_s = 8, 0.7
    dtheta, dv, dt = _noisy_poses(np.random.default_rng(5), n_poses, rest_s)
    rests = find_rests(dtheta, dv, dt, PROFILE.arw, PROFILE.vrw)
    pose, turn = int(round(rest_s * RATE_HZ)), 50
    first = np.arange(n_poses) * (pose + turn)
    assert rests.count == 2 and rests.start[0] == 0 and rests.end[-1] == len(dt)  # the two ends only
    assert len(rests.brief_start) == n_poses - 2
    for k, (a, b) in enumerate(zip(rests.brief_start, rests.brief_end, strict=True)):
        assert first[k + 1] <= a and b <= first[k + 1] + pose
    time_s = np.cumsum(dt) - dt[0]
    said = brief_pose_lines(rests, time_s)
    assert len(said) == 1 and said[0].startswith(f"{n_poses - 2} pose(s) held too briefly")
    assert f"from {time_s[rests.brief_start[0]]:.1f}," in said[0]
    # Cut the two end poses away (the log starts and ends mid-turn): no rest is left, and the
    # refusal counts the brief poses (those whose windows still see them quiet, the run's steady
    # rate now taken from a log 40 % turning) and says how long to hold one.
    middle = slice(first[1] - turn // 2, first[-1] - turn // 2)
    with pytest.raises(CalibError, match=r"; \d pose\(s\) held too briefly for a rest") as refused:
        find_rests(dtheta[middle], dv[middle], dt[middle], PROFILE.arw, PROFILE.vrw, "brief.csv")
    assert "hold each pose still for 1.0 s or more" in str(refused.value)


def test_long_poses_noisier_than_the_profile_are_not_said_to_be_brief():
    # Poses of 4 s whose accelerometer is noisier than the profile (spread about the threshold): the
    # still verdict breaks, and windows quiet by chance are no brief poses (no turn bounds them).
    # The refusal must not tell a user who held each pose 4 s to hold them longer.
    rng = np.random.default_rng(5)
    _, dtheta, dv, dt, _ = synthetic_hand_run(rng, ErrorModel.zero(), n_poses=8)
    dtheta = dtheta + PROFILE.arw * np.sqrt(dt)[:, None] * rng.normal(size=dtheta.shape)
    dv = dv + 0.2 * dt[:, None] * rng.normal(size=dv.shape)  # m/s^2 a sample, the threshold 0.18
    try:
        rests = find_rests(dtheta, dv, dt, PROFILE.arw, PROFILE.vrw)
    except CalibError as refused:
        assert "held too briefly" not in str(refused), str(refused)
    else:
        assert len(rests.brief_start) == 0


def test_how_long_a_pose_must_be_held_follows_the_log_s_rate():
    # At 4 Hz the finder's window is three samples (0.75 s, not 0.25 s) and the 0.05 s margin no
    # sample: each rest is kept 1.5 windows, 1.125 s, clear of a move, and a pose must be held
    # 0.15 + 2 x 1.125 = 2.4 s to give a rest. What a user is told says so, not 100 Hz's 1.0 s.
    rng = np.random.default_rng(5)
    _, dtheta, dv, dt, _ = synthetic_hand_run(rng, ErrorModel.zero(), n_poses=6)
    block = 25  # 100 Hz summed to 4 Hz
    n = len(dt) // block * block
    dtheta, dv, dt = (x[:n].reshape(n // block, block, *x.shape[1:]).sum(axis=1) for x in (dtheta, dv, dt))
    rests = find_rests(dtheta, dv, dt, PROFILE.arw, PROFILE.vrw)
    assert rests.reach_s == pytest.approx(1.125, rel=1e-9)
    assert rests.shortest_pose_s == pytest.approx(2.4, rel=1e-9)


def test_too_few_rests_are_refused_saying_why():
    h = 0.01
    n = 3000
    dtheta = np.tile([0.5 * h, 0.0, 0.0], (n, 1))  # turning the whole time
    dv = np.tile([0.0, 0.0, G * h], (n, 1))
    with pytest.raises(CalibError, match="rest"):
        find_rests(dtheta, dv, np.full(n, h), PROFILE.arw, PROFILE.vrw, "spin.csv")


def test_poses_that_never_tip_x_are_refused_naming_parameters_not_states():
    # Rests 90 deg apart about the body x axis, turned about x alone: gravity never lies along x
    # and the gyro never turns about y or z, so the x accelerometer's scale factor and the gyro's
    # y and z scale factors cannot be seen. The refusal names parameter combinations only (the
    # fit's own state names mean nothing to a user).
    h = 1.0 / RATE_HZ
    omega_n, f_n = earth.omega_ie_n(LAT), earth.specific_force_n(G)
    dth, dvs = [], []
    w_b = np.array([math.radians(90.0) / 0.5, 0.0, 0.0])
    for k in range(8):
        C = rotvec_to_dcm(np.array([math.radians(90.0 * k), 0.0, 0.0]))
        dth.append(np.tile(C.T @ omega_n * h, (400, 1)))
        dvs.append(np.tile(C.T @ f_n * h, (400, 1)))
        if k < 7:
            tt = (np.arange(50) + 0.5) * h
            Ct = C @ rotvec_to_dcm(np.outer(tt, w_b))
            dth.append((w_b + np.einsum("nji,j->ni", Ct, omega_n)) * h)
            dvs.append(np.einsum("nji,j->ni", Ct, f_n) * h)
    dtheta, dv = np.vstack(dth), np.vstack(dvs)
    options = HandFitOptions(requirements=MEMS_REQUIREMENTS)
    with pytest.raises(CalibError, match="do not separate every parameter") as refused:
        samples = HandSamples(dtheta, dv, np.full(len(dv), h))
        fit_by_hand(samples, Site(LAT, G), PROFILE, options, where="x.csv")
    said = str(refused.value)
    combinations = said.split("unobserved combinations: ")[1]
    assert "sax" in combinations and "sgy" in combinations and "sgz" in combinations, said
    assert "rest" not in combinations and "earth_rate" not in combinations, said


def test_reading_steps_are_found_on_any_grid_and_not_in_floats():
    rng = np.random.default_rng(8)
    whole_dps = np.radians(rng.integers(-300, 300, 5000).astype(float))  # a gyro printed in whole deg/s
    assert reading_step(whole_dps) == pytest.approx(math.radians(1.0), rel=1e-9)
    counts = (rng.integers(0, 65536, 5000) - 32768.4) * 0.061e-3 * 9.80665  # counts less a zero, scaled
    assert reading_step(counts) == pytest.approx(0.061e-3 * 9.80665, rel=1e-9)
    assert reading_step(rng.normal(size=5000)) == 0.0  # full floats: no grid


def test_a_rest_mean_s_rounding_error_is_bounded_by_the_floor():
    # The RMS over true values spread across a step (2000 of them) of a rest mean's rounding
    # error. No noise: uniform over a step, q / sqrt(12), which the floor is (to 3 %: the
    # sampling error of 2000 values). Some noise (0.3 step): the floor, taken at the noise's
    # lower bound from the rounded scatter, is no smaller at any true value. A step of noise
    # dithers it: the floor is below a fiftieth of the rest's own white noise (1 / sqrt(400)),
    # 0.02 % of it in quadrature.
    q = 1.0
    rng = np.random.default_rng(9)
    x = rng.uniform(0.0, q, 2000)
    assert np.sqrt(np.mean((np.round(x) - x) ** 2)) == pytest.approx(
        rounding_floor(np.zeros(400), q), rel=0.03
    )
    noisy = [np.round(v + 0.3 * rng.normal(size=400)) for v in x]
    rms = np.sqrt(np.mean([(r.mean() - v) ** 2 for r, v in zip(noisy, x, strict=True)]))
    assert min(rounding_floor(r, q) for r in noisy[:200]) >= rms
    assert rounding_floor(np.round(0.3 + rng.normal(size=400)), q) < 0.02 * (q / np.sqrt(400))


def test_a_gyro_printed_coarser_than_its_noise_reports_a_bias_sigma_its_rests_can_back(tmp_path):
    # A quiet gyro (a tenth of the profile's noise) printed in whole deg/s: at every rest it
    # reads its bias and the Earth's rate rounded, the same value, whatever the bias within half
    # a step. The fit's bias sigmas must cover their errors (within 3 sigma), where the rests'
    # 400 samples alone would claim a few deg/h, and need not exceed the rounding's own bound.
    rng = np.random.default_rng(12)
    values = np.zeros(P.N_PARAMS)
    values[P.GYRO_BIAS] = np.radians([0.31, -0.22, 0.12])  # deg/s, within half a step
    _, dtheta, dv, dt, _ = synthetic_hand_run(rng, ErrorModel(values), n_poses=14)
    quiet = NoiseProfile("quiet", 0.26, 46.0)  # a tenth of PROFILE's ARW and VRW
    dtheta = dtheta + quiet.arw * np.sqrt(dt)[:, None] * rng.normal(size=dtheta.shape)
    dv = dv + quiet.vrw * np.sqrt(dt)[:, None] * rng.normal(size=dv.shape)
    step = math.radians(1.0)
    dtheta = np.round(dtheta / dt[:, None] / step) * step * dt[:, None]
    options = HandFitOptions(requirements=MEMS_REQUIREMENTS)
    fit = fit_by_hand(HandSamples(dtheta, dv, dt), Site(LAT, G), PROFILE, options, where="rounded")
    assert fit.data.reading_steps[1] == pytest.approx([step] * 3, rel=1e-9)
    sigma = np.sqrt(np.diag(fit.covariance))[P.GYRO_BIAS]
    error = fit.values[P.GYRO_BIAS] - values[P.GYRO_BIAS]
    assert np.all(np.abs(error) < 3.0 * sigma)
    assert np.all(sigma < 1.1 * step / math.sqrt(12.0))
    # Through the CLI, as its logger wrote it (whole deg/s), the same is said in --json.
    log = tmp_path / "rounded.csv"
    rows = np.column_stack([np.cumsum(dt), np.degrees(dtheta / dt[:, None]), dv / dt[:, None]])
    np.savetxt(log, rows, delimiter=",", fmt=["%.2f", "%.0f", "%.0f", "%.0f", "%.6f", "%.6f", "%.6f"],
               header="t,gx,gy,gz,ax,ay,az", comments="")  # fmt: skip
    columns = (
        "t=time_s,gx=gyro_x_dps,gy=gyro_y_dps,gz=gyro_z_dps,ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2"
    )
    done = CliRunner().invoke(
        main,
        ["calibrate", str(log), "--by-hand", "--profile", "mems", "--latitude", "45", "--height", "0",
         "--columns", columns, "-o", str(tmp_path / "r.toml"), "--json"],
    )  # fmt: skip
    assert done.exit_code == 0, done.output
    said = json.loads(done.stdout)["by_hand"]["rounding"]
    assert len(said) == 1 and "steps of 1, 1, 1 deg/s" in said[0]


def test_an_accelerometer_printed_coarser_than_its_noise_reports_sigmas_its_rests_can_back():
    # A quiet accelerometer (a tenth of the profile's noise, 4.5 mm/s^2 a sample) printed in steps
    # of 0.05 m/s^2: each rest's mean is off by its rounding, up to half a step, q / sqrt(12) RMS
    # over the poses' gravity projections, where 400 samples of the profile's noise alone would
    # claim 2.3 mm/s^2. That floor is each rest's (the projections differ from pose to pose), so the
    # nine accelerometer parameters' sigmas must cover their errors (within 3 sigma), by the floor
    # alone: weights earned from the residuals would cover them too, so they are not earned here.
    rng = np.random.default_rng(21)
    values = _mems_errors(rng)
    _, dtheta, dv, dt, _ = synthetic_hand_run(rng, ErrorModel(values), n_poses=14)
    quiet = NoiseProfile("quiet", 0.26, 46.0)
    dtheta = dtheta + PROFILE.arw * np.sqrt(dt)[:, None] * rng.normal(size=dtheta.shape)
    dv = dv + quiet.vrw * np.sqrt(dt)[:, None] * rng.normal(size=dv.shape)
    step = 0.05
    dv = np.round(dv / dt[:, None] / step) * step * dt[:, None]
    options = HandFitOptions(requirements=MEMS_REQUIREMENTS, earn_weights=False)
    fit = fit_by_hand(HandSamples(dtheta, dv, dt), Site(LAT, G), PROFILE, options, where="rounded")
    assert fit.data.reading_steps[0] == pytest.approx([step] * 3, rel=1e-9)
    accel = slice(P.ACCEL_BIAS.start, P.ACCEL_MISALIGNMENT.stop)  # the nine, in order
    sigma = np.sqrt(np.diag(fit.covariance))[accel]
    error = fit.values[accel] - values[accel]
    assert np.all(np.abs(error) < 3.0 * sigma), dict(
        zip(np.array(P.NAMES)[accel], error / sigma, strict=True)
    )


def test_a_rest_loose_alone_is_named_as_one_rest_and_a_block_as_rests():
    # Two parameters and three rests (the first rest's two tilts, the others' three angles), every
    # unknown tied down by its own row but the listed vertical turns: those alone are free.
    from calib.hand.weak import split_weak
    from calib.model.information import scaled_inverse

    names = ["p1", "p2", "r1e", "r1n", "r2e", "r2n", "r2u", "r3e", "r3n", "r3u"]
    columns = [np.array([2, 3]), np.array([4, 5, 6]), np.array([7, 8, 9])]
    for free, said in (
        ([6], "rest 2 turns alone about the vertical: no move that fits ties it to the others"),
        ([6, 9], "rests 2-3 turn together about the vertical: no move that fits ties them to the others"),
    ):
        tied = np.eye(len(names))[[k for k in range(len(names)) if k not in free]]
        if len(free) == 2:  # the two turn as one: only their difference is seen
            tied = np.vstack([tied, np.eye(len(names))[6] - np.eye(len(names))[9]])
        parameters, rests = split_weak(scaled_inverse(tied.T @ tied, names=names), 2, columns)
        assert parameters == [] and len(rests) == 1 and rests[0].startswith(said), rests
