"""A logger that polls the sensor: rows sampled at their stamps, integrated over their own intervals."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from calib.calibration.correction import Correction, SensorCorrection
from calib.errors import CalibError
from calib.hand.plan import PlanShape, random_hand_plan
from calib.hand.simulate import draw_errors, simulate_by_hand
from calib.model import params as P
from calib.noise.profiles import load_profile
from calib.runlog import read_run
from calib.runlog.clock import sample_clock, stamps_rate
from calib.runlog.polled import told_at_stamps, walk_ratio
from calib.sequence.kinematics import SimConfig
from seqdesign.cli import main
from seqdesign.verify import error_half_range

PERIOD = 0.005
COLUMNS = (
    "t=time_us,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps,"
    + "ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2"
)


def test_a_walk_a_jitter_and_a_clock_are_told_apart():
    rng = np.random.default_rng(1)
    n = 20_000
    k = np.arange(n)
    # Polled: independent steps of 4-6 ms. The deviation from the line walks: ratio ~1.
    polled = np.cumsum(rng.uniform(0.004, 0.006, n))
    # A host's reception delays (0-6 ms) on a 5 ms crystal: bounded, ratio ~1/100.
    jittered = PERIOD * k + rng.uniform(0.0, 0.006, n)
    # The IMU's own clock printed to 1 us: steps spread by 0.01 % of the period, not judged.
    printed = np.round(PERIOD * 1.00003 * k, 6)
    line = lambda t: t - np.polyval(np.polyfit(k, t, 1), k)  # noqa: E731
    # Tolerances: over 20,000 rows the ratio's own scatter is a few per cent.
    assert walk_ratio(line(polled), PERIOD) == pytest.approx(1.0, abs=0.2)
    assert walk_ratio(line(jittered), PERIOD) < 0.05
    assert walk_ratio(line(printed), PERIOD) == 0.0


def _polled_log(path, seed: int, rtos: bool = False):
    """A hand run at 1 kHz, read by a loop that comes round every 4-6 ms, stamped in us.

    Each row holds the mean rate and force since the loop's last pass (what a sensor's
    decimation filter gives), so integrated over the stamps' own intervals it is exact.
    ``rtos``: the loop's steps are 3 and 7 ms in turn, and once it is delayed 3 ms for good
    (an RTOS task's; its stamps do not walk, and no rule tells them from a crystal's).
    """
    rng = np.random.default_rng(seed)
    errors = draw_errors(error_half_range("mems"), rng)
    plan = random_hand_plan(16, rng, PlanShape(peak_rate_dps=300.0))
    cfg = SimConfig(latitude_rad=np.radians(45.0), height_m=0.0, sample_rate_hz=1000.0)
    run, truth = simulate_by_hand(plan, cfg, errors, load_profile("mems"), seed=seed, oversample=2)
    steps = rng.integers(4, 7, run.n_samples // 4)
    if rtos:
        steps = np.where(np.arange(len(steps)) % 2 == 0, 3, 7)
        steps[len(steps) // 2] += 3
    ends = np.cumsum(steps)
    ends = ends[ends <= run.n_samples] - 1
    starts = np.r_[0, ends[:-1] + 1]
    dt = run.time_s[ends] - np.r_[run.time_s[0] - 1e-3, run.time_s[ends[:-1]]]
    rate = np.add.reduceat(run.dtheta_rad, starts)[: len(ends)] / dt[:, None]
    force = np.add.reduceat(run.dv_mps, starts)[: len(ends)] / dt[:, None]
    rows = np.column_stack([np.round(run.time_s[ends] * 1e6), rate, force])
    np.savetxt(
        path, rows, delimiter=",", header="t,gx,gy,gz,ax,ay,az", comments="", fmt=["%d"] + ["%.9e"] * 6
    )
    return run, truth, ends


def test_a_polled_log_is_read_at_its_stamps_each_rate_over_its_own_interval(tmp_path):
    run, _, ends = _polled_log(tmp_path / "polled.csv", 3)
    got = read_run(tmp_path / "polled.csv", columns=COLUMNS, latitude_deg=45.0, height_m=0.0)
    assert got.clock.rule == "stamps" and got.clock.dropped == []
    assert np.allclose(got.time_s, run.time_s[ends], rtol=0, atol=1e-6)  # the stamps, to their 1 us
    # Each row's increment is the 1 kHz increments it spans, summed (the stamps' rounding
    # to 1 us moves an interval by 0.02 %: the tolerance).
    truth = np.add.reduceat(run.dtheta_rad, np.r_[0, ends[:-1] + 1])[: len(ends)]
    scale = np.abs(truth).max()
    assert np.allclose(got.dtheta_rad[1:], truth[1:], rtol=0, atol=5e-4 * scale)


def _hub_stamps(rng, n: int) -> np.ndarray:
    """Stamps (s) of a phone's sensor hub that polls every 20.02 ms and now and then, for a
    while, every 21.03 ms (a delay it keeps), each stamp within 0.06 ms of its poll.

    As a real phone's Sensor Logger files (a Samsung's gyro and accelerometer at 50 Hz): steps
    of 20.0 ms and 21-22 ms in a fifth of the rows, the stamps 25 ms RMS from a uniform count.
    """
    late = np.zeros(n, dtype=bool)
    chance = rng.random(n)
    for i in range(1, n):  # runs: a 21 ms spell starts with chance 1/200 a row, ends with 1/50
        late[i] = late[i - 1] != (chance[i] < (0.02 if late[i - 1] else 0.005))
    return 1e-3 * (np.cumsum(20.02 + 1.01 * late) + rng.uniform(-0.06, 0.06, n))


def test_a_hub_polling_at_two_cadences_in_spells_is_read_at_its_stamps():
    # Every step is within 5 % of the mean one, so counted step by step each row would be the
    # next sample of a uniform clock; the stamps run periods from that count (a 300 deg/s turn
    # integrated 20 ms early or late: 6 deg). The longer steps are a fifth of the rows: no
    # rare stall to leave out of the walk test (before, they were, and the rows were counted).
    rng = np.random.default_rng(5)
    stamps = _hub_stamps(rng, 10_000)
    clock = sample_clock(stamps, stamps_rate(stamps))
    assert clock.jitter_rms_s > clock.period_s
    assert clock.rule == "stamps" and clock.dropped == []
    assert np.array_equal(clock.index, np.arange(len(stamps)))  # each row the next sample


def test_a_polled_log_calibrates_honestly_through_the_cli(tmp_path):
    # Counted on a uniform clock, a 4-6 ms loop puts 0.3 deg into each turn: the moves earned
    # x10 their noise and sgy came out 4.8 sigma off (measured). At its stamps the moves fit
    # their noise and the 21 come out within 3.5 sigma of the truth.
    _, truth, _ = _polled_log(tmp_path / "polled.csv", 7)
    out = CliRunner().invoke(
        main,
        ["calibrate", str(tmp_path / "polled.csv"), "--by-hand", "--profile", "mems", "--columns", COLUMNS,
         "--latitude", "45", "--height", "0", "--json", "-o", str(tmp_path / "r.toml")],
    )  # fmt: skip
    assert out.exit_code == 0, out.output
    doc = json.loads(out.stdout)
    assert doc["by_hand"]["weights"]["white_factor"]["move"] < 1.5
    est = np.array([doc["parameters"][n]["value"] for n in P.NAMES])
    sig = np.array([doc["parameters"][n]["sigma"] for n in P.NAMES])
    z = (est - P.from_si(truth.errors.values)) / sig
    assert np.max(np.abs(z)) < 3.5, dict(zip(P.NAMES, np.round(z, 2), strict=True))
    assert doc["clock"]["rule"] == "stamps" and "samples taken at their stamps" in out.stderr


def test_a_host_clock_with_stalls_that_drain_in_bursts_is_no_walk():
    # A 200 Hz crystal, host delays 0-0.5 ms, and every 20 s a 100 ms stall that the host
    # drains at twice the rate: heavy tails in bounded jitter. Clipped at 4 robust sigmas, the
    # steps' deviation stays bounded (ratio ~1/100, threshold 0.25).
    rng = np.random.default_rng(6)
    n = 40_000
    lag = rng.uniform(0.0, 0.0005, n)
    for start in range(2000, n, 4000):
        lag[start : start + 40] += np.linspace(0.1, 0.0, 40)  # 100 ms late, made good over 40 rows
    stamps = PERIOD * np.arange(n) + lag
    k = np.arange(n)
    line = stamps - np.polyval(np.polyfit(k, stamps, 1), k)
    assert walk_ratio(line, PERIOD) < 0.1


def _rewrite(path, drop_row=None, repeat_row=None, stall_at=None, stall_us=0):
    """The polled log with one row repeated, or one stall (later stamps moved on by stall_us)."""
    lines = path.read_text().splitlines()
    header, rows = lines[0], lines[1:]
    if repeat_row is not None:
        rows.insert(repeat_row, rows[repeat_row])
    if stall_at is not None:
        for i in range(stall_at, len(rows)):
            t, rest = rows[i].split(",", 1)
            rows[i] = f"{int(t) + stall_us},{rest}"
    path.write_text("\n".join([header, *rows]) + "\n")


def test_a_repeated_row_in_a_polled_log_is_a_repeat_and_the_rest_still_at_their_stamps(tmp_path):
    path = tmp_path / "polled.csv"
    run, _, ends = _polled_log(path, 3)
    _rewrite(path, repeat_row=5000)
    with pytest.raises(CalibError, match="duplicated"):
        read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0)
    got = read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0, allow_gaps=True)
    assert got.clock.rule == "stamps" and got.n_samples == len(ends)
    truth = np.add.reduceat(run.dtheta_rad, np.r_[0, ends[:-1] + 1])[: len(ends)]
    assert np.allclose(got.dtheta_rad[1:], truth[1:], rtol=0, atol=5e-4 * np.abs(truth).max())


@pytest.mark.parametrize("turning", [False, True])
def test_a_polling_loop_that_stalls_is_refused_while_turning_and_kept_at_rest(tmp_path, turning):
    path = tmp_path / "polled.csv"
    run, _, ends = _polled_log(path, 3)
    t = run.time_s[ends]
    rate = np.linalg.norm(run.dtheta_rad, axis=1)[ends] / 1e-3
    row = int(
        np.flatnonzero(rate > 1.0)[50] if turning else np.flatnonzero(t > 10.0)[0]
    )  # 1 rad/s; static start
    _rewrite(path, stall_at=row, stall_us=60_000)  # an SD card's write: 60 ms
    with pytest.raises(CalibError, match="dropped"):
        read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0)
    if turning:
        with pytest.raises(CalibError, match="stalled for 6.*ms .* while the IMU turns"):
            read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0, allow_gaps=True)
    else:
        got = read_run(path, columns=COLUMNS, latitude_deg=45.0, height_m=0.0, allow_gaps=True)
        assert got.clock.rule == "stamps" and got.n_samples == len(ends)


def test_a_loop_whose_period_drifts_is_read_at_its_stamps_not_refused():
    # A real 154 Hz logger's loop took 6.42 ms at the start and 6.51 ms four minutes later, each
    # step within 24 us of its neighbours: too even for the polled test's 2 % gate, yet its time
    # runs periods ahead of any uniform count, which no crystal does. Each row is the next sample.
    rng = np.random.default_rng(5)
    n = 37_000
    steps = np.linspace(6.42e-3, 6.51e-3, n - 1) + rng.normal(0.0, 24e-6, n - 1)
    stamps = np.round(np.r_[0.0, np.cumsum(steps)] + 2314.9, 6)  # micros() printed to 1 us
    clock = sample_clock(stamps, stamps_rate(stamps))
    assert clock.rule == "stamps" and clock.dropped == []
    assert np.array_equal(clock.index, np.arange(n))
    # The same steps on a crystal (bounded jitter, the same spread) stay counted on its clock.
    crystal = 2314.9 + 6.465e-3 * np.arange(n) + rng.uniform(0.0, 1e-3, n)
    assert sample_clock(crystal, stamps_rate(crystal)).rule != "stamps"


def _loop_stamps(rng, n: int, delayed_every: float, delay_s: float, caught_up: bool) -> np.ndarray:
    """An 88 Hz loop (11.33 ms, 0.1 ms of jitter) printed to 1 ms: steps of 11 and 12 ms. Every
    ``delayed_every`` rows one row comes ``delay_s`` late; a crystal's next rows make it up."""
    k = np.arange(n)
    late = (np.floor(k / delayed_every) > np.floor((k - 1) / delayed_every)) & (k > 0)
    if caught_up:  # the IMU's clock: only the late row's stamp moves
        t = 11.33e-3 * k + delay_s * late
    else:  # the loop's own time: every later row moves with it
        t = 11.33e-3 * k + delay_s * np.cumsum(late)
    return np.round(107.539 + t + rng.uniform(0.0, 1e-4, n), 3)


