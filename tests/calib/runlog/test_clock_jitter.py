"""Host stamps that jitter are not lost samples: the count rule of :mod:`calib.runlog.clock`.

A logger that stamps each sample when the host reads it writes times that wander by
milliseconds around the IMU's period while every sample is there. The samples are
then counted, not timed: the same samples with uniform, float or epoch-millisecond
stamps give the same run, the same rests and the same estimates. A sample truly lost
(the stamps fall a period behind the count and stay there) is still named, and still
refused while the unit turns.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.calibration.entry import calibrate
from calib.errors import CalibError
from calib.hand.plan import xsens_like_plan
from calib.hand.simulate import simulate_by_hand
from calib.model.error_model import ErrorModel
from calib.nav.transform import rotvec_to_dcm
from calib.noise.profiles import load_profile
from calib.runlog import read_run
from calib.runlog.clock import sample_clock, stamps_rate
from calib.runlog.polled import interleaved
from calib.sequence.kinematics import SimConfig
from seqdesign.repeatability import Repeatability

RATE_HZ = 100.0
PERIOD = 1.0 / RATE_HZ


def host_delays(n: int, rng: np.random.Generator) -> np.ndarray:
    """Reception delays of a host that now and then reads late and catches up 2 ms a sample.

    Steps between stamps then lie between 8 and 20 ms around the 10 ms period: the
    logger of the issue (every sample present, stamps jittering by 8-20 ms).
    """
    d = np.zeros(n)
    late = rng.random(n) < 0.05
    extra = rng.uniform(0.0, 0.010, n)
    for i in range(1, n):
        d[i] = max(0.0, d[i - 1] - 0.002) + (extra[i] if late[i] else 0.0)
    return d


def test_jittering_host_stamps_are_counted_not_read_as_gaps():
    rng = np.random.default_rng(3)
    n = 20_000
    delays = host_delays(n, rng)
    stamps = 12.0 + PERIOD * np.arange(n) + delays
    steps = np.diff(stamps) / PERIOD
    assert steps.min() < 0.85 and steps.max() > 1.9  # the jitter the old step rule misread
    clock = sample_clock(stamps, RATE_HZ)
    assert not clock.dropped and not clock.duplicates
    np.testing.assert_array_equal(clock.index, np.arange(n))
    # The jitter is the delays about the fitted line: never more than their range.
    assert 1e-3 < clock.jitter_rms_s < PERIOD
    assert clock.jitter_max_s <= np.ptp(delays) + 1e-9


def test_samples_received_in_bursts_are_timed_at_their_rate_not_their_median_step():
    # A Bluetooth link hands the host its 10 ms samples nine at a time: eight stamps 11.2 ms
    # apart and one 0.4 ms after (a real wireless IMU's log: 23,725 samples, every one there by
    # its counter). The median step, 11.2 ms, is no period: counted at it the rows overflowed
    # the stamps ("more rows than the stamps have room for", the rate taken as 88.9 Hz).
    rng = np.random.default_rng(8)
    n = 20_007
    burst = np.tile(np.r_[np.full(8, 0.0112), 0.0004], n // 9 + 1)[: n - 1]
    stamps = 30.0 + np.concatenate([[0.0], np.cumsum(burst)]) + rng.uniform(0.0, 3e-4, n)
    assert np.median(np.diff(stamps)) > 1.1 * PERIOD
    rate = stamps_rate(stamps)
    # The bursts' 90 ms repeat exactly, so the rate comes out within the jitter over the run
    # (0.3 ms over 200 s: 2 ppm); 10 ppm is ample.
    assert rate == pytest.approx(RATE_HZ, rel=1e-5)
    clock = sample_clock(stamps, rate)
    assert not clock.dropped and not clock.duplicates
    np.testing.assert_array_equal(clock.index, np.arange(n))


def test_a_lost_sample_amid_the_jitter_is_still_found():
    rng = np.random.default_rng(4)
    n = 20_000
    index = np.delete(np.arange(n + 3), [7_000, 12_000, 12_001])  # 1 then 2 samples lost
    stamps = PERIOD * index + host_delays(n, rng)
    clock = sample_clock(stamps, RATE_HZ)
    assert [c for _, c in clock.dropped] == [1, 2]
    for (t, _), lost in zip(clock.dropped, (7_000, 12_000), strict=True):
        assert abs(t - lost * PERIOD) < 0.015  # located within the jitter (0-10 ms) and a period
    np.testing.assert_array_equal(clock.index, index)


def test_stamps_half_a_period_off_for_good_are_refused():
    n = 10_000  # 100 s: the logger-clock trend fitted over the run takes little of the shift
    stamps = PERIOD * np.arange(n) + np.where(np.arange(n) >= 5_000, 0.5 * PERIOD, 0.0)
    stamps += 0.3 * PERIOD * (np.arange(n) % 2)  # jitter, so that the count rule applies
    with pytest.raises(CalibError, match="not a whole number"):
        sample_clock(stamps, RATE_HZ)


def test_precise_stamps_that_take_up_another_phase_once_are_read_at_their_stamps():
    # A phone's gyro stamped to 0.1 ms at 94.77 Hz (steps of 10.5 and 10.6 ms) whose sampling took
    # up another phase once: one step of 1.5 periods, every later stamp half a period on. No count
    # of one clock places those samples; the stamps do, each row the next sample, the one long
    # interval the sample's own. With jittering host stamps the same shift is refused (above).
    period = 1.0 / 94.7663
    n = 7_000
    stamps = np.round(period * (np.arange(n) + np.where(np.arange(n) >= 2_065, 0.5, 0.0)), 4)
    clock = sample_clock(stamps, 1.0 / period)
    assert clock.rule == "stamps" and not clock.dropped
    np.testing.assert_array_equal(clock.index, np.arange(n))


def _phone_stamps(index: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A phone's stamps: a 99.7369 Hz clock printed to 1 ms, with a host's reception jitter."""
    period = 1.0 / 99.7369
    return np.round(period * index + host_delays(len(index), rng), 3)


