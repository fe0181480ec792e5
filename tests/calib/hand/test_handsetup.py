"""The setup of a hand run checked by physics before the fit: each mistake named, or put right.

Every check rests on a fact that needs no calibration: at rest the accelerometers
read gravity, and across a move the gyro's turn carries the gravity direction of
one rest onto the next's. A log whose labels contradict either is refused with the
likely mistake (or put right under ``fix_units``); a recording carried by hand is
refused by the gimbal fit naming ``--by-hand``.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import REPO

from calib.calibration.entry import CalibrateOptions, calibrate
from calib.errors import CalibError
from calib.hand.plan import PlanShape, xsens_like_plan
from calib.hand.rests import _time_said
from calib.hand.setup import carried_by_hand, diagnose, rate_mistake, still_stretches
from calib.hand.simulate import simulate_by_hand
from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.runlog import write_run
from calib.runlog.clock import sample_clock
from calib.runlog.conversion import Conversion
from calib.sequence.kinematics import SimConfig
from calib.sim.log_mistakes import (
    accel_in_g,
    accel_in_mg,
    axes_swapped,
    axis_flipped,
    gravity_removed,
    gyro_accel_swapped,
    gyro_in_deg,
    gyro_in_mdeg,
    rate_mislabelled,
)
from seqdesign.cli import main

LAT = math.radians(45.0)
RATE_HZ = 100.0


@pytest.fixture(scope="module")
def hand_run():
    """An Xsens-shaped hand run of a MEMS unit (errors of MEMS size, the mems profile's noise)."""
    rng = np.random.default_rng(21)
    values = np.zeros(21)
    values[0:3] = np.radians([0.2, -0.3, 0.1])  # gyro biases, deg/s
    values[3:6] = [3e-3, -2e-3, 4e-3]  # gyro scale factors: unlike, below a per cent
    values[12:15] = [0.05, -0.03, 0.08]
    values[15:18] = [2e-3, 3e-3, -1e-3]
    cfg = SimConfig(latitude_rad=LAT, height_m=0.0, sample_rate_hz=RATE_HZ)
    run, truth = simulate_by_hand(xsens_like_plan(rng), cfg, ErrorModel(values), load_profile("mems"), seed=4)
    return run, cfg.gravity


@pytest.fixture(scope="module")
def plain_fit(hand_run):
    """The fit of the log as it was written: what every put-right log must give."""
    return calibrate(hand_run[0], "mems", by_hand=True)


def test_a_log_as_labelled_has_no_mistake(hand_run):
    run, g = hand_run
    assert diagnose(run, g) == []
    assert carried_by_hand(run) is not None  # carried 0.3 m on each move: a hand's


@pytest.mark.parametrize(
    ("mistake", "said"),
    [
        (accel_in_g, "the accelerometer is in g and read as m/s^2"),
        (accel_in_mg, "the accelerometer is in mg (milli-g) and read as m/s^2"),
        (gyro_in_deg, "the gyro is in deg/s and read as rad/s"),
        (gyro_in_mdeg, "the gyro is in mdeg/s (milli-degrees per second) and read as rad/s"),
        (gyro_accel_swapped, "the gyro and accelerometer columns are swapped"),
        (lambda r: axes_swapped(r, "gyro", ("x", "y")), "x and y swapped"),
        (lambda r: axis_flipped(r, "gyro", "z"), "z sign flipped"),
    ],
)
def test_each_unit_mistake_is_named(hand_run, mistake, said):
    run, g = hand_run
    found = diagnose(mistake(run), g)
    assert len(found) == 1 and said in found[0].what, found


def test_turns_sampled_too_seldom_to_integrate_are_refused_saying_so():
    # A logger that prints the rate as it is at every 20th sample (5 Hz), not its mean over the
    # interval, while a hand turns at up to 1000 deg/s: the turns move up to ~180 deg between
    # samples, and the turn integrated from them misses the gravity's change by degrees (smooth
    # simulated turns: 6.5 deg median; at 10 Hz 3.7 deg, within what a unit's errors may leave),
    # which no unit or axis mistake explains. Refused, naming the rate and the angle.
    rng = np.random.default_rng(21)
    cfg = SimConfig(latitude_rad=LAT, height_m=0.0, sample_rate_hz=RATE_HZ)
    plan = xsens_like_plan(rng, PlanShape(peak_rate_dps=1000.0))
    run, _ = simulate_by_hand(plan, cfg, ErrorModel.zero(), load_profile("mems"), seed=4)
    pick, period = slice(0, None, 20), 20.0 / RATE_HZ
    rate, force = run.dtheta_rad[pick] * RATE_HZ, run.dv_mps[pick] * RATE_HZ
    sparse = dataclasses.replace(
        run, time_s=run.time_s[pick], dtheta_rad=rate * period, dv_mps=force * period
    )
    found = diagnose(sparse, cfg.gravity)
    assert len(found) == 1 and found[0].cannot_fix, found
    assert re.search(r"at 5 Hz the unit turns up to [\d.]+ deg between samples", found[0].what), found[0].what
    with pytest.raises(CalibError, match="log the gyro at a higher rate"):
        calibrate(sparse, "mems", by_hand=True)


# The milli-unit cases are the same put-right by another factor: run with the slow tests.
@pytest.mark.parametrize(
    "mistake",
    [
        accel_in_g,
        pytest.param(accel_in_mg, marks=pytest.mark.slow),
        gyro_in_deg,
        pytest.param(gyro_in_mdeg, marks=pytest.mark.slow),
        gyro_accel_swapped,
    ],
)
def test_fix_units_puts_the_mistake_right(hand_run, plain_fit, mistake):
    run, g = hand_run
    with pytest.raises(CalibError, match="--fix-units"):
        calibrate(mistake(run), "mems", by_hand=True)
    fixed = calibrate(mistake(run), "mems", by_hand=True, options=CalibrateOptions(fix_units=True))
    plain = plain_fit
    assert any(line.startswith("fixed: ") for line in fixed.by_hand.notes)
    # Put right exactly (a unit factor or a swap): the fit of the log as it should have been.
    assert np.max(np.abs(fixed.values - plain.values) / plain.sigma) < 1e-6


@pytest.mark.parametrize(
    ("mistake", "said", "advice"),
    [
        # A phone's 'linear acceleration': |f| at rest near 0 is no unit, and no factor brings back
        # the gravity the 21 are read from.
        (lambda r, g: gravity_removed(r, g), "the logger has taken it out", "gravity included"),
        # Three times too large: no unit we know; scaling it to g would hide the scale factors.
        (lambda r, g: dataclasses.replace(r, dv_mps=3.0 * r.dv_mps, clock=None),
         "which no unit mistake we know of gives", "zero and counts per unit"),
        # A +-8 g 16-bit part's raw counts (4096 per g) read as m/s^2: named as counts, its scale
        # the one |f| at rest is near (a unit's few per cent of error keep it within 10 %).
        (lambda r, g: dataclasses.replace(r, dv_mps=r.dv_mps * 4096 / 9.80665, clock=None),
         "raw converter counts, as an accelerometer of 4096 counts per g reads", "counts_per_unit 4096"),
    ],
)  # fmt: skip
def test_an_accelerometer_no_relabelling_puts_right_is_refused_even_under_fix_units(
    hand_run, mistake, said, advice
):
    run, g = hand_run
    bad = mistake(run, g)
    for fix in (False, True):
        with pytest.raises(CalibError) as err:
            calibrate(bad, "mems", by_hand=True, options=CalibrateOptions(fix_units=fix))
        assert said in err.value.what and advice in err.value.fix and "--fix-units" not in err.value.fix


@pytest.mark.parametrize("in_counts", [False, True])
def test_an_accelerometer_zero_offset_is_named_with_the_zero_to_set(hand_run, in_counts):
    # Gravity at every rest lies on a sphere of radius g about the reading of no force: an offset
    # of (0, 0.4, 0.5) g (a real MPU-9250's log read with zero 0) puts |f| anywhere from 0.4 g to
    # 1.6 g over the poses, which no unit or scale mistake does. The sphere's centre is the
    # offset plus the accelerometer's own bias (0.05, -0.03, 0.08 m/s^2: under 0.01 g).
    run, g = hand_run
    offset = np.array([0.0, 0.4, 0.5]) * g
    dt = np.diff(run.time_s, prepend=run.time_s[0] - 1.0 / RATE_HZ)
    bad = dataclasses.replace(run, dv_mps=run.dv_mps + offset * dt[:, None], clock=None)
    counts_per_unit = np.full(3, 2048.0 / g)  # a +-16 g converter's 2048 counts per g
    if in_counts:
        zero = np.zeros(3)
        bad = dataclasses.replace(
            bad,
            conversion=Conversion(
                {"gyro": zero, "accel": zero}, {"gyro": np.ones(3), "accel": counts_per_unit}
            ),
        )
    for fix in (False, True):
        with pytest.raises(CalibError) as err:
            calibrate(bad, "mems", by_hand=True, options=CalibrateOptions(fix_units=fix))
        assert "a zero offset" in err.value.what and "--fix-units" not in err.value.fix
    centre = [float(x) for x in err.value.what.split("at (")[-1].split(")")[0].split(",")]
    np.testing.assert_allclose(centre, offset / g, atol=0.01)
    if in_counts:
        said = err.value.fix.split("zero_counts to [")[1].split("]")[0]
        np.testing.assert_allclose(
            [float(x) for x in said.split(",")], offset * counts_per_unit, atol=0.01 * 2048
        )
    else:
        assert "m/s^2 from the accelerometer columns" in err.value.fix


def test_rests_cut_out_and_joined_without_their_turns_are_refused_naming_it(hand_run, tmp_path):
    # The poses of a hand run kept, the moves between them cut out (as a log of six static faces
    # recorded one by one, or imucal's pre-cut session): gravity jumps between rests while the
    # gyro records no turn. No relabelling puts it right; the refusal says what is missing.
    run, g = hand_run
    from calib.hand.setup import still_stretches

    start, end = still_stretches(run.dtheta_rad, run.dv_mps, np.full(run.n_samples, 1.0 / RATE_HZ))
    keep = np.concatenate([np.arange(a, b) for a, b in zip(start, end, strict=True)])
    spliced = dataclasses.replace(
        run,
        time_s=(np.arange(keep.size) + 1) / RATE_HZ,
        dtheta_rad=run.dtheta_rad[keep],
        dv_mps=run.dv_mps[keep],
        clock=None,
    )
    for fix in (False, True):
        with pytest.raises(CalibError) as err:
            calibrate(spliced, "mems", by_hand=True, options=CalibrateOptions(fix_units=fix))
        assert "the log does not hold the turns between its rests" in err.value.what
        assert "one continuous recording" in err.value.fix
    # The same rests with their turns left in is no mistake (the fixture's test above).
    assert diagnose(run, g) == []


@pytest.mark.slow
def test_a_wrong_rate_shows_as_three_gyro_scale_factors_alike(hand_run, plain_fit):
    # A rate-writing logger at 102.4 Hz read as 100 Hz: every increment 2.4 % too large. The
    # fit would take it for three scale factors of +2.4 %; a MEMS gyro's are below 1 % and unlike.
    run, _ = hand_run
    wrong = rate_mislabelled(run, RATE_HZ / 1.024)
    with pytest.raises(CalibError, match=r"sample rate is likely 10[01]\.\d+ Hz, not the 97\.656 Hz"):
        calibrate(wrong, "mems", by_hand=True)
    fixed = calibrate(wrong, "mems", by_hand=True, options=CalibrateOptions(fix_units=True))
    plain = plain_fit
    # Put right at the rate the data say: a common gyro scale factor and a rate error are one
    # thing, so the fixed fit's three scale factors average zero, and their differences (the
    # unit's own, unlike) are the log's within their sigma.
    assert abs(np.mean(fixed.values[3:6])) < 1e-4
    spread_fixed = fixed.values[3:6] - np.mean(fixed.values[3:6])
    spread_plain = plain.values[3:6] - np.mean(plain.values[3:6])
    assert np.all(np.abs(spread_fixed - spread_plain) < 3 * plain.sigma[3:6])


def test_a_time_base_ten_times_too_long_is_named_with_the_likely_rate(hand_run):
    # A device's 1e-4 s ticks read as ms: every sample 10 times too long, every turn 10 times the
    # change of gravity the accelerometer sees. No unit of the gyro's explains a factor 10; the
    # rate it implies is the log's own (100 Hz) to the few per cent the carried gravity's median
    # resolves (the unit's own scale factors are 0.2-0.4 %).
    run, g = hand_run
    found = diagnose(rate_mislabelled(run, RATE_HZ / 10.0), g)
    assert len(found) == 1 and found[0].cannot_fix and "times too long" in found[0].what
    likely = float(re.search(r"likely ([0-9.]+) Hz", found[0].what).group(1))
    assert abs(likely / RATE_HZ - 1.0) < 0.05
    with pytest.raises(CalibError, match="time base is"):
        calibrate(rate_mislabelled(run, RATE_HZ / 10.0), "mems", by_hand=True)


def test_a_time_base_too_short_is_named_or_said_with_the_rate_it_reads(hand_run):
    # Read 10 times too fast the poses (5-12 s) are still 0.5-1.2 s: the turns come out a tenth
    # of gravity's change, named. Read 50 times too fast, each 0.25 s window spans more samples
    # than a pose has: no pose is still (the longer opening stretch may be), and the refusal says
    # the rate the time gives (5000 Hz) for the user to see it is not the unit's.
    run, g = hand_run
    found = diagnose(rate_mislabelled(run, RATE_HZ * 10.0), g)
    assert len(found) == 1 and re.search(r"the time base is (9\.9|10|11) times too short", found[0].what)
    said_rate = r"found [01] rest.* samples in [0-9.]+ s: 5000 Hz as the time reads"
    with pytest.raises(CalibError, match=said_rate):
        calibrate(rate_mislabelled(run, RATE_HZ * 50.0), "mems", by_hand=True)
    # Xsens' 0.1 ms ticks read as us: 51,175 samples in 5.1 s, beyond any IMU's output rate, said so.
    said = _time_said(np.zeros(0), np.zeros(0, dtype=int), np.arange(51_175) * 1e-4)
    assert "10000 Hz as the time reads, faster than IMUs output: check the time column's unit" in said


def test_a_gimbal_run_is_not_taken_for_a_hand(tmp_path):
    from calib.sequence.definition import load_sequence
    from calib.sim.gimbal_run import SimOptions, simulate

    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=100.0)
    run, _ = simulate(
        load_sequence("paper-9pos"), cfg, ErrorModel.zero(), load_profile("mems"), options=SimOptions(seed=1)
    )
    assert carried_by_hand(run) is None