def test_a_loop_delayed_now_and_then_is_read_at_its_stamps_not_as_lost_samples():
    # A pen IMU's Arduino loop (a real log: both its clocks agree): steps of 11 and 12 ms and one
    # of 18 ms every 466.5 rows that the loop never makes up. Each such step shifts every later
    # stamp by 0.59 period, no whole number: no crystal's lost sample (1) nor caught-up delay (0).
    # The steps' robust spread is 0 (most are 11 ms), so the walk test cannot see it.
    rng = np.random.default_rng(3)
    n = 18_917
    polled = _loop_stamps(rng, n, 466.5, 6.67e-3, caught_up=False)
    clock = sample_clock(polled, stamps_rate(polled))
    assert clock.rule == "stamps" and clock.dropped == []
    assert np.array_equal(clock.index, np.arange(n))
    # The same late rows on a crystal, each caught up by the next: the count's, nothing lost.
    crystal = _loop_stamps(rng, n, 466.5, 6.67e-3, caught_up=True)
    clock = sample_clock(crystal, stamps_rate(crystal))
    assert clock.rule != "stamps" and clock.dropped == []
    # A crystal that loses a sample every 466.5 rows: its 1-period shifts are whole, so each is
    # a sample lost, not a loop's delay.
    k = np.arange(n)
    lost = 11.33e-3 * (k + np.floor(k / 466.5))
    lossy = np.round(107.539 + lost + rng.uniform(0.0, 1e-4, n), 3)
    clock = sample_clock(lossy, 1.0 / 11.33e-3)
    assert clock.rule != "stamps" and sum(c for _, c in clock.dropped) == int(np.floor((n - 1) / 466.5))