def test_a_long_hole_of_whole_samples_in_a_long_jittery_log_is_counted_where_it_is():
    # 140 samples lost 280 s into a 630 s log: a lag jump the size of a clock 2,200 ppm slow if
    # the clock's trend were read from the log's ends; counted as a hole, the rest of the log is
    # on one clock and nothing is refused.
    rng = np.random.default_rng(5)
    index = np.delete(np.arange(63_000), np.arange(28_000, 28_140))
    clock = sample_clock(_phone_stamps(index, rng), 99.7369)
    assert clock.dropped and [c for _, c in clock.dropped] == [140]
    assert abs(clock.dropped[0][0] - 28_000 / 99.7369) < 0.015  # jitter (0-10 ms) and a period
    np.testing.assert_array_equal(clock.index, index)


def test_a_hole_of_no_whole_number_of_samples_is_refused_at_the_hole():
    # A logger that paused 1.409 s and took up its samples on another phase of its clock (a
    # phone's recording, 139.5 samples' time): refused naming the row after the hole, not a
    # row the clock's trend pushed elsewhere.
    rng = np.random.default_rng(6)
    index = np.arange(62_000) + np.where(np.arange(62_000) >= 27_833, 139.5, 0.0)
    with pytest.raises(CalibError) as err:
        sample_clock(_phone_stamps(index, rng), 99.7369)
    assert err.value.where == "27833" and "not a whole number of samples" in err.value.what


def _hand_run(seed: int = 11):
    """A hand run with MEMS-sized errors and the mems profile's noise, 100 Hz (Xsens-like poses)."""
    rng = np.random.default_rng(seed)
    plan = xsens_like_plan(rng)
    values = np.zeros(21)
    values[:3] = np.radians(0.3)  # gyro biases, 0.3 deg/s
    values[3:6] = 2e-3
    values[12:15] = 0.05  # accelerometer biases, m/s^2
    values[15:18] = 3e-3
    cfg = SimConfig(latitude_rad=math.radians(45.0), height_m=0.0, sample_rate_hz=RATE_HZ)
    run, _ = simulate_by_hand(plan, cfg, ErrorModel(values), load_profile("mems"), seed=5)
    return run


def _write(path, stamps, fmt: str, rate_gyro, force) -> None:
    with open(path, "w") as fh:
        fh.write("t,gx,gy,gz,ax,ay,az\n")
        for t, w, f in zip(stamps, rate_gyro, force, strict=True):
            fh.write((fmt % t) + "," + ",".join(f"{x:.9e}" for x in (*w, *f)) + "\n")


COLUMNS = (
    "t=time_s,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps,ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2"
)


def _write_without(path, rates, force, lost: int, seed: int):
    """The log with sample ``lost`` left out, its host stamps jittering (`host_delays`)."""
    keep = np.delete(np.arange(len(rates)), lost)
    stamps = PERIOD * np.arange(1, len(rates) + 1) + host_delays(len(rates), np.random.default_rng(seed))
    _write(path, stamps[keep], "%.6f", rates[keep], force[keep])
    return path


