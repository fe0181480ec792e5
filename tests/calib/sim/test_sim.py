"""Simulator: rest physics, flips, injected errors, noise, flip errors, determinism, truth files."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import (
    ARW_NAV,
    DWELL_S,
    FLIP_S,
    LAT_DEG,
    N_POS,
    SETUP_DEG,
    SPEC_NAMES,
    VRW_NAV,
    W_EARTH,
    attitude,
    earth_rate_enu,
    log_so3,
    normal_gravity,
    pre_attitudes,
    rest_window,
    rodrigues,
    rot_about,
    sensor_model,
    table1_gimbal,
    table_column_si,
)

from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.sequence.definition import Sequence, Step
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, Truth, simulate
from calib.sim.truth import read_truth, write_truth

FS = 200.0
DT = 1.0 / FS
LAT = math.radians(LAT_DEG)
R_SETUP = rodrigues(np.radians(SETUP_DEG))
TRIM_S = 10.0  # the "middle" of a rest: drop 10 s at each end


def middle(run, k):
    """Mask of samples lying entirely inside the middle of rest position k."""
    t0, t1 = rest_window(k)
    return (run.time_s > t0 + TRIM_S + DT / 2) & (run.time_s <= t1 - TRIM_S + DT / 2)


def mean_rates(run, k):
    sel = middle(run, k)
    T = sel.sum() * DT
    return run.dtheta_rad[sel].sum(0) / T, run.dv_mps[sel].sum(0) / T, T


def true_rest_physics(k):
    """Body-frame Earth rate and specific force at position k, from Table 1 and R_setup."""
    C = R_SETUP @ pre_attitudes()[k - 1]
    g = normal_gravity(LAT, 0.0)
    return C.T @ earth_rate_enu(LAT), C.T @ np.array([0.0, 0.0, g])


@pytest.fixture(scope="module")
def table2_sim(paper_seq):
    cfg = SimConfig(latitude_rad=LAT)
    return simulate(
        paper_seq,
        cfg,
        ErrorModel.from_table2(),
        load_profile("navigation"),
        options=SimOptions(setup_rotvec=np.radians(SETUP_DEG), noise=False, seed=2),
    )


@pytest.fixture(scope="module")
def noisy_sim(paper_seq):
    cfg = SimConfig(latitude_rad=LAT)
    return simulate(
        paper_seq,
        cfg,
        ErrorModel.from_table2(),
        load_profile("navigation"),
        options=SimOptions(setup_rotvec=np.radians(SETUP_DEG), noise=True, seed=7),
    )


def test_run_shape_and_time(clean_sim):
    run, truth, _ = clean_sim
    n = int(round((9 * DWELL_S + 8 * FLIP_S) * FS))
    assert run.time_s.shape == (n,) and run.dtheta_rad.shape == (n, 3) and run.dv_mps.shape == (n, 3)
    # time_s ends each interval: the first is one period after 0, the last the sequence's end.
    assert run.time_s[0] == pytest.approx(DT, abs=1e-15)
    assert run.time_s[-1] == pytest.approx(9 * DWELL_S + 8 * FLIP_S, abs=1e-9)
    np.testing.assert_allclose(np.diff(run.time_s), DT, atol=1e-9)
    assert float(run.meta["latitude_deg"]) == pytest.approx(LAT_DEG, abs=1e-12)
    assert float(run.meta["sample_rate_hz"]) == FS
    np.testing.assert_allclose(truth.setup_rotvec, np.radians(SETUP_DEG), rtol=1e-15)


@pytest.mark.parametrize("k", range(1, N_POS + 1))
def test_rest_error_free_equals_gravity_and_earth_rate(clean_sim, k):
    run, _, _ = clean_sim
    w, f, _ = mean_rates(run, k)
    w_true, f_true = true_rest_physics(k)
    # Closed-form increments summed over 32000 samples: rounding ~sqrt(n) eps ~ 2e-14 relative;
    # 1e-12 of the vector's magnitude is still 1e-6 of the smallest effect tested below.
    np.testing.assert_allclose(w, w_true, rtol=0, atol=1e-12 * W_EARTH)
    np.testing.assert_allclose(f, f_true, rtol=0, atol=1e-12 * 9.8)
    # The same holds sample by sample at rest (constant in the body). Per sample the interval
    # length b - a is a difference of rounded times: error <= ulp(2048 s) = 4.5e-13 s, i.e.
    # 1e-10 of a 5 ms sample -> tolerance 1e-10 of the increment.
    sel = middle(run, k)
    np.testing.assert_allclose(
        run.dv_mps[sel], np.tile(f_true * DT, (sel.sum(), 1)), rtol=0, atol=1e-10 * 9.8 * DT
    )


@pytest.mark.parametrize("k", range(1, N_POS + 1))
def test_rest_with_table2_errors(table2_sim, k):
    run, truth = table2_sim
    si = table_column_si("table2_simulation", "standard")
    Eg, bg = sensor_model(si, "gyro")
    Ea, ba = sensor_model(si, "accel")
    w, f, _ = mean_rates(run, k)
    w_true, f_true = true_rest_physics(k)
    # Deterministic, so the tolerance is rounding again (see the error-free test).
    np.testing.assert_allclose(w, Eg @ w_true + bg, rtol=0, atol=1e-12 * W_EARTH)
    np.testing.assert_allclose(f, Ea @ f_true + ba, rtol=0, atol=1e-12 * 9.8)
    np.testing.assert_allclose(truth.errors.values, [si[n] for n in SPEC_NAMES], rtol=1e-14)


@pytest.mark.parametrize("k", range(1, N_POS + 1))
def test_rest_with_noise_within_noise_bounds(noisy_sim, k):
    run, _ = noisy_sim
    si = table_column_si("table2_simulation", "standard")
    Eg, bg = sensor_model(si, "gyro")
    Ea, ba = sensor_model(si, "accel")
    w, f, T = mean_rates(run, k)
    w_true, f_true = true_rest_physics(k)
    # White noise averaged over T: sigma = ARW/sqrt(T) (2.3e-8 rad/s) and VRW/sqrt(T)
    # (7.8e-6 m/s^2); 5 sigma per component (54 components: false alarm ~3e-5; seed fixed).
    np.testing.assert_allclose(w, Eg @ w_true + bg, rtol=0, atol=5 * ARW_NAV / math.sqrt(T))
    np.testing.assert_allclose(f, Ea @ f_true + ba, rtol=0, atol=5 * VRW_NAV / math.sqrt(T))


def test_noise_statistics(noisy_sim, table2_sim):
    noisy, _ = noisy_sim
    clean, _ = table2_sim
    # Same deterministic part -> the difference is the noise exactly.
    e_t = noisy.dtheta_rad - clean.dtheta_rad
    e_v = noisy.dv_mps - clean.dv_mps
    n = len(e_t)
    sd_t, sd_v = ARW_NAV * math.sqrt(DT), VRW_NAV * math.sqrt(DT)
    # Relative standard error of a sample std is 1/sqrt(2n) = 0.12 % for n = 338400:
    # 1 % is ~8 sigma per axis.
    np.testing.assert_allclose(e_t.std(0), sd_t, rtol=0.01)
    np.testing.assert_allclose(e_v.std(0), sd_v, rtol=0.01)
    # Zero mean: |mean| < 5 sigma/sqrt(n).
    assert np.all(np.abs(e_t.mean(0)) < 5 * sd_t / math.sqrt(n))
    assert np.all(np.abs(e_v.mean(0)) < 5 * sd_v / math.sqrt(n))
    # White: lag-1 autocorrelation and cross-axis correlation within 5/sqrt(n).
    for e in (e_t, e_v):
        z = (e - e.mean(0)) / e.std(0)
        lag1 = np.mean(z[1:] * z[:-1], axis=0)
        assert np.all(np.abs(lag1) < 5 / math.sqrt(n))
        cross = np.mean(z[:, [0, 1, 2]] * z[:, [1, 2, 0]], axis=0)
        assert np.all(np.abs(cross) < 5 / math.sqrt(n))


def test_noise_at_rest_by_differencing_the_mean(noisy_sim):
    # The brief's form: sample std of dtheta at rest after removing each rest's mean.
    run, _ = noisy_sim
    res_t, res_v = [], []
    for k in range(1, N_POS + 1):
        sel = middle(run, k)
        res_t.append(run.dtheta_rad[sel] - run.dtheta_rad[sel].mean(0))
        res_v.append(run.dv_mps[sel] - run.dv_mps[sel].mean(0))
    res_t, res_v = np.vstack(res_t), np.vstack(res_v)
    # n = 288000 per axis -> 0.13 % standard error; 1 % tolerance.
    np.testing.assert_allclose(res_t.std(0), ARW_NAV * math.sqrt(DT), rtol=0.01)
    np.testing.assert_allclose(res_v.std(0), VRW_NAV * math.sqrt(DT), rtol=0.01)


def flip_samples(run, k):
    """Samples of flip k (1-based) of paper-9pos: t in (start, start + 9 s]."""
    t0 = rest_window(k)[1]
    return (run.time_s > t0 + DT / 2) & (run.time_s <= t0 + FLIP_S + DT / 2)


@pytest.mark.parametrize("k", range(1, N_POS))
def test_flip_integrates_to_its_angle(clean_sim, paper_seq, k):
    run, _, _ = clean_sim
    s = paper_seq.steps[k - 1]
    ax = "XYZ".index(s.axis)
    sel = flip_samples(run, k)
    assert sel.sum() == int(FLIP_S * FS)
    total = run.dtheta_rad[sel].sum(0)
    C_pre = R_SETUP @ pre_attitudes()[k - 1]
    C_post = R_SETUP @ pre_attitudes()[k]
    # The flip axis is fixed in the body and in n during the flip, so its Earth-rate
    # component is constant: axis part = angle + (C e_axis . omega) T, exact to rounding.
    w_axis = C_pre[:, ax] @ earth_rate_enu(LAT)
    assert total[ax] == pytest.approx(math.radians(s.angle_deg) + w_axis * FLIP_S, abs=1e-12)
    # The other components are Earth rate only: bounded by |omega| T = 6.6e-4 rad.
    others = np.delete(total, ax)
    assert np.all(np.abs(others) <= W_EARTH * FLIP_S)
    # Composition of the per-sample rotations: inertial rotation over the flip is
    # C_pre^T R_earth(W T) C_post (the n frame turns by W T meanwhile). Treating each sample's
    # increment as its rotation vector neglects coning, <= 1/12 |w_flip||W| dt^2 per sample,
    # 1800 samples -> 5e-8 rad; tolerance 1e-6 rad (the Earth's turn is 6.6e-4 rad).
    R = np.eye(3)
    for d in run.dtheta_rad[sel]:
        R = R @ rodrigues(d)
    want = C_pre.T @ rodrigues(earth_rate_enu(LAT) * FLIP_S) @ C_post
    assert np.linalg.norm(log_so3(R.T @ want)) < 1e-6
    np.testing.assert_allclose(C_pre @ rot_about(s.axis, math.radians(s.angle_deg)), C_post, atol=1e-12)


def test_flip_increments_match_quadrature(clean_sim, paper_seq):
    """Each sample of flip 3 against Gauss-Legendre quadrature of the body rate and force."""
    run, _, _ = clean_sim
    k = 3
    s = paper_seq.steps[k - 1]
    ax = "XYZ".index(s.axis)
    rate = math.copysign(math.radians(s.rate_dps), s.angle_deg)
    C_pre = R_SETUP @ pre_attitudes()[k - 1]
    t_flip = rest_window(k)[1]
    e = np.zeros(3)
    e[ax] = 1.0
    w_n, f_n = earth_rate_enu(LAT), np.array([0.0, 0.0, normal_gravity(LAT, 0.0)])
    x, wq = np.polynomial.legendre.leggauss(8)
    idx = np.nonzero(flip_samples(run, k))[0][::37]
    for i in idx:
        a, b = run.time_s[i] - DT, run.time_s[i]
        ts = 0.5 * (b - a) * x + 0.5 * (a + b)
        dth, dv = np.zeros(3), np.zeros(3)
        for t, wgt in zip(ts, wq, strict=True):
            C = C_pre @ rot_about(s.axis, rate * (t - t_flip))
            dth += 0.5 * (b - a) * wgt * (C.T @ w_n + rate * e)
            dv += 0.5 * (b - a) * wgt * (C.T @ f_n)
        # 8-point Gauss on an integrand analytic over 8.7e-4 rad: quadrature error << rounding.
        # The sample's length is a difference of rounded times (<= ulp(2048 s) = 4.5e-13 s,
        # 1e-10 of 5 ms) -> tolerance 1e-10 of the increment sizes (8.7e-4 rad, 0.049 m/s);
        # a wrong sign of the Earth-rate or gravity rotation would be off by ~1e-7 and 1e-5.
        np.testing.assert_allclose(run.dtheta_rad[i], dth, rtol=0, atol=1e-10 * 8.7e-4)
        np.testing.assert_allclose(run.dv_mps[i], dv, rtol=0, atol=1e-10 * 0.049)


def test_flip_errors_realised_and_recorded(paper_seq):
    cfg = SimConfig(latitude_rad=LAT)
    A = 0.5
    run, truth = simulate(
        paper_seq,
        cfg,
        ErrorModel.zero(),
        load_profile("navigation"),
        options=SimOptions(flip_error_deg=A, noise=False, seed=3),
    )
    e = truth.flip_errors_deg
    assert e.shape == (len(paper_seq.steps),)
    assert np.all(np.abs(e) <= A)
    assert np.max(np.abs(e)) > 0.05 * A  # they really are drawn (fixed seed)
    assert len(np.unique(e)) == len(e)  # one independent draw per flip
    # Find each flip from the gyros, with 5 rest samples on each side, and take the flip axis
    # component: realised angle + (axis in n . omega) * window (constant through a flip).
    moving = np.abs(run.dtheta_rad).max(1) > 10 * W_EARTH * DT
    starts = np.nonzero(moving & ~np.r_[False, moving[:-1]])[0]
    ends = np.nonzero(moving & ~np.r_[moving[1:], False])[0]
    assert len(starts) == len(ends) == len(paper_seq.steps)
    C = attitude(*paper_seq.start)
    for s, err, i0, i1 in zip(paper_seq.steps, e, starts, ends, strict=True):
        ax = "XYZ".index(s.axis)
        window = slice(i0 - 5, i1 + 6)
        T = (i1 - i0 + 11) * DT
        got = run.dtheta_rad[window, ax].sum() - (C[:, ax] @ earth_rate_enu(LAT)) * T
        # Exact kinematics: rounding only (1e-12 rad = 6e-11 deg).
        assert math.degrees(got) == pytest.approx(s.angle_deg + err, abs=1e-9)
        C = C @ rot_about(s.axis, math.radians(s.angle_deg + err))
    # The gravity seen at the end follows the realised (not nominal) attitude.
    f_end = run.dv_mps[-1000:].sum(0) / (1000 * DT)
    np.testing.assert_allclose(f_end, C.T @ [0, 0, normal_gravity(LAT, 0.0)], atol=1e-11)


def test_no_flip_errors_by_default(clean_sim):
    _, truth, _ = clean_sim
    np.testing.assert_array_equal(truth.flip_errors_deg, np.zeros(8))


SHORT = Sequence(
    name="short",
    start=("east", "up", "south"),
    steps=(Step("Z", 90.0, 10.0, 5.0), Step("Y", -90.0, 10.0, 5.0)),
    initial_dwell_s=5.0,
)


def short_sim(seed, **kw):
    return simulate(
        SHORT,
        SimConfig(latitude_rad=LAT),
        ErrorModel.from_table2(),
        load_profile("navigation"),
        SimOptions(seed=seed, **kw),
    )


def test_same_seed_same_run_different_seed_different():
    kw = dict(flip_error_deg=1.0, random_setup_deg=3.0)
    a, ta = short_sim(5, **kw)
    b, tb = short_sim(5, **kw)
    c, tc = short_sim(6, **kw)
    np.testing.assert_array_equal(a.dtheta_rad, b.dtheta_rad)
    np.testing.assert_array_equal(a.dv_mps, b.dv_mps)
    np.testing.assert_array_equal(ta.setup_rotvec, tb.setup_rotvec)
    np.testing.assert_array_equal(ta.flip_errors_deg, tb.flip_errors_deg)
    assert not np.array_equal(a.dtheta_rad, c.dtheta_rad)
    assert not np.array_equal(a.dv_mps, c.dv_mps)
    assert not np.array_equal(ta.setup_rotvec, tc.setup_rotvec)
    # The random setup stays inside the +-3 deg box.
    assert np.all(np.abs(np.degrees(ta.setup_rotvec)) <= 3.0)


def test_truth_file_round_trip(tmp_path):
    _, truth = short_sim(9, flip_error_deg=0.3, random_setup_deg=3.0)
    path = tmp_path / "run.truth.toml"
    write_truth(path, truth)
    back = read_truth(path)
    assert isinstance(back, Truth)
    # Units conversion there and back (x / s * s): rounding only.
    np.testing.assert_allclose(back.errors.values, truth.errors.values, rtol=1e-14)
    np.testing.assert_allclose(back.setup_rotvec, truth.setup_rotvec, rtol=1e-14)
    np.testing.assert_array_equal(back.flip_errors_deg, truth.flip_errors_deg)
    assert (back.profile, back.seed, back.noise) == ("navigation", 9, True)
    text = path.read_text("utf-8")
    for section in ("[errors]", "[setup]", "[meta]"):
        assert section in text
    assert "east_deg" in text and "bgx" in text


@pytest.mark.parametrize("k", range(1, N_POS + 1))
def test_encoder_angles_at_rest(clean_sim, k):
    run, _, _ = clean_sim
    row = table1_gimbal()[k - 1]
    want = [float(row["outer_deg"]), float(row["middle_deg"]), float(row["inner_deg"])]
    t0, t1 = rest_window(k)
    sel = (run.time_s > t0 + DT / 2) & (run.time_s <= t1 - DT / 2)
    # The setup rotation must not enter (the gimbal sits on the base); grid angles are exact
    # to rounding of atan2 -> 1e-9 deg.
    np.testing.assert_allclose(run.gimbal_deg[sel], np.tile(want, (sel.sum(), 1)), rtol=0, atol=1e-9)


def test_encoder_angles_continuous(clean_sim):
    run, _, _ = clean_sim
    # Encoders count: no 360 deg jumps; one sample moves at most rate * dt = 0.05 deg.
    step = np.abs(np.diff(run.gimbal_deg, axis=0))
    assert step.max() <= 10.0 * DT + 1e-9


def test_encoder_angles_track_middle_gimbal_through_90():
    # At the start body X is the middle gimbal's axis, so +180 deg about X turns only the middle
    # gimbal: an encoder counts 0 -> 180 with outer and inner still at 0 (conventions: angles
    # continuous along a run, as encoders count). rest_positions must agree with the run log.
    from calib.gimbal.encoders import rest_positions

    seq = Sequence(
        name="mid",
        start=("east", "up", "south"),
        steps=(Step("X", 180.0, 10.0, 5.0), Step("Y", 90.0, 10.0, 5.0)),
        initial_dwell_s=5.0,
    )
    run, _ = simulate(
        seq,
        SimConfig(latitude_rad=LAT),
        ErrorModel.zero(),
        load_profile("navigation"),
        options=SimOptions(noise=False),
    )
    # Continuous: one 5 ms sample moves a gimbal by at most 10 deg/s * 5 ms = 0.05 deg.
    jumps = np.abs(np.diff(run.gimbal_deg, axis=0)).max(0)
    assert np.all(jumps <= 10.0 * DT + 1e-6), f"largest per-sample encoder step {jumps} deg"
    pos = rest_positions(seq)
    i2 = np.searchsorted(run.time_s, 0.5 * (pos[1].start_s + pos[1].end_s))
    np.testing.assert_allclose(pos[1].gimbal_deg, [0.0, 180.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(run.gimbal_deg[i2], [0.0, 180.0, 0.0], atol=1e-6)
    for p in pos:
        i = np.searchsorted(run.time_s, 0.5 * (p.start_s + p.end_s))
        np.testing.assert_allclose(run.gimbal_deg[i], p.gimbal_deg, atol=1e-6)


def test_flip_not_aligned_with_samples():
    # 37.5 deg at 7 deg/s lasts 5.357 s: flip boundaries fall inside samples, which must be
    # split exactly. The axis component over the flip (with rest samples around it) is the
    # angle plus the constant axis component of the Earth rate.
    seq = Sequence(
        name="odd", start=("east", "up", "south"), steps=(Step("X", 37.5, 7.0, 20.0),), initial_dwell_s=10.0
    )
    run, _ = simulate(
        seq,
        SimConfig(latitude_rad=LAT),
        ErrorModel.zero(),
        load_profile("navigation"),
        options=SimOptions(noise=False),
    )
    assert run.time_s.size == math.floor((10.0 + 37.5 / 7.0 + 20.0) * FS)
    C0 = attitude("east", "up", "south")
    w_n = earth_rate_enu(LAT)
    sel = (run.time_s > 9.0) & (run.time_s <= 17.0)  # flip is 10 .. 15.357 s
    total = run.dtheta_rad[sel, 0].sum()
    assert total == pytest.approx(math.radians(37.5) + (C0[:, 0] @ w_n) * 8.0, abs=1e-12)
    # After the flip: gravity and Earth rate of C0 R_X(37.5), exact to rounding.
    C1 = C0 @ rot_about("X", math.radians(37.5))
    rest = run.time_s > 16.0
    T = rest.sum() * DT
    g = normal_gravity(LAT, 0.0)
    np.testing.assert_allclose(run.dv_mps[rest].sum(0) / T, C1.T @ [0, 0, g], atol=1e-12 * g)
    np.testing.assert_allclose(run.dtheta_rad[rest].sum(0) / T, C1.T @ w_n, atol=1e-12 * W_EARTH)
    # The samples straddling the flip's ends carry the partial rotation: no sample holds more
    # than a full sample's turn (7 deg/s * 5 ms) plus Earth rate.
    assert np.abs(run.dtheta_rad[:, 0]).max() <= math.radians(7.0) * DT + W_EARTH * DT


@pytest.mark.parametrize(
    "lat_deg,height,gravity", [(-30.0, 0.0, None), (60.0, 1500.0, None), (40.0, 0.0, 9.80123)]
)
def test_site_latitude_height_and_measured_gravity(lat_deg, height, gravity):
    lat = math.radians(lat_deg)
    cfg = SimConfig(latitude_rad=lat, height_m=height, gravity_mps2=gravity)
    run, _ = simulate(
        SHORT, cfg, ErrorModel.zero(), load_profile("navigation"), options=SimOptions(noise=False)
    )
    g = gravity if gravity is not None else normal_gravity(lat, height)
    C = attitude(*SHORT.start)
    sel = run.time_s <= 5.0
    T = sel.sum() * DT
    # Exact data: rounding only (1e-12 relative); a 1500 m height changes g by 4.6e-3 m/s^2.
    np.testing.assert_allclose(run.dv_mps[sel].sum(0) / T, C.T @ [0, 0, g], atol=1e-12 * g)
    np.testing.assert_allclose(
        run.dtheta_rad[sel].sum(0) / T, C.T @ earth_rate_enu(lat), atol=1e-12 * W_EARTH
    )
    if gravity is not None:
        assert float(run.meta["gravity_mps2"]) == gravity
    assert float(run.meta["height_m"]) == height


def test_tactical_profile_noise_level():
    prof = load_profile("tactical")
    noisy, _ = simulate(
        SHORT, SimConfig(latitude_rad=LAT), ErrorModel.zero(), prof, options=SimOptions(noise=True, seed=21)
    )
    clean, _ = simulate(
        SHORT, SimConfig(latitude_rad=LAT), ErrorModel.zero(), prof, options=SimOptions(noise=False, seed=21)
    )
    n = noisy.time_s.size
    # conventions.md: tactical = 0.05 deg/sqrt(h), 50 ug/sqrt(Hz). Sample std of n = 6600:
    # relative standard error 1/sqrt(2n) = 0.9 % -> 5 % tolerance (~5.7 sigma).
    sd_t = 0.05 * math.pi / 180 / 60 * math.sqrt(DT)
    sd_v = 50 * 9.80665e-6 * math.sqrt(DT)
    np.testing.assert_allclose((noisy.dtheta_rad - clean.dtheta_rad).std(0), sd_t, rtol=0.05)
    np.testing.assert_allclose((noisy.dv_mps - clean.dv_mps).std(0), sd_v, rtol=0.05)
    assert n == int((5 + 9 + 5 + 9 + 5) * FS)