def test_a_stall_amid_a_turn_is_a_guess_by_hand_with_gaps_allowed(tmp_path):
    # Refused unless asked; by hand with gaps allowed its row is marked, for the fit to leave
    # its move out (as a sample lost amid a turn is).
    path = tmp_path / "polled.csv"
    run, _, ends = _polled_log(path, 3)
    rate = np.linalg.norm(run.dtheta_rad, axis=1)[ends] / 1e-3
    row = int(np.flatnonzero(rate > 1.0)[50])
    _rewrite(path, stall_at=row, stall_us=60_000)
    site = dict(columns=COLUMNS, latitude_deg=45.0, height_m=0.0, allow_gaps=True)
    got = read_run(path, guess_turns=True, **site)
    assert got.clock.rule == "stamps" and got.guessed is not None
    assert np.flatnonzero(got.guessed).tolist() == [row]


def test_a_reading_told_the_rows_were_sampled_at_their_stamps_reads_them_there():
    # Stamps alternating 0.3 periods late with every later one half a period on (a loop's steps
    # of 4 and 6 ms and a delay it kept, or a host's jitter and a sample clock that slipped): no
    # rule here tells them apart, so they are refused. Told they were sampled at their stamps
    # (the CLI's --at-stamps), each row is the next sample and the clock says it was told.
    n = 10_000
    stamps = PERIOD * np.arange(n) + np.where(np.arange(n) >= 5_000, 0.5 * PERIOD, 0.0)
    stamps += 0.3 * PERIOD * (np.arange(n) % 2)
    with pytest.raises(CalibError, match="not a whole number"):
        sample_clock(stamps, 1.0 / PERIOD)
    with told_at_stamps(True):
        clock = sample_clock(stamps, 1.0 / PERIOD)
    assert clock.rule == "stamps" and clock.told and clock.dropped == []
    np.testing.assert_array_equal(clock.index, np.arange(n))
    assert "as the reading was told (the CLI's --at-stamps)" in clock.summary()
    assert not sample_clock(PERIOD * np.arange(n), 1.0 / PERIOD).told  # the flag lasts one reading
    # Its rate from the stamps is the loop's, a stall of 200 periods counted as its hole (not one
    # row: 2 % low); to the 0.3-period alternation over the span (1e-4).
    stalled = np.r_[stamps[:5000], stamps[5000:] + 200 * PERIOD]
    with told_at_stamps(True):
        assert stamps_rate(stalled) == pytest.approx(1.0 / PERIOD, rel=1e-4)
    # A clock that jumps by years is still no sample's interval.
    with told_at_stamps(True), pytest.raises(CalibError, match="the time jumps by"):
        sample_clock(np.r_[stamps, stamps[-1] + 1e8], 1.0 / PERIOD)