@pytest.mark.slow
def test_the_same_samples_under_uniform_float_and_epoch_ms_stamps_calibrate_alike(tmp_path):
    run = _hand_run()
    n = len(run.time_s)
    rates, force = run.dtheta_rad / PERIOD, run.dv_mps / PERIOD
    rng = np.random.default_rng(9)
    uniform = PERIOD * np.arange(1, n + 1)
    versions = {
        "uniform": (uniform, "%.6f", "time_s"),
        "float": (uniform + host_delays(n, rng), "%.6f", "time_s"),
        "epoch_ms": (np.rint(1.7e12 + 1e3 * (uniform + host_delays(n, rng))), "%d", "time_ms"),
    }
    results = {}
    for name, (stamps, fmt, unit) in versions.items():
        path = tmp_path / f"{name}.csv"
        _write(path, stamps, fmt, rates, force)
        logged = read_run(
            path, columns=COLUMNS.replace("t=time_s", f"t={unit}"), latitude_deg=45.0, height_m=0.0
        )
        assert not logged.clock.dropped
        results[name] = calibrate(logged, "mems", by_hand=True)
    base = results["uniform"]
    for name, result in results.items():
        np.testing.assert_array_equal(result.by_hand.rest_s.shape, base.by_hand.rest_s.shape)
        # The rests are the same samples (times within the fitted period's ppm over the run).
        np.testing.assert_allclose(result.by_hand.rest_s, base.by_hand.rest_s, atol=1e-3)
        # The bound: the same estimates within 0.01 sigma.
        assert np.max(np.abs(result.values - base.values) / base.sigma) < 0.01, name
        # compare knows them as fits of one recording, not two calibrations that agree.
        assert Repeatability(base, result, ("uniform", name)).same_samples
    other = calibrate(_hand_run(seed=12), "mems", by_hand=True)
    assert not Repeatability(base, other, ("uniform", "another run")).same_samples


def test_a_sample_lost_in_a_move_is_refused_even_with_allow_gaps(tmp_path):
    run = _hand_run()
    rates, force = run.dtheta_rad / PERIOD, run.dv_mps / PERIOD
    turning = np.flatnonzero(np.linalg.norm(rates, axis=1) > 1.0)  # 57 deg/s: mid-move
    lost = int(turning[len(turning) // 2])
    path = _write_without(tmp_path / "lost.csv", rates, force, lost, seed=2)
    with pytest.raises(CalibError, match="1 sample.s. lost at t = .* while the IMU turns"):
        read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0, allow_gaps=True)
    with pytest.raises(CalibError, match="1 sample.s. dropped"):
        read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0)


