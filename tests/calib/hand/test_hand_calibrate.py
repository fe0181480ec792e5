"""Calibrating runs placed by hand end to end: the simulator's runs, the correction, the refusals.

The simulator (:mod:`calib.hand.simulate`) is independent of the fit: it integrates a
closed-form trajectory (wobbling turn axes, a carried translation) ten times finer
than the output rate by Gauss-Legendre quadrature. Recovering its errors to a tenth
of a sigma is the proof that the fit's integration rule (interval increments, the
two-sample coning correction) is good enough at the hand's rates.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import FERRARIS, XSENS

from calib.calibration.correction import Correction, correction_of_result, raw_samples
from calib.calibration.entry import CalibrateOptions, calibrate
from calib.errors import CalibError
from calib.hand.plan import HandPlan, PlanShape, random_hand_plan, xsens_like_plan
from calib.hand.simulate import draw_errors, simulate_by_hand
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.runlog import Run, write_run
from calib.sequence.kinematics import SimConfig
from seqdesign.cli import main
from seqdesign.verify import error_half_range

MEMS = load_profile("mems")
CONFIG = SimConfig(latitude_rad=np.radians(45.4), height_m=0.0, sample_rate_hz=100.0, gravity_mps2=9.81744)


def _noise_free(plan: HandPlan, seed: int, oversample: int = 10) -> tuple[Run, np.ndarray]:
    errors = draw_errors(error_half_range("mems"), np.random.default_rng(seed))
    run, truth = simulate_by_hand(plan, CONFIG, errors, None, oversample=oversample)
    return run, truth.errors.values


@pytest.mark.parametrize("peak_rate_dps", [300.0, 1000.0])
def test_fast_hand_moves_are_integrated_to_a_tenth_of_a_sigma(peak_rate_dps):
    # Truth at 10x the output rate, turns peaking at 1000 deg/s (0.17 rad per sample) with a
    # wobbling axis: the fit's rule must leave every parameter within 0.1 sigma (the sigmas of
    # the mems profile, what a user would be told).
    plan = xsens_like_plan(np.random.default_rng(4), PlanShape(peak_rate_dps=peak_rate_dps))
    run, truth = _noise_free(plan, 4)
    result = calibrate(run, MEMS, by_hand=True, requirements="mems")
    z = (result.values - truth) / result.sigma
    assert result.converged
    assert np.max(np.abs(z)) < 0.1, dict(zip(P.NAMES, np.round(z, 3), strict=True))


def test_the_correction_applied_leaves_nothing_to_calibrate(tmp_path):
    # calibrated = M (raw - b) from the fit, applied to the log, then calibrated again: every
    # parameter is zero within a hundredth of its sigma (noise-free, so only the rule's error).
    plan = random_hand_plan(14, np.random.default_rng(8), PlanShape(peak_rate_dps=500.0))
    run, truth = _noise_free(plan, 8)
    result = calibrate(run, MEMS, by_hand=True, requirements="mems")
    correction = correction_of_result(result)
    path = tmp_path / "c.toml"
    correction.save(path)
    loaded = Correction.load(path)
    assert np.allclose(loaded.gyro.M, correction.gyro.M, rtol=0, atol=0)
    rate, force = loaded.apply(*raw_samples(run, loaded, "run"))
    dt = np.diff(np.concatenate([[run.time_s[0] - 0.01], run.time_s]))[:, None]
    again = calibrate(
        Run(run.time_s, rate * dt, force * dt, run.meta), MEMS, by_hand=True, requirements="mems"
    )
    assert np.max(np.abs(again.values / again.sigma)) < 0.02
    # M is the inverse of the fitted (I + S + M): the accelerometer's against its truth to 1e-3 sigma.
    A = np.eye(3) + 0
    for p in P.PARAMETERS[P.ACCEL_SCALE] + P.PARAMETERS[P.ACCEL_MISALIGNMENT]:
        A[p.row, p.col] += truth[p.index]
    assert np.allclose(correction.accel.M @ A, np.eye(3), atol=1e-5)


def test_a_correction_in_counts_needs_the_conversion():
    plan = random_hand_plan(6, np.random.default_rng(1))
    run, _ = _noise_free(plan, 1)
    correction = correction_of_result(
        calibrate(run, MEMS, by_hand=True, requirements="mems", options=CalibrateOptions(partial=True))
    )
    counts = Correction(
        correction.gyro.__class__(
            *[getattr(correction.gyro, f) for f in ("M", "b", "sigma_M", "sigma_b")], "counts"
        ),
        correction.accel,
    )
    with pytest.raises(CalibError, match="counts"):
        raw_samples(run, counts, "run.csv")


def test_too_few_poses_are_refused_naming_what_is_not_estimable():
    # Three rests: 9 accelerometer unknowns cannot come from three gravity directions.
    plan = random_hand_plan(3, np.random.default_rng(2))
    run, _ = _noise_free(plan, 2)
    # The poses and moves counted for the user (three random poses 30 deg or more apart, both
    # moves whole): none of the 21 comes out.
    with pytest.raises(
        CalibError, match=r"\(3 rests in 3 poses 10 deg apart, 2 of 2 moves used\): none is"
    ) as err:
        calibrate(run, MEMS, by_hand=True, requirements="mems")
    assert "add poses" in str(err.value.fix)


def test_scale_factors_known_to_no_better_than_a_per_cent_are_not_to_be_applied():
    # Eight random poses with the mems profile's noise separate all 21, but some scale factors
    # only to a few per cent: there the error model's products of errors (1e-4 at 1 %) pass a
    # MEMS requirement, and the linearised estimate and sigma no longer describe the fit.
    plan = random_hand_plan(8, np.random.default_rng(3))
    errors = draw_errors(error_half_range("mems"), np.random.default_rng(2))
    run, _ = simulate_by_hand(plan, CONFIG, errors, MEMS, seed=3)
    result = calibrate(run, MEMS, by_hand=True, requirements="mems")
    loose = [p.name for p in P.PARAMETERS if p.kind != "bias" and result.sigma[p.index] > 1e-2]
    assert loose  # the case holds what it is meant to
    (said,) = [w for w in result.warnings() if "barely determines" in w]
    assert all(name in said for name in loose) and "do not apply" in said


def test_cli_partial_with_no_parameter_estimable_says_so(tmp_path):
    # Two rests and one move: no one of the 21 is separable (a tilt and a heading per rest take
    # what gravity and one turn could tell). --partial asked for what is estimable: none, said
    # as such, with the table of its n/e rows and the result file written whole.
    run, _ = _noise_free(random_hand_plan(2, np.random.default_rng(2)), 2)
    path = tmp_path / "two.csv"
    write_run(run, path)
    out = tmp_path / "two.result.toml"
    res = CliRunner().invoke(
        main, ["calibrate", str(path), "--by-hand", "--profile", "mems", "--partial", "-o", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert "no parameter estimable" in res.stdout and out.exists()


def test_cli_calibrates_a_simulated_hand_run_and_writes_its_correction(tmp_path):
    runner = CliRunner()
    run_path = tmp_path / "hand.csv"
    res = runner.invoke(
        main,
        [
            "simulate",
            "--by-hand",
            "--poses",
            "12",
            "--profile",
            "mems",
            "--random-errors",
            "mems",
            "--seed",
            "5",
        ]
        + ["-o", str(run_path)],
    )
    assert res.exit_code == 0, res.output
    res = runner.invoke(
        main,
        ["calibrate", str(run_path), "--by-hand", "--profile", "mems", "--requirements", "mems", "--json"]
        + ["--correction", str(tmp_path / "c.toml")],
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["fit"]["converged"] and len(doc["by_hand"]["rests"]) == 12
    assert len(doc["by_hand"]["moves"]) == 11
    # With the simulator's truth beside it: the NEES of an honest fit, well inside chi2(21)'s 99.9 %.
    assert doc["nees"] < 46.8
    out = tmp_path / "calibrated.csv"
    res = runner.invoke(
        main, ["correct", str(run_path), "--correction", str(tmp_path / "c.toml"), "-o", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert out.exists()


def test_cli_refuses_by_hand_with_a_sequence_or_stream(tmp_path):
    runner = CliRunner()
    run_path = tmp_path / "hand.csv"
    runner.invoke(main, ["simulate", "--by-hand", "--poses", "5", "--noise-free", "-o", str(run_path)])
    for extra in (["--stream"], ["--sequence", "paper-9pos"], ["--with", "lever-arm"]):
        res = runner.invoke(
            main, ["calibrate", str(run_path), "--by-hand", "-o", str(tmp_path / "r.toml")] + extra
        )
        assert res.exit_code != 0
        assert "Traceback" not in res.output and "error:" in res.output
        assert not (tmp_path / "r.toml").exists()


FERRARIS_COLUMNS = (
    "n_samples=counter,gyr_x=gyro_x_dps,gyr_y=gyro_y_dps,gyr_z=gyro_z_dps,"
    "acc_x=accel_x_mps2,acc_y=accel_y_mps2,acc_z=accel_z_mps2"
)


def test_imu_tk_recording_calibrates_as_it_is(tmp_path):
    # imu_tk's two files in raw counts with the datasheet values, through the CLI: all rests of
    # the recording (a 52 s start and 37 poses) and every move before the clipped end are used,
    # and with the gyro g-sensitivity the residuals are the profile's noise (chi2/dof near 1;
    # 16 without the term: the docs' evidence for it).
    d = XSENS
    res = CliRunner().invoke(
        main,
        ["calibrate", str(d / "xsens_acc.mat.gz"), "--gyro-file", str(d / "xsens_gyro.mat.gz")]
        + ["--conversion", str(d / "xsens-nominal-values.txt"), "--by-hand", "--profile", "mems"]
        + ["--latitude", "45.4", "--height", "0", "--with", "g-sensitivity", "--json"]
        + ["-o", str(tmp_path / "x.toml"), "--correction", str(tmp_path / "x.correction.toml")],
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["fit"]["converged"]
    assert len(doc["by_hand"]["rests"]) == 38
    assert all(m["used"] for m in doc["by_hand"]["moves"])
    assert 0.7 < doc["fit"]["chi2_per_dof"] < 1.5
    assert doc["gravity"]["value_mps2"] == pytest.approx(9.81744)
    # The correction is in counts: a gyro at rest near the 16-bit zero, scale ~1/4770 rad/s per count.
    c = Correction.load(tmp_path / "x.correction.toml")
    assert c.gyro.raw_unit == "counts"
    assert np.allclose(np.diag(c.gyro.M), 1 / 4770, rtol=0.01)
    assert np.allclose(c.gyro.b, 32768, atol=400)


def test_imucal_recording_calibrates_by_its_sample_counter(tmp_path):
    # The Ferraris session: six faces and three turns about vertical axes, read by its counter
    # at 102.4 Hz. Each of imucal's six annotated faces lies inside one of the rests found.
    path = FERRARIS / "example_ferraris_session.csv"
    res = CliRunner().invoke(
        main,
        ["calibrate", str(path), "--columns", FERRARIS_COLUMNS, "--sample-rate-hz", "102.4", "--by-hand"]
        + ["--profile", "mems", "--latitude", "49.6", "--height", "300", "--gravity", "9.81", "--json"]
        + ["-o", str(tmp_path / "f.toml")],
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["fit"]["converged"]
    rests = [(r["start_s"], r["end_s"]) for r in doc["by_hand"]["rests"]]
    sections = json.loads((path.parent / "example_ferraris_session_list.json").read_text())
    for name in ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a"):
        a, b = sections[name]["start"] / 102.4, sections[name]["end"] / 102.4
        assert any(lo <= a and b <= hi for lo, hi in rests), name
    # At the profile's weights its fast flips leave chi2/dof 3.4; the weights the residuals earn
    # bring it to 1 (each group's variance over its redundancy). Most of its flips, not one, lie
    # beyond the ARW (8 of 11 at the profile's weights above white noise's median), so the moves
    # earn their noise as a group (a white factor well above 1) rather than a few being
    # weighted out and the rest left to vouch for the profile.
    assert 0.7 <= doc["fit"]["chi2_per_dof"] <= 1.5
    assert doc["by_hand"]["weights"]["white_factor"]["move"] > 2.0
    # The gyro's g-sensitivity is tested and not chosen: every element within 1.3 sigma of zero.
    assert doc["by_hand"]["model"][0] == {
        **doc["by_hand"]["model"][0],
        "term": "g-sensitivity",
        "fitted": False,
    }


def test_analyze_of_a_recording_is_the_sigma_calibrating_it_reports(tmp_path):
    # From the recording's own rests and moves: the prediction is the fit's covariance, so it is
    # what calibrate reports (its chi2/dof 1.03 is below the Birge limit: no inflation either side).
    d = XSENS
    reading = [
        "--gyro-file",
        str(d / "xsens_gyro.mat.gz"),
        "--conversion",
        str(d / "xsens-nominal-values.txt"),
    ]
    reading += [
        "--profile",
        "mems",
        "--latitude",
        "45.4",
        "--height",
        "0",
        "--with",
        "g-sensitivity",
        "--json",
    ]
    runner = CliRunner()
    res = runner.invoke(main, ["analyze", str(d / "xsens_acc.mat.gz"), "--by-hand", *reading])
    assert res.exit_code == 0, res.output
    predicted = json.loads(res.stdout)
    res = runner.invoke(
        main,
        ["calibrate", str(d / "xsens_acc.mat.gz"), "--by-hand", *reading, "-o", str(tmp_path / "r.toml")],
    )
    achieved = json.loads(res.stdout)
    assert predicted["recorded"] and predicted["n_poses"] == 38
    for name in P.NAMES:
        assert predicted["parameters"][name]["sigma"] == pytest.approx(
            achieved["parameters"][name]["sigma"], rel=0.1
        )


def test_verify_a_pose_list_against_its_prediction(tmp_path):
    # The Monte Carlo of a pose list is held against analyze --by-hand's prediction: the column
    # the random-pose verification leaves empty is filled, and a few runs stay honest.
    poses = tmp_path / "poses.toml"
    ups = ["+z", "+x", "[1, 1, 0]", "+y", "[0, 1, 1]", "-z", "[-1, 0, -1]", "-x", "[-1, -1, 0]", "-y"]
    ups += ["[0, -1, 1]", "[1, 0, 1]", "+z"]
    poses.write_text(
        'name = "twelve"\nfirst_rest_s = 30\n'
        + "".join(
            f"[[pose]]\nup = {u if u.startswith('[') else repr(u).replace(chr(39), chr(34))}\n" for u in ups
        )
    )
    res = CliRunner().invoke(
        main, ["verify", str(poses), "--by-hand", "--profile", "mems", "--runs", "3", "--seed", "2", "--json"]
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["requirements"] == "mems" and doc["converged"] == 3
    assert all(e["predicted_sigma"] is not None for e in doc["parameters"].values())


def test_a_gyro_of_range_250_dps_clipping_fast_turns_costs_those_moves_not_the_gyro(tmp_path):
    # A MEMS unit turned by hand at up to 400 deg/s, logged by a 16-bit gyro of range
    # 250 deg/s (131 counts per deg/s, a common default) and an accelerometer of range 2 g,
    # as a logger writes deg/s and g. The clipped turns lose an unknown part of their angle:
    # they must be named and left out, not fitted with a move noise inflated for all
    # (which the old 286 deg/s floor for flat tops did: moves white x9.8, gyro sigmas x7).
    rng = np.random.default_rng(5)
    errors = draw_errors(error_half_range("mems"), rng)
    plan = random_hand_plan(20, rng, PlanShape(peak_rate_dps=400.0))
    run, truth = simulate_by_hand(plan, CONFIG, errors, MEMS, seed=5)
    dt = 1.0 / CONFIG.sample_rate_hz
    gyro = np.clip(np.round(np.degrees(run.dtheta_rad / dt) * 131.0), -32768, 32767) / 131.0
    accel = np.clip(np.round(run.dv_mps / dt / 9.80665 * 16384.0), -32768, 32767) / 16384.0
    clipped = np.abs(gyro) >= 32767 / 131.0
    assert clipped.any(axis=1).sum() >= 10  # the case: some turns do exceed the range
    rows = np.column_stack([run.time_s, gyro, accel])
    log = tmp_path / "clipped.csv"
    np.savetxt(log, rows, delimiter=",", header="t,gx,gy,gz,ax,ay,az", comments="", fmt="%.6f")
    columns = "t=time_s,gx=gyro_x_dps,gy=gyro_y_dps,gz=gyro_z_dps,ax=accel_x_g,ay=accel_y_g,az=accel_z_g"
    args = ["calibrate", str(log), "--by-hand", "--profile", "mems", "--columns", columns, "--json"]
    site = ["--latitude", "45.4", "--height", "0", "--gravity", "9.81744"]
    out = CliRunner().invoke(main, args + site + ["-o", str(tmp_path / "r.toml")])
    assert out.exit_code == 0, out.output
    doc = json.loads(out.stdout)
    moves = doc["by_hand"]["moves"]
    left_out = [m for m in moves if not m["used"]]
    assert left_out  # the clipped turns
    t = run.time_s
    for m in left_out:  # each one holds clipped samples
        inside = (t > m["start_s"]) & (t <= m["end_s"] + dt)
        assert clipped[inside].any()
    # The moves kept fit at the profile's noise (earned factor: white noise gives 1 +- ~0.3
    # over ~15 moves of 3 dof), and the 21 come out within 3.5 sigma of the truth.
    assert doc["by_hand"]["weights"]["white_factor"]["move"] < 1.5
    est = np.array([doc["parameters"][n]["value"] for n in P.NAMES])
    sig = np.array([doc["parameters"][n]["sigma"] for n in P.NAMES])
    z = (est - P.from_si(truth.errors.values)) / sig
    assert np.max(np.abs(z)) < 3.5, dict(zip(P.NAMES, np.round(z, 2), strict=True))


def test_a_correction_in_counts_for_one_sensor_and_g_for_the_other_reads_each_in_its_own_unit():
    # A correction written by hand: the gyro's raw unit counts, the accelerometer's g. Each
    # sensor's samples must reach it in its own unit: counts = si * scale + zero for the gyro,
    # si / 9.80665 for the accelerometer (the standard g a "g" unit means).
    from types import SimpleNamespace

    from calib.calibration.correction import SensorCorrection
    from calib.runlog.conversion import Conversion

    rng = np.random.default_rng(3)
    time_s = np.arange(1, 201) * 0.01
    rate, force = rng.normal(0, 1, (200, 3)), rng.normal(0, 9, (200, 3))
    zero = {"gyro": np.array([10.0, -20.0, 30.0]), "accel": np.array([1.0, 2.0, 3.0])}
    scale = {"gyro": np.array([900.0, 950.0, 1000.0]), "accel": np.array([400.0, 410.0, 420.0])}
    run = SimpleNamespace(
        time_s=time_s, dtheta_rad=rate * 0.01, dv_mps=force * 0.01, conversion=Conversion(zero, scale)
    )
    eye, zero3 = np.eye(3), np.zeros(3)
    mixed = Correction(
        SensorCorrection(eye, zero3, eye, zero3, "counts"), SensorCorrection(eye, zero3, eye, zero3, "g")
    )
    raw_rate, raw_force = raw_samples(run, mixed, "mixed.toml")
    assert np.allclose(raw_rate, rate * scale["gyro"] + zero["gyro"], rtol=1e-12)
    assert np.allclose(raw_force, force / 9.80665, rtol=1e-12)


def test_estimates_beyond_any_triad_are_recovered_and_said_to_be_checked():
    # A gyro z scale factor of -10 % (a unit read at the wrong sensitivity, or moves the fit
    # cannot trust) is recovered, noise-free: the model (I + S + M, inverted exactly) describes
    # any linear triad. No triad is built that far off, so it is said, with what to check before
    # applying it. A misalignment of 1.7 deg (3e-2 rad) is a real triad's and is not named.
    errors = draw_errors(error_half_range("mems"), np.random.default_rng(5))
    values = errors.values.copy()
    values[P.INDEX["sgz"]], values[P.INDEX["mgxy"]] = -0.10, 0.03
    plan = xsens_like_plan(np.random.default_rng(5))
    run, _ = simulate_by_hand(plan, CONFIG, ErrorModel(values), None, oversample=10)
    result = calibrate(run, MEMS, by_hand=True, requirements="mems")
    assert abs(result.values[P.INDEX["sgz"]] + 0.10) < 1e-4
    (said,) = [w for w in result.warnings() if "beyond 5 %" in w]
    assert "sgz -10 %" in said and "mgxy" not in said and "check the conversion" in said


def test_poses_held_too_briefly_for_a_rest_are_said_with_their_times(tmp_path):
    # Two of fourteen poses held 0.7 s, under the 1.0 s a pose needs to give a rest (the finder
    # keeps 0.425 s clear of each move, and a rest is 0.15 s or more). They are left in the moves,
    # and a user is told so, with their times, in the lines and in --json: not told to add faces.
    plan = random_hand_plan(14, np.random.default_rng(3), PlanShape(peak_rate_dps=300.0))
    rest_s = plan.rest_s.copy()
    rest_s[[4, 9]] = 0.7
    plan = replace(plan, rest_s=rest_s)
    errors = draw_errors(error_half_range("mems"), np.random.default_rng(3))
    run, _ = simulate_by_hand(plan, CONFIG, errors, MEMS, seed=3)
    path = tmp_path / "brief.csv"
    write_run(run, path)
    done = CliRunner().invoke(main, ["calibrate", str(path), "--by-hand", "--profile", "mems", "--json"])
    assert done.exit_code == 0, done.output
    hand = json.loads(done.stdout)["by_hand"]
    assert len(hand["rests"]) == 12
    # Each is found about its own pose: overlapping it, and holding none of the turns either side
    # (the unit is quiet too while lifted and set down, before and after a turn).
    begins = np.concatenate([[0.0], np.cumsum(plan.rest_s[:-1] + plan.move_s)])
    brief = np.array(hand["brief_poses_s"])
    assert brief.shape == (2, 2)
    for (a, b), k in zip(brief, [4, 9], strict=True):
        assert a < begins[k] + 0.7 and b > begins[k]
        assert plan.turn_start_s[k - 1] + plan.turn_s[k - 1] <= a and b <= plan.turn_start_s[k]
    done = CliRunner().invoke(main, ["calibrate", str(path), "--by-hand", "--profile", "mems"])
    said = [line for line in done.output.splitlines() if "held too briefly" in line]
    assert (
        len(said) == 1
        and f"2 pose(s) held too briefly for a rest, not used (from {brief[0, 0]:.1f}, " in said[0]
    )