def test_cli_at_stamps_reads_a_logger_file_at_its_stamps_and_says_so(tmp_path):
    _polled_log(tmp_path / "polled.csv", 3)
    args = ["--columns", COLUMNS, "--latitude", "45", "--height", "0", "--at-stamps"]
    out = CliRunner().invoke(
        main, ["calibrate", str(tmp_path / "polled.csv"), "--by-hand", "--profile", "mems", *args, "--json"]
    )
    assert out.exit_code == 0, out.output
    assert "as the reading was told (the CLI's --at-stamps)" in out.stderr
    doc = json.loads(out.stdout)
    assert doc["clock"]["rule"] == "stamps" and doc["clock"]["told_at_stamps"] is True


def test_cli_corrects_a_log_told_read_at_its_stamps_and_keeps_them(tmp_path):
    # The stamps of the refusal above (0.3 periods late every other row, half a period on for
    # good from the middle), a still unit's rows: refused untold; told, corrected, the calibrated
    # log keeping its stamps (checked as they were read, read again when told again).
    n = 10_000  # 50 s: the logger-clock trend fitted over the run takes little of the shift
    stamps = PERIOD * (
        np.arange(n) + 1 + np.where(np.arange(n) >= n // 2, 0.5, 0.0) + 0.3 * (np.arange(n) % 2)
    )
    rows = [f"{round(t * 1e6)},0.001,-0.002,0.003,0.05,0.02,9.81" for t in stamps]
    log = tmp_path / "still.csv"
    log.write_text("t,gx,gy,gz,ax,ay,az\n" + "\n".join(rows) + "\n")
    corr = tmp_path / "c.toml"
    one = np.eye(3), np.zeros(3), np.full((3, 3), np.nan), np.full(3, np.nan)
    Correction(SensorCorrection(*one, "rad/s"), SensorCorrection(*one, "m/s^2")).save(corr)
    out = tmp_path / "calibrated.csv"
    args = ["correct", str(log), "--columns", COLUMNS, "--latitude", "45", "--height", "0"]
    args += ["--correction", str(corr), "-o", str(out)]
    res = CliRunner().invoke(main, args)
    assert res.exit_code != 0 and "the CLI's --at-stamps" in res.output and not out.exists()
    res = CliRunner().invoke(main, [*args, "--at-stamps"])
    assert res.exit_code == 0, res.output
    assert "read it again with --at-stamps" in res.stderr
    back = read_run(out, at_stamps=True)
    np.testing.assert_allclose(back.time_s, stamps, rtol=0, atol=1e-6)  # the stamps, to their 1 us
    # Each row's force over its own stamp interval is the still unit's, to float rounding.
    force = back.dv_mps[1:] / np.diff(back.time_s)[:, None]
    assert np.allclose(force, [0.05, 0.02, 9.81], rtol=1e-9, atol=0)