def test_a_hand_fit_with_allow_gaps_leaves_out_the_move_that_lost_a_sample(tmp_path):
    # The same lost sample read for a hand fit (guess_turns): put in as a guess and marked, the
    # move holding it left out and said, every other move used, the fit as honest as the
    # simulator's noise (chi2/dof near 1). The gimbal fit refuses the guess.
    run = _hand_run()
    rates, force = run.dtheta_rad / PERIOD, run.dv_mps / PERIOD
    turning = np.flatnonzero(np.linalg.norm(rates, axis=1) > 1.0)
    lost = int(turning[len(turning) // 2])
    path = _write_without(tmp_path / "lost.csv", rates, force, lost, seed=2)
    read = read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0, allow_gaps=True, guess_turns=True)
    assert read.guessed is not None and np.flatnonzero(read.guessed).tolist() == [lost]
    result = calibrate(read, "mems", by_hand=True)
    summary = result.by_hand
    assert list(summary.lost.values()) == [1]
    (k,) = summary.lost
    assert not summary.move_used[k] and summary.move_used.sum() == len(summary.move_used) - 1
    assert summary.move_s[k, 0] <= lost * PERIOD <= summary.move_s[k, 1]
    assert any("lost amid its turn" in line for line in summary.lines())
    assert 0.7 < result.chi2_per_dof < 1.3  # the band the hand fits of this simulator keep
    with pytest.raises(CalibError, match="put in as a guess"):
        calibrate(read, "mems")


def test_two_imus_interleaved_in_one_log_are_refused_naming_it(tmp_path):
    # A flight controller's log: two IMUs at 100 Hz, 0.25 ms apart, their rows one after the
    # other. Read as one unit, the stamps look like a polling loop (steps of 0.25 and 9.75 ms)
    # and gravity jumps by the second unit's mounting (0.5 deg) and biases from row to row.
    run = _hand_run()
    rates, force = run.dtheta_rad / PERIOD, run.dv_mps / PERIOD
    other = force @ rotvec_to_dcm(np.radians([0.5, -0.3, 0.0])).T + np.array([0.08, -0.05, 0.1])
    stamps = PERIOD * np.arange(1, len(rates) + 1)
    rows = np.empty((2 * len(rates), 7))
    rows[0::2] = np.column_stack([stamps, rates, force])
    rows[1::2] = np.column_stack([stamps + 0.00025, rates, other])
    path = tmp_path / "two_imus.csv"
    _write(path, rows[:, 0], "%.6f", rows[:, 1:4], rows[:, 4:])
    with pytest.raises(CalibError, match="2 IMUs. samples interleaved: the stamps keep a 10 ms period"):
        read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0)
    # One unit read by a host two samples at a time (stamps 0.25 ms apart in pairs, the same
    # steps) is no two units: its gravity moves no more from a row to the next than over two.
    one = np.column_stack([stamps[0::2].repeat(2) + np.tile([0.0, 0.00025], len(stamps) // 2), rates, force])
    _write(path, one[:, 0], "%.6f", one[:, 1:4], one[:, 4:])
    assert interleaved(one[:, 0], one[:, 4:]) is None


def test_the_clock_says_which_rule_it_used():
    # Stamps of the IMU's own clock (jitter far below a quarter period): rounded step by step.
    clean = PERIOD * np.arange(1_000) + 1e-5 * np.random.default_rng(0).standard_normal(1_000)
    assert sample_clock(clean, RATE_HZ).rule == "step"
    jittery = PERIOD * np.arange(1_000) + host_delays(1_000, np.random.default_rng(1))
    clock = sample_clock(jittery, RATE_HZ)
    assert clock.rule == "count" and "rows counted as samples" in clock.summary()
    assert clock.as_dict()["rule"] == "count"


def _mems_biased_run(bias_deg_s: float):
    """`_hand_run` with gyro biases of a consumer MEMS unit (an MPU-6050 reads 1-3 deg/s still)."""
    run = _hand_run()
    bias = np.radians(bias_deg_s) * np.array([1.0, -0.6, 0.4]) * PERIOD
    return run.dtheta_rad / PERIOD + bias / PERIOD, run.dv_mps / PERIOD


def _rows_still_around(rates: np.ndarray, seconds: float) -> np.ndarray:
    """Rows whose neighbours within ``seconds`` all turn by less than 5 deg/s (bias removed)."""
    bias = np.median(rates, axis=0)
    moving = np.linalg.norm(rates - bias, axis=1) > np.radians(5.0)
    k = int(round(seconds / PERIOD))
    near = np.convolve(moving.astype(float), np.ones(2 * k + 1), mode="same") > 0
    return np.flatnonzero(~near)


def test_a_mems_unit_s_sample_lost_at_rest_is_filled_however_large_its_bias(tmp_path):
    # A bias of 2 deg/s (35 mrad/s) is 35 times the absolute rule's rest rate: still is then
    # judged against the noise the log shows when still. The lost sample lies 0.5 s after a
    # turn, inside a hand's pose: the rest is a good part of the log's time, the fill is the
    # mean of the quarter second around the hole.
    rates, force = _mems_biased_run(2.0)
    still = _rows_still_around(rates, 0.5)
    after_turn = still[np.flatnonzero(np.diff(still) > 1)[2] + 1]  # the first still row 0.5 s after a turn
    path = _write_without(tmp_path / "lost_at_rest.csv", rates, force, after_turn, seed=6)
    # The shared spec: a gap is filled only when asked for; the refusal says that it can be.
    with pytest.raises(CalibError, match="1 sample.s. dropped: .*; every one where the IMU is still"):
        read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0)
    run = read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0, allow_gaps=True)
    assert run.n_samples == len(rates)
    assert [c for _, c in run.clock.dropped] == [1]
    # The filled increment is the mean of its still neighbours: the lost one to its own noise
    # (the mems profile's per-sample noise, a few mrad/s and cm/s^2 at 100 Hz; 10 times that bounds
    # it where the neighbours' mean missed the true one by their settling).
    filled_rate = run.dtheta_rad[after_turn] / PERIOD
    filled_force = run.dv_mps[after_turn] / PERIOD
    mems = load_profile("mems")
    assert np.max(np.abs(filled_rate - rates[after_turn])) < 10 * mems.arw / math.sqrt(PERIOD)
    assert np.max(np.abs(filled_force - force[after_turn])) < 10 * mems.vrw / math.sqrt(PERIOD)


def test_a_mems_unit_s_sample_lost_as_its_turn_settles_is_refused(tmp_path):
    # A tenth of a second after a turn the hand still moves: the relative rule sees it.
    rates, force = _mems_biased_run(2.0)
    bias = np.median(rates, axis=0)
    turning = np.linalg.norm(rates - bias, axis=1) > np.radians(20.0)
    ends = np.flatnonzero(turning[:-1] & ~turning[1:])
    lost = int(ends[2] + 2)  # two rows after a turn fell below 20 deg/s
    path = _write_without(tmp_path / "lost_settling.csv", rates, force, lost, seed=6)
    with pytest.raises(
        CalibError, match="lost at t = .* while the IMU turns; within 0.25 s of it the rows stray"
    ):
        read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0, allow_gaps=True)
    with pytest.raises(CalibError, match="1 sample.s. dropped: .*; 1 of them while the IMU turns"):
        read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0)