def test_cli_refuses_a_hand_recording_in_the_gimbal_fit_naming_by_hand(hand_run, tmp_path):
    run, _ = hand_run
    path = tmp_path / "hand.npz"
    write_run(run, path)
    out = tmp_path / "hand.result.toml"
    res = CliRunner().invoke(main, ["calibrate", str(path), "--profile", "mems", "-o", str(out)])
    assert res.exit_code == 2 and "--by-hand" in res.output and "Traceback" not in res.output
    assert not out.exists()


def test_cli_names_the_mistake_and_fix_units_puts_it_right(hand_run, tmp_path):
    run, _ = hand_run
    path = tmp_path / "g.npz"
    write_run(accel_in_g(run), path)
    out = tmp_path / "g.result.toml"
    args = ["calibrate", str(path), "--by-hand", "--profile", "mems", "-o", str(out)]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2 and "in g and read as m/s^2" in res.output and not out.exists()
    res = CliRunner().invoke(main, [*args, "--fix-units"])
    assert res.exit_code == 0, res.output
    assert "fixed: " in res.output and out.exists()


def test_a_static_log_gets_the_one_diagnosis_of_the_gimbal_path(tmp_path):
    seq = tmp_path / "static.toml"
    seq.write_text(
        'name = "static"\nstart = ["east", "south", "down"]\ninitial_dwell_s = 60\n'
        '[[step]]\naxis = "Z"\nangle_deg = 0.001\ndwell_s = 0\n'
    )
    run_path = tmp_path / "static.npz"
    runner = CliRunner()
    res = runner.invoke(
        main, ["simulate", str(seq), "--profile", "mems", "--sample-rate-hz", "100", "-o", str(run_path)]
    )
    assert res.exit_code == 0, res.output
    for extra in (["--by-hand"], []):
        res = runner.invoke(
            main, ["calibrate", str(run_path), "--profile", "mems", *extra, "-o", str(tmp_path / "r.toml")]
        )
        assert res.exit_code == 2 and "it is a static log; use it with `seqdesign profile fit`" in res.output
        assert "Traceback" not in res.output and not (tmp_path / "r.toml").exists()


