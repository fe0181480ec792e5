"""The troubles of real hand recordings in the hand-run simulator, against physics derived here.

Tremor of a held pose (the gyro against the tremor's own sinusoids and attitude, the
accelerometer against the shake's velocity through the strapdown navigator), host time
stamps (their statistics, order and count), the gyro g-sensitivity (``G f`` in the rest
means), a sample-clock rate error (a turn reads ``1 + epsilon`` of its angle), the unit
mistakes of a written log, the truth file and the CLI. The simulator is tested, not the fit.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import DEG, DEG_PER_H, earth_rate_enu, log_so3, rodrigues

from calib.hand.host_clock import EPOCH_MS, host_stamps
from calib.hand.plan import HandPlan, PlanShape, random_hand_plan
from calib.hand.simulate import simulate_by_hand, true_increments, write_hand_run
from calib.hand.tremor import Tremor, random_tremor
from calib.hand.troubles import HandTroubles, TroubleSpec, g_sensitivity_from_dphg, troubles_from_table
from calib.nav.site import Site
from calib.nav.strapdown import coning_rotvec, navigate
from calib.nav.transform import quat_mult, quat_to_dcm, rotvec_to_quat
from calib.noise.profiles import load_profile
from calib.sequence.kinematics import SimConfig

LAT = 45.4 * DEG
G = 9.81744
RATE = 100.0
CFG = SimConfig(latitude_rad=LAT, sample_rate_hz=RATE, gravity_mps2=G)


def _plan(seed: int = 5, n: int = 4, **kw) -> HandPlan:
    """Long rests (a held pose's middle spans several seconds), fast fixed-axis turns."""
    args = dict(first_rest_s=12.0, rest_s=(8.0, 10.0), peak_rate_dps=600.0, wobble_deg=0.0) | kw
    return random_hand_plan(n, np.random.default_rng(seed), PlanShape(**args))


def _inside(time_s: np.ndarray, rate: float, a: float, b: float) -> np.ndarray:
    """Samples whose whole interval lies in ``[a, b]``."""
    return np.flatnonzero((time_s - 1.0 / rate >= a - 1e-9) & (time_s <= b + 1e-9))


def _middle(tremor: Tremor, j: int) -> tuple[float, float]:
    """The untapered middle of held rest ``j`` (the window is 1 there)."""
    return tremor.start_s[j] + tremor.taper_s[j], tremor.end_s[j] - tremor.taper_s[j]


def _theta(tremor: Tremor, j: int, t: np.ndarray) -> np.ndarray:
    """The tremor's rotation vector in the untapered middle, from its sinusoids, (m, 3)."""
    arg = 2 * np.pi * tremor.frequency_hz[j, :3] * (t[:, None, None] - tremor.start_s[j])
    return np.sum(tremor.amplitude[j, :3] * np.sin(arg + tremor.phase_rad[j, :3]), axis=2)


def _coning_attitude(dtheta: np.ndarray) -> np.ndarray:
    """The rotation the increments integrate to (two-sample coning, quaternion products)."""
    q = np.array([1.0, 0.0, 0.0, 0.0])
    for r in rotvec_to_quat(coning_rotvec(dtheta)):
        q = quat_mult(q, r)
    return quat_to_dcm(q)


@pytest.fixture(scope="module")
def tremor_run():
    plan = _plan()
    tremor = random_tremor(plan, np.random.default_rng(1), tremor_deg=0.2)
    t, dth, dv = true_increments(plan, Site(LAT, G), RATE, tremor=tremor)
    return plan, tremor, t, dth, dv


# Off by default --------------------------------------------------------------------------------


def test_no_troubles_is_the_table_run_bit_for_bit():
    plan = _plan(n=3)
    prof = load_profile("mems")
    base, _ = simulate_by_hand(plan, CFG, profile=prof, seed=4)
    same, truth = simulate_by_hand(plan, CFG, profile=prof, seed=4, troubles=HandTroubles())
    for name in ("time_s", "dtheta_rad", "dv_mps"):
        assert np.array_equal(getattr(base, name), getattr(same, name)), name
    assert not truth.troubles.any
    # The CLI draws the troubles from a fourth stream: the first three are those it drew before.
    three, four = np.random.SeedSequence(9).spawn(3), np.random.SeedSequence(9).spawn(4)
    for a, b in zip(three, four[:3], strict=True):
        assert a.generate_state(4).tolist() == b.generate_state(4).tolist()


# Tremor ----------------------------------------------------------------------------------------


def test_tremor_gyro_is_the_tremor_s_rate_sample_by_sample(tremor_run):
    """Each sample's mean rate: ``A w sinc(f T) cos(w (t - T/2) + phi)`` per sinusoid, plus the Earth's.

    Exact for ``omega = theta'``; the gyro sees ``J_r(theta) theta'``, which differs by at most
    ``|theta| |theta'| / 2`` (the right Jacobian's first term): the tolerance.
    """
    plan, tremor, t, dth, _ = tremor_run
    T = 1.0 / RATE
    for j, k in enumerate(tremor.rest):
        a, b = _middle(tremor, j)
        idx = _inside(t, RATE, a, b)
        assert idx.size > 500
        f, A, phi = tremor.frequency_hz[j, :3], tremor.amplitude[j, :3], tremor.phase_rad[j, :3]
        w = 2 * np.pi * f
        tc = t[idx][:, None, None] - T / 2 - tremor.start_s[j]
        expect = np.sum(A * w * np.sinc(f * T) * np.cos(w * tc + phi), axis=2)
        gyro = dth[idx] / T - plan.C_b_n[k].T @ earth_rate_enu(LAT)
        bound = 0.5 * np.abs(A).sum(axis=1).max() * np.abs(A * w).sum(axis=1).max()
        assert np.abs(gyro - expect).max() < 1.1 * bound
        assert bound < 0.01 * np.abs(A * w).sum(axis=1).max()  # the check is sharp: J_r within 1 %
        # Its RMS: the analytic one (over the window, not the long-run sum of squares).
        rms, rms_expect = np.sqrt(np.mean(gyro**2, axis=0)), np.sqrt(np.mean(expect**2, axis=0))
        assert np.allclose(rms, rms_expect, rtol=0.01)
        assert np.all(rms > 0.5 * np.radians(0.2) * 2 * np.pi * 3.0)  # a 0.2 deg tremor at >= 3 Hz


def _held_attitude_errors(plan: HandPlan, tremor: Tremor, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Per held pose, over 5 s of its middle: the angle between the coning-integrated gyro and
    ``exp(-theta(a)) C_k^T R(w_ie dt) C_k exp(theta(b))``; and the angle the tremor turned."""
    t, dth, _ = true_increments(plan, Site(LAT, G), rate, tremor=tremor)
    errors, turned = [], []
    for j, k in enumerate(tremor.rest):
        a, _ = _middle(tremor, j)
        idx = _inside(t, rate, a, a + 5.0)
        t0, t1 = t[idx[0]] - 1.0 / rate, t[idx[-1]]
        th0, th1 = _theta(tremor, j, np.array([t0, t1]))
        C0, C1 = plan.C_b_n[k] @ rodrigues(th0), plan.C_b_n[k] @ rodrigues(th1)
        expect = C0.T @ rodrigues(earth_rate_enu(LAT) * (t1 - t0)) @ C1
        errors.append(np.linalg.norm(log_so3(expect.T @ _coning_attitude(dth[idx]))))
        turned.append(np.linalg.norm(log_so3(C0.T @ C1)))
    return np.array(errors), np.array(turned)


def test_tremor_gyro_integrates_to_the_held_attitude(tremor_run):
    """Coning-integrated over 5 s of a held pose, the gyro turns ``exp(theta(a))`` into ``exp(theta(b))``
    (the Earth turning meanwhile), at the rule's order: a quarter of the period gives at most 1/45 of
    the error (third order: 1/64, as for the moves in test_handsim; a wobble's coning falls faster),
    and at 400 Hz below 1e-7 rad."""
    plan, tremor = tremor_run[:2]
    slow, turned = _held_attitude_errors(plan, tremor, 100.0)
    fast, _ = _held_attitude_errors(plan, tremor, 400.0)
    assert np.all(fast < 1e-7) and np.all(turned > 1e-4)  # it did wobble
    assert np.all(slow / fast > 45.0)


def _shake_errors(plan: HandPlan, tremor: Tremor, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Per held pose, over 4 s of its middle: the navigator's velocity less the shake's ``q'(t)``
    (both from the window's start), largest; and the shake's largest velocity."""
    t, dth, dv = true_increments(plan, Site(LAT, G), rate, tremor=tremor)
    errors, sizes = [], []
    for j, k in enumerate(tremor.rest):
        a, _ = _middle(tremor, j)
        idx = _inside(t, rate, a, a + 4.0)
        t0 = t[idx[0]] - 1.0 / rate
        C0 = plan.C_b_n[k] @ rodrigues(_theta(tremor, j, np.array([t0]))[0])
        nav = navigate(dth[idx], dv[idx], t[idx], C0, Site(LAT, G), t0=t0)
        times = np.concatenate([[t0], t[idx]])
        w = 2 * np.pi * tremor.frequency_hz[j, 3:]
        arg = w * (times[:, None, None] - tremor.start_s[j]) + tremor.phase_rad[j, 3:]
        v = np.sum(tremor.amplitude[j, 3:] * w * np.cos(arg), axis=2)
        errors.append(np.abs(nav.v_n - (v - v[0])).max())
        sizes.append(np.abs(v).max())
    return np.array(errors), np.array(sizes)


def test_tremor_accelerometer_follows_the_shake(tremor_run):
    """The strapdown navigator on gyro and accelerometer together (from the true attitude) tracks the
    shake's velocity: the two sensors see one motion. Its error falls at second order (the sculling of
    gravity through a wobbling attitude; a quarter of the period gives 1/16, at least 12 here) to
    below 0.3 % of the shake's velocity at 400 Hz: no inconsistency is left over."""
    plan, tremor = tremor_run[:2]
    slow, size = _shake_errors(plan, tremor, 100.0)
    fast, _ = _shake_errors(plan, tremor, 400.0)
    assert np.all(size > 3e-4)  # the shake is there: 0.05 m/s^2 at 3-12 Hz
    assert np.all(fast < 3e-3 * size) and np.all(slow / fast > 12.0)


def test_held_pose_means_are_still_gravity_and_the_unit_stays_put(tremor_run):
    """Over a held pose the tremor averages out: the mean specific force is ``C_k^T g`` to the tremor's
    second order (``theta^2 g``, 1e-5 of g for 0.2 deg) and the shake's mean acceleration over the
    window (``2 |v|max / window``)."""
    plan, tremor, t, _, dv = tremor_run
    for j, k in enumerate(tremor.rest):
        idx = _inside(t, RATE, tremor.start_s[j], tremor.end_s[j])
        f = dv[idx].sum(axis=0) * RATE / idx.size
        v_max = np.sum(tremor.amplitude[j, 3:] * 2 * np.pi * tremor.frequency_hz[j, 3:], axis=1).max()
        tol = 2.0 * np.sum(tremor.amplitude[j, :3], axis=1).max() ** 2 * G + 2 * v_max / (idx.size / RATE)
        assert np.linalg.norm(f - plan.C_b_n[k].T @ [0.0, 0.0, G]) < tol


def test_only_the_poses_of_the_first_seconds_are_held():
    """Like mikoff's logs (the first 26 s in the hand, 1-6 s poses): the later rests are the table's
    to the last bit, and the moves' increments too."""
    plan = random_hand_plan(
        12, np.random.default_rng(2), PlanShape(first_rest_s=3.0, rest_s=(1.0, 6.0), peak_rate_dps=500.0)
    )
    tremor = random_tremor(plan, np.random.default_rng(3), 0.3, hand_held_s=26.0)
    assert np.all(plan.rest_start_s[tremor.rest] < 26.0) and 0 < len(tremor.rest) < plan.n_poses
    assert np.all(tremor.rest == np.arange(len(tremor.rest)))
    t, dth, dv = true_increments(plan, Site(LAT, G), RATE, tremor=tremor)
    _, dth0, dv0 = true_increments(plan, Site(LAT, G), RATE)
    held = np.zeros(len(t), bool)
    for a, b in zip(tremor.start_s, tremor.end_s, strict=True):
        held |= (t > a) & (t - 1.0 / RATE < b)
    assert np.array_equal(dth[~held], dth0[~held]) and np.array_equal(dv[~held], dv0[~held])
    assert np.abs(dth[held] - dth0[held]).max() > 1e-4


def test_tremor_quadrature_has_converged(tremor_run):
    plan, tremor, _, dth10, dv10 = tremor_run
    _, dth40, dv40 = true_increments(plan, Site(LAT, G), RATE, oversample=40, tremor=tremor)
    assert np.abs(dth10 - dth40).max() < 1e-13 and np.abs(dv10 - dv40).max() < 1e-12


# Host stamps -----------------------------------------------------------------------------------


def test_host_stamps_short_delays_are_independent():
    """Delays uniform in [0, D], D below the period: no sample waits for the one before, so the steps
    are ``T + d_k - d_(k-1)``: mean T, variance D^2 / 6, lag-one correlation -1/2. 200,000 steps:
    the variance is known to 0.5 % (1 sigma) and the correlation to 0.002; tolerances 3 % and 0.02."""
    T, D = 0.01, 0.008
    t = np.arange(1, 200_001) * T
    s = host_stamps(t, D, np.random.default_rng(0))
    step = np.diff(s)
    assert s.size == t.size and np.all(step > 0)
    assert np.all((s >= t) & (s <= t + D))
    assert abs(step.mean() - T) < 1e-7  # telescoping: (s_n - s_1) / (n - 1), within D / n
    assert abs(step.var() / (D**2 / 6) - 1) < 0.03
    assert abs(np.corrcoef(step[1:], step[:-1])[0, 1] + 0.5) < 0.02


def test_host_stamps_long_delays_bunch_samples_in_order():
    """Delays up to 12 ms at 100 Hz (the steps of 8-20 ms of a real logger): a late sample holds the
    next back, so some steps are 0; never a decrease, no step longer than T + D, none lost."""
    T, D = 0.01, 0.012
    t = np.arange(1, 50_001) * T
    s = host_stamps(t, D, np.random.default_rng(1))
    step = np.diff(s)
    assert s.size == t.size and np.all(step >= 0) and np.any(step == 0)
    assert step.max() <= T + D + 1e-12 and np.all((s >= t) & (s <= t + D + 1e-12))


def test_jittering_stamps_change_the_stamps_not_the_samples(tmp_path):
    plan = _plan(n=3)
    prof = load_profile("mems")
    base, _ = simulate_by_hand(plan, CFG, profile=prof, seed=2)
    troubles = HandTroubles(stamp_jitter_s=0.012)
    run, truth = simulate_by_hand(plan, CFG, profile=prof, seed=2, troubles=troubles)
    assert np.array_equal(run.dtheta_rad, base.dtheta_rad) and np.array_equal(run.dv_mps, base.dv_mps)
    assert np.all(np.diff(run.time_s) >= 0) and np.all(
        (run.time_s >= base.time_s) & (run.time_s <= base.time_s + 0.012)
    )
    path = tmp_path / "jitter.csv"
    write_hand_run(path, run, truth)  # written as the host wrote it (a reader judges it)
    rows = np.loadtxt(path, delimiter=",", comments="#", skiprows=1 + len(run.meta))  # meta, header
    assert rows.shape[0] == run.n_samples and np.array_equal(rows[:, 0], run.time_s)


def test_epoch_ms_stamps_are_whole_milliseconds_and_read_back(tmp_path):
    from calib.runlog import read_run

    plan = _plan(n=3)
    run, truth = simulate_by_hand(plan, CFG, seed=2, troubles=HandTroubles(stamps="epoch-ms"))
    path = tmp_path / "epoch.csv"
    write_hand_run(path, run, truth)
    header = next(line for line in path.read_text().splitlines() if not line.startswith("#"))
    assert header.startswith("time_ms,")
    stamps = np.loadtxt(path, delimiter=",", skiprows=1 + len(run.meta), usecols=0, dtype=np.int64)
    assert stamps[0] == EPOCH_MS + 10 and np.all(np.diff(stamps) == 10)  # 100 Hz: 10 ms each
    back = read_run(path)
    assert back.n_samples == run.n_samples and np.array_equal(back.dtheta_rad, run.dtheta_rad)
    with pytest.raises(ValueError, match="csv"):
        write_hand_run(tmp_path / "epoch.npz", run, truth)


# Gyro g-sensitivity ----------------------------------------------------------------------------


def test_g_sensitivity_appears_in_the_rest_means_as_G_f():
    """Noise-free: the rest's mean rate less the Earth's is ``G C_k^T g`` to rounding. With the
    mems profile's noise: within 4 sigma of the mean of a rest (ARW / sqrt(rest))."""
    plan = _plan()
    G_dphg = np.array([[600.0, -300.0, 160.0], [80.0, -500.0, 240.0], [-180.0, 120.0, 400.0]])
    troubles = HandTroubles(g_sensitivity=g_sensitivity_from_dphg(G_dphg))
    prof = load_profile("mems")
    clean, _ = simulate_by_hand(plan, CFG, troubles=troubles)
    noisy, _ = simulate_by_hand(plan, CFG, profile=prof, seed=1, troubles=troubles)
    for k in range(plan.n_poses):
        idx = _inside(clean.time_s, RATE, plan.rest_start_s[k], plan.rest_end_s[k])
        f = plan.C_b_n[k].T @ [0.0, 0.0, G]
        expect = (G_dphg @ (f / 9.80665)) * DEG_PER_H + plan.C_b_n[k].T @ earth_rate_enu(LAT)
        duration = idx.size / RATE
        w = clean.dtheta_rad[idx].sum(axis=0) / duration
        assert np.abs(w - expect).max() < 1e-12
        w_noisy = noisy.dtheta_rad[idx].sum(axis=0) / duration
        assert np.abs(w_noisy - expect).max() < 4 * prof.arw / np.sqrt(duration)
        assert np.abs(expect).max() > 5 * prof.arw / np.sqrt(duration)  # the effect stands out


# Sample-clock rate error -----------------------------------------------------------------------


def test_a_rate_error_scales_each_turn_and_keeps_the_rests_right():
    """The IMU 1 % fast: ``1.01 x`` the samples at the nominal stamps; a move's summed increments read
    1.01 times the true ones (the Earth turns 2e-6 rad in a sample's shift of the window: 1e-6 of a
    30 deg turn); the rests' mean rate and specific force per nominal period are right to 1e-9."""
    plan = _plan(translation_m=0.0)
    eps = 0.01
    base, _ = simulate_by_hand(plan, CFG)
    fast, _ = simulate_by_hand(plan, CFG, troubles=HandTroubles(rate_error=eps))
    assert abs(fast.n_samples / base.n_samples - (1 + eps)) < 2.0 / base.n_samples
    assert np.array_equal(fast.time_s, np.arange(1, fast.n_samples + 1) / RATE)  # nominal stamps
    t_true = np.arange(1, fast.n_samples + 1) / (RATE * (1 + eps))
    for k in range(plan.n_poses - 1):
        a, b = plan.rest_end_s[k] - 0.5, plan.rest_start_s[k + 1] + 0.5
        turn0 = base.dtheta_rad[_inside(base.time_s, RATE, a, b)].sum(axis=0)
        turn = fast.dtheta_rad[_inside(t_true, RATE * (1 + eps), a, b)].sum(axis=0)
        assert np.linalg.norm(turn - (1 + eps) * turn0) < 1e-5 * np.linalg.norm(turn0)
    for k in range(plan.n_poses):
        idx = _inside(t_true, RATE * (1 + eps), plan.rest_start_s[k], plan.rest_end_s[k])
        f = fast.dv_mps[idx].sum(axis=0) * RATE / idx.size
        assert np.linalg.norm(f - plan.C_b_n[k].T @ [0.0, 0.0, G]) < 1e-9 * G


# The truth file and the CLI ------------------------------------------------------------------


def test_the_truth_file_holds_the_troubles_exactly(tmp_path):
    from calib.io.files import load_toml
    from calib.sim.truth import read_truth

    plan = _plan(n=3)
    spec = TroubleSpec(tremor_deg=0.2, hand_held_s=15.0, g_sensitivity_dphg=300.0, rate_error=-0.005)
    troubles = spec.draw(plan, np.random.default_rng(4))
    run, truth = simulate_by_hand(plan, CFG, troubles=troubles)
    path = write_hand_run(tmp_path / "hand.npz", run, truth)
    read_truth(path)  # the common reader takes it as is
    hand = load_toml(path)["hand"]
    assert hand["rate_error"] == -0.005
    back = troubles_from_table(hand)
    assert back.tremor is not None and troubles.tremor is not None
    for name in ("rest", "start_s", "end_s", "taper_s", "amplitude", "frequency_hz", "phase_rad"):
        assert np.array_equal(getattr(back.tremor, name), getattr(troubles.tremor, name)), name
    assert np.allclose(back.g_sensitivity, troubles.g_sensitivity, rtol=1e-15, atol=0)
    assert np.all(np.abs(hand["g_sensitivity_dphg"]) <= 300.0)
    assert np.allclose(hand["tremor"]["rms_angle_deg"], 0.2)
    plain, plain_truth = simulate_by_hand(plan, CFG)
    doc = load_toml(write_hand_run(tmp_path / "plain.npz", plain, plain_truth))["hand"]
    assert not {"tremor", "g_sensitivity_dphg", "rate_error", "stamps"} & set(doc)


def test_cli_simulate_with_troubles(tmp_path):
    from calib.io.files import load_toml
    from seqdesign.cli import main

    out = tmp_path / "hand.csv"
    res = CliRunner().invoke(
        main,
        ["simulate", "--by-hand", "--poses", "4", "--seed", "3", "--tremor-deg", "0.2",
         "--hand-held-s", "40", "--stamp-jitter-ms", "12", "--stamps", "epoch-ms",
         "--g-sensitivity-dphg", "200", "--rate-error", "0.01", "--profile", "mems",
         "-o", str(out), "--json"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert len(doc["troubles"]) == 5
    hand = load_toml(tmp_path / "hand.truth.toml")["hand"]
    assert hand["stamps"] == {"mode": "epoch-ms", "jitter_ms": 12.0, "epoch_ms": EPOCH_MS}
    assert hand["rate_error"] == 0.01 and hand["tremor"]["rest"] == [0]  # the first rest: 50 s
    lines = [line for line in out.read_text().splitlines() if not line.startswith("#")]
    stamps = np.array([int(line.split(",")[0]) for line in lines[1:]])
    assert lines[0].startswith("time_ms,") and np.all(np.diff(stamps) >= 0)
    assert len(stamps) == doc["samples"]


@pytest.mark.parametrize(
    "args, names",
    [
        (["--hand-held-s", "20"], "--hand-held-s"),
        (["--shake-mps2", "0.1"], "--shake-mps2"),
        (["--g-sensitivity-dphg", "1,2,3"], "--g-sensitivity-dphg"),
        (["--g-sensitivity-dphg", "abc"], "--g-sensitivity-dphg"),
        (["--g-sensitivity-dphg", "-5"], "--g-sensitivity-dphg"),
        (["--stamps", "epoch-ms", "-o", "x.npz"], "--stamps"),
        (["--rate-error", "0.5"], "--rate-error"),
    ],
)
def test_cli_refuses_bad_troubles_in_one_line(tmp_path, args, names):
    from seqdesign.cli import main

    res = CliRunner().invoke(main, ["simulate", "--by-hand", "-o", str(tmp_path / "x.csv"), *args])
    assert res.exit_code == 2 and names in res.output and "Traceback" not in res.output
    # One error line (click's range errors come with its usage lines), nothing written.
    assert sum("rror" in line for line in res.output.splitlines()) == 1 and not list(tmp_path.iterdir())


def test_cli_troubles_need_by_hand(tmp_path):
    from seqdesign.cli import main

    runner = CliRunner()
    out = str(tmp_path / "x.npz")
    res = runner.invoke(main, ["simulate", "paper-9pos", "--tremor-deg", "0.1", "-o", out])
    assert res.exit_code == 2 and "--tremor-deg" in res.output and "--by-hand" in res.output
    res = runner.invoke(main, ["verify", "paper-9pos", "--rate-error", "0.01", "--runs", "2"])
    assert res.exit_code == 2 and "--rate-error" in res.output and "--by-hand" in res.output


def test_cli_verify_by_hand_with_troubles():
    """The runs carry the troubles (named in the report); each run is simulated, and fitted or refused."""
    from seqdesign.cli import main

    res = CliRunner().invoke(
        main,
        ["verify", "--by-hand", "--poses", "6", "--runs", "2", "--profile", "mems", "--sample-rate-hz", "100",
         "--g-sensitivity-dphg", "200", "--rate-error", "0.001", "--with", "g-sensitivity", "--json"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["runs"] == 2 and "g-sensitivity 200" in doc["sequence"] and "rate error" in doc["sequence"]


def test_cli_short_poses_held_in_the_hand(tmp_path):
    """Like a recording whose first 26 s are held in the hand with 1-6 s poses."""
    from calib.io.files import load_toml
    from seqdesign.cli import main

    out = tmp_path / "short.npz"
    res = CliRunner().invoke(
        main,
        ["simulate", "--by-hand", "--poses", "10", "--rest-s", "1", "6", "--first-rest-s", "3", "--seed", "1",
         "--tremor-deg", "0.3", "--hand-held-s", "26", "--peak-rate-dps", "400", "-o", str(out)],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    hand = load_toml(tmp_path / "short.truth.toml")["hand"]
    rests, starts = np.array(hand["rest_s"]), np.array(hand["rest_start_s"])
    assert rests[0] == 3.0 and np.all((rests[1:] >= 1.0) & (rests[1:] <= 6.0))
    assert hand["tremor"]["rest"] == np.flatnonzero(starts < 26.0).tolist()