def _quantised_log(path, lost: range) -> None:
    """A still unit printed to two decimals (g, deg/s; a 1.2 deg/s gyro bias): channels that sit
    on one count, one of them ticking by a count near the hole."""
    rng = np.random.default_rng(3)
    n = 3000
    gyro = np.column_stack([1.2 + rng.normal(0, 0.1, n), rng.normal(0, 0.1, n), rng.normal(0, 0.1, n)])
    accel = np.round(np.column_stack([rng.normal(0, 0.0015, (n, 2)), 1.0 + rng.normal(0, 0.0015, n)]), 2)
    accel[1010, 2] = 1.01
    with open(path, "w") as fh:
        fh.write(
            "# latitude_deg: 45\n# height_m: 100\n"
            "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_g,accel_y_g,accel_z_g\n"
        )
        for i in range(n):
            if i not in lost:
                fh.write(",".join([repr(i / 100.0)] + [f"{x:.2f}" for x in (*gyro[i], *accel[i])]) + "\n")


def test_a_quantised_channel_s_one_count_tick_is_no_turn(tmp_path):
    # accel z sits on 1.00 g but for one row: its block spread is 0 most of the time; judged by
    # its quantisation (0.01 g / sqrt(12)) the tick is 3.5 of it, below the 6 of a stray.
    _quantised_log(tmp_path / "q.csv", range(1000, 1001))
    with pytest.raises(CalibError, match="every one where the IMU is still"):
        read_run(tmp_path / "q.csv")
    assert read_run(tmp_path / "q.csv", allow_gaps=True).n_samples == 3000


def test_a_hole_too_long_to_fill_is_said_so_before_allow_gaps_is_tried(tmp_path):
    _quantised_log(tmp_path / "q.csv", range(1000, 1300))  # 300 samples: over the 200 a fill stands for
    with pytest.raises(
        CalibError, match="1 hole.s. too long to fill .first at t = 10 s.: split the log there"
    ):
        read_run(tmp_path / "q.csv")
    with pytest.raises(CalibError, match="300 samples lost at t = 10 s, more than the 200"):
        read_run(tmp_path / "q.csv", allow_gaps=True)


@pytest.mark.parametrize("seed", range(4))
def test_the_count_rule_taken_together_counts_as_one_median_at_a_time(monkeypatch, seed):
    # The long steps' medians are taken together, each re-taken alone near a moved lag or a
    # decision's edge; with every one taken alone (TIE beyond any shift) the rule is the plain
    # loop. Stamps printed to 1 ms put medians on exact halves: the two must count alike, row
    # for row (a phone's jittering host stamps, 20 bursts of 1-5 samples lost).
    from calib.runlog import countrule

    rng = np.random.default_rng(seed)
    keep = np.ones(20_000, dtype=bool)
    for start in rng.choice(np.arange(200, 19_800), 20, replace=False):
        keep[start : start + rng.integers(1, 6)] = False
    index = np.flatnonzero(keep)
    stamps = _phone_stamps(index, rng)
    period = 1.0 / 99.7369
    periods = np.diff(stamps) / period
    counted = np.diff(stamps) > 0

    def count():
        try:
            return countrule.counted_steps(stamps, periods, counted, period)
        except CalibError as exc:  # refused alike, at the same row, with the same figures
            return str(exc)

    together = count()
    monkeypatch.setattr(countrule, "TIE", 1.0)  # every shift taken alone on the lag as it stands
    alone = count()
    assert isinstance(together, np.ndarray), together  # the case holds what it is meant to
    np.testing.assert_array_equal(together, alone)
    assert together.sum() == index[-1] - index[0]  # and each lost sample is counted