def test_a_profile_with_a_gauss_markov_bias_weights_a_hand_fit_by_its_white_part(hand_run, tmp_path):
    from calib.noise.profiles import load_profile, white_part

    run, _ = hand_run
    path = tmp_path / "hand.npz"
    write_run(run, path)
    gm = REPO / "benchmarks" / "profiles" / "adis16405.toml"
    assert load_profile(gm).has_gauss_markov
    out = tmp_path / "r.toml"
    res = CliRunner().invoke(
        main, ["calibrate", str(path), "--by-hand", "--profile", str(gm), "-o", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert "its white part weights the fit" in res.output
    white = white_part(load_profile(gm))
    assert not white.has_gauss_markov and white.gyro_arw_dph == load_profile(gm).gyro_arw_dph


def test_a_long_refusal_is_printed_within_400_characters(tmp_path):
    from calib.errors import CalibError
    from seqdesign.cli.tools import MAX_MESSAGE, refusal_line

    deep = tmp_path.joinpath(*["a-long-folder-name"] * 12) / "run.csv"
    exc = CalibError("x" * 250, f"{deep}, line 4, column t", "give the IMU's rate (--sample-rate-hz)")
    line = refusal_line(exc)
    assert len(line) <= MAX_MESSAGE and line.startswith("run.csv, line 4")
    assert line.endswith("(--sample-rate-hz))")


def test_alike_gyro_scale_factors_in_a_log_timed_by_its_stamps_blame_the_conversion():
    # A polling logger times each row by its own stamp: no rate was given to be wrong. A gyro in
    # counts read 12.5 % low is its sensitivity (an LSM6's 57.1 counts per deg/s taken for an
    # MPU's 65.5): every turn 1/0.875 = 1.143 times too short, said as such and put right by it.
    scale = np.array([-0.126, -0.124, -0.125])
    sigma = np.full(3, 0.002)
    stamped = rate_mistake(scale, sigma, 1 / 154.0, at_stamps=True, counts=True)
    assert stamped is not None and "timed by its stamps" in stamped.what
    assert "counts per unit are 1.143 times" in stamped.what and "sample rate" not in stamped.what
    assert np.allclose(stamped.gyro, np.eye(3) / 0.875) and np.allclose(stamped.accel, np.eye(3))
    assert stamped.rate_factor == 1.0
    # On a uniform clock both causes are named, and the rate is what --fix-units puts right.
    clocked = rate_mistake(scale, sigma, 1 / 154.0, counts=True)
    assert clocked is not None and "sample rate is likely 134.75 Hz, not the 154 Hz given" in clocked.what
    assert "counts per unit" in clocked.what and clocked.rate_factor == pytest.approx(0.875)
    # Unlike scale factors (a unit's own) are no such mistake.
    assert rate_mistake(np.array([-0.006, 0.004, 0.001]), sigma, 1 / 154.0, at_stamps=True) is None


def test_a_zero_offset_is_named_when_the_median_rest_still_reads_about_g(hand_run):
    # An offset of 0.48 g on z (a real flight computer's, read as m/s^2): its poses read |f| from
    # about 0.5 g to 1.5 g, the median within 15 % of g, so no unit mistake is in question; the
    # spread is the offset's, named with the zero to subtract (not left to the fit, which
    # converged on a bias of 480,000 ug, or to a pose count).
    run, g = hand_run
    offset = np.array([0.0, 0.0, 0.48]) * g
    dt = np.diff(run.time_s, prepend=run.time_s[0] - 1.0 / RATE_HZ)
    bad = dataclasses.replace(run, dv_mps=run.dv_mps + offset * dt[:, None], clock=None)
    still = diagnose(bad, g)
    assert len(still) == 1 and "a zero offset" in still[0].what
    centre = [float(x) for x in still[0].what.split("at (")[-1].split(")")[0].split(",")]
    np.testing.assert_allclose(centre, offset / g, atol=0.01)  # the bias (< 0.01 g) on top
    low, high = (float(x) for x in re.findall(r"runs from ([\d.]+) g to ([\d.]+) g", still[0].what)[0])
    assert low < 0.7 and high > 1.3
    start, end = still_stretches(bad.dtheta_rad, bad.dv_mps, dt)
    f = [np.linalg.norm(bad.dv_mps[a:b].sum(0) / dt[a:b].sum()) for a, b in zip(start, end, strict=True)]
    assert abs(np.median(f) / g - 1.0) < 0.15  # the case a unit mistake's test let through


@pytest.mark.parametrize("reads", [0.5, 2.0])
def test_a_gyro_off_by_a_power_of_two_is_its_full_scale_range_where_stamps_time_the_samples(hand_run, reads):
    # A gyro set to +-500 deg/s converted at the +-250 sensitivity reads half its turns (and the
    # converse twice). Where a host's jittering stamps time the samples, the time base cannot be
    # off by a factor: named as the range and put right under --fix-units (the same samples and
    # numbers as the log's own: to rounding). Where the time is uniform (a stated rate, a
    # counter: InvenSense and Bosch rates step by powers of two too) both are named, neither fixed.
    run, g = hand_run
    rng = np.random.default_rng(8)
    stamps = run.time_s + rng.uniform(0.0, 5e-4, len(run.time_s))  # a host's reception delays
    stamped = dataclasses.replace(run, time_s=stamps, clock=sample_clock(stamps, RATE_HZ))
    bad = dataclasses.replace(stamped, dtheta_rad=run.dtheta_rad * reads)
    found = diagnose(bad, g)
    said = "2 times" if reads == 0.5 else "half"
    assert len(found) == 1 and f"full-scale range is likely {said} the one" in found[0].what
    assert not found[0].cannot_fix and np.allclose(found[0].gyro, np.eye(3) / reads)
    fixed = calibrate(bad, "mems", by_hand=True, options=CalibrateOptions(fix_units=True))
    plain = calibrate(stamped, "mems", by_hand=True)
    np.testing.assert_allclose(fixed.values, plain.values, rtol=0, atol=1e-3 * plain.sigma.min())
    (uniform,) = diagnose(dataclasses.replace(run, dtheta_rad=run.dtheta_rad * reads, clock=None), g)
    assert "the time base is" in uniform.what and "or the gyro's unit or full-scale range" in uniform.what
    assert uniform.cannot_fix


def test_a_cheap_part_s_large_bias_is_the_fit_s_not_a_zero_offset(hand_run):
    # An ADXL345's z zero-g offset may reach 150 mg by its datasheet: |f| then spreads by 0.3 g
    # over the poses, as an offset left in does, but it is the part's bias, for the fit to
    # estimate (named only from a quarter of g on).
    run, g = hand_run
    dt = np.diff(run.time_s, prepend=run.time_s[0] - 1.0 / RATE_HZ)
    biased = dataclasses.replace(
        run, dv_mps=run.dv_mps + np.array([0.0, 0.0, 0.15 * g]) * dt[:, None], clock=None
    )
    assert diagnose(biased, g) == []
