"""Analysing a run placed by hand from its pose list: the file, the attitudes, the prediction.

The prediction is held against what it predicts: the spread of the errors of noisy runs of the
same poses, simulated and calibrated (not against the analyser's own numbers).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from calib.calibration.entry import calibrate
from calib.errors import CalibError
from calib.hand.poses import load_poses, tip_to
from calib.hand.predict import plan_sigma
from calib.hand.simulate import HandStreams, draw_errors, simulate_by_hand
from calib.model import params as P
from calib.model.requirements import load_requirements
from calib.nav.site import Site
from calib.noise.profiles import load_profile
from calib.sequence.kinematics import SimConfig
from seqdesign.cli import main
from seqdesign.hand.pose_search import HandDesignOptions, design_hand
from seqdesign.hand.prediction import analyze_hand
from seqdesign.hand.protocol import pose_toml, protocol_markdown
from seqdesign.verify import error_half_range

MEMS = load_profile("mems")
REQ = load_requirements("mems")
TWELVE = """name = "twelve"
first_rest_s = 30
hold_s = 8
move_s = 3
""" + "".join(
    f"[[pose]]\nup = {u}\n"
    for u in (
        '"+z"',
        '"+x"',
        "[1, 1, 0]",
        '"+y"',
        "[0, 1, 1]",
        '"-z"',
        "[-1, 0, -1]",
        '"-x"',
        "[-1, -1, 0]",
        '"-y"',
        "[0, -1, 1]",
        "[1, 0, 1]",
        '"+z"',
    )
)


def _write(tmp_path, text: str, name: str = "poses.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_each_pose_puts_its_up_axis_up():
    # Gravity projection: after the tip, the body vector named "up" is the ENU vertical.
    rng = np.random.default_rng(1)
    C = np.eye(3)
    for _ in range(20):
        up = rng.normal(size=3)
        C = tip_to(C, up)
        assert np.allclose(C @ (up / np.linalg.norm(up)), [0, 0, 1], atol=1e-12)
    # A half-turn (up to down) is a rotation, not a reflection.
    C = tip_to(np.eye(3), np.array([0.0, 0.0, -1.0]))
    assert np.isclose(np.linalg.det(C), 1.0) and np.allclose(C @ [0, 0, -1], [0, 0, 1])


def test_a_pose_file_with_a_typo_is_refused(tmp_path):
    with pytest.raises(CalibError, match="did you mean 'hold_s'"):
        load_poses(_write(tmp_path, TWELVE.replace("hold_s = 8", "hold_ss = 8")))
    with pytest.raises(CalibError, match="not an axis") as err:
        load_poses(_write(tmp_path, TWELVE.replace('up = "+x"', 'up = "+w"')))
    assert "pose 2" in str(err.value)
    with pytest.raises(CalibError, match="at least two"):
        load_poses(_write(tmp_path, 'name = "one"\n[[pose]]\nup = "+z"\n'))
    res = CliRunner().invoke(
        main, ["analyze", str(_write(tmp_path, TWELVE.replace("move_s", "mov_s"))), "--by-hand"]
    )
    assert res.exit_code != 0 and "Traceback" not in res.output and "did you mean" in res.output


def test_six_faces_tipped_over_edges_leave_gyro_terms_unobserved_and_name_a_cure(tmp_path):
    # Tipping a cube from face to face turns it about horizontal axes one at a time: gravity never
    # sees a turn about the vertical, so gyro scale and misalignment terms stay unobserved.
    cube = 'name = "cube"\nfirst_rest_s = 30\n' + "".join(
        f'[[pose]]\nup = "{u}"\n' for u in ("+z", "+x", "+y", "-z", "-x", "-y", "+z")
    )
    result = analyze_hand(load_poses(_write(tmp_path, cube)), MEMS, REQ)
    doc = result.to_json()
    assert "sgx" in doc["not_estimable"] and "bax" not in doc["not_estimable"]
    assert doc["unobserved_directions"] and doc["cure"]["add_pose_up"] in {"+x", "-x", "+y", "-y", "+z", "-z"}


@pytest.mark.slow
def test_the_prediction_is_what_calibrating_noisy_runs_of_the_poses_achieves(tmp_path):
    # 40 noisy runs of the same thirteen poses, each with its own MEMS-sized errors, calibrated.
    # The sigma a run reports is the predicted one (2 %: rests found in noise differ by a few
    # samples from the noise-free plan's) for the median run: a run whose residuals refute the
    # profile's noise by chance (1 % per group) or hold an outlying block (0.01 %) earns weights of
    # its own (calib.hand.weights). The RMS error over the predicted sigma is 1 within
    # its sampling spread: sqrt(chi2(40)/40) lies in [0.67, 1.36] with 99.9 % per parameter.
    poses = load_poses(_write(tmp_path, TWELVE))
    predicted = analyze_hand(poses, MEMS, REQ, cure=False).nominal.sigma
    config = SimConfig(latitude_rad=math.radians(45.0), height_m=0.0, sample_rate_hz=100.0)
    errors, reported = [], []
    for seed in range(40):
        rng = np.random.default_rng(100 + seed)
        truth = draw_errors(error_half_range("mems"), rng)
        run, _ = simulate_by_hand(poses.plan(), config, truth, MEMS, streams=HandStreams(noise=rng))
        result = calibrate(run, MEMS, by_hand=True, requirements=REQ)
        errors.append(result.values - truth.values)
        reported.append(result.sigma)
    assert np.allclose(np.median(reported, axis=0), predicted, rtol=0.02)
    ratio = np.sqrt(np.mean(np.square(errors), axis=0)) / predicted
    assert np.all((ratio > 0.67) & (ratio < 1.36)), np.round(ratio, 2)


def test_cli_analyze_by_hand_json(tmp_path):
    res = CliRunner().invoke(
        main,
        [
            "analyze",
            str(_write(tmp_path, TWELVE)),
            "--by-hand",
            "--profile",
            "mems",
            "--placements",
            "2",
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["n_poses"] == 13 and doc["placement_samples"] == 2
    # The worst over the placements is never better than the plan as drawn.
    for e in doc["parameters"].values():
        assert e["sigma"] >= e["sigma_as_planned"] * (1 - 1e-12)


def test_the_fast_information_is_the_simulated_prediction(tmp_path):
    # The design search's fast path (the fit's rows at the truth, no simulated run) against the
    # prediction through the simulator and the rest finder: 1.5 % (the rests' trimmed ends).
    poses = load_poses(_write(tmp_path, TWELVE))
    slow = analyze_hand(poses, MEMS, REQ, cure=False).nominal.sigma
    fast, estimable = plan_sigma(
        poses.attitudes(), poses.hold_s, poses.move_s, MEMS, REQ, Site.at(math.radians(45.0))
    )
    assert estimable.all()
    assert np.allclose(fast, slow, rtol=0.015)


def test_a_hand_design_observes_all_and_respects_the_bias_bound(tmp_path):
    # A 3.5 min plan with a 20 s start: every parameter estimable, no worse than its seed alone,
    # and no gyro bias better than ARW / sqrt(duration) (every second tells the bias through the
    # ARW alone: the bound no plan beats).
    design = design_hand(210.0, MEMS, REQ, HandDesignOptions(first_rest_s=20.0), counts=(13,))
    assert np.all(np.isfinite(design.sigma))
    bound = MEMS.arw / math.sqrt(design.poses.duration_s)
    assert np.all(design.sigma[P.GYRO_BIAS] >= bound * (1 - 1e-9))
    assert design.bias_bound_ratio <= design.worst_ratio
    seed_only = design_hand(210.0, MEMS, REQ, HandDesignOptions(first_rest_s=20.0), counts=(12,))
    assert design.worst_ratio <= seed_only.worst_ratio * 1.05
    # The pose list it writes reads back as the same plan, and the protocol numbers every pose.
    path = _write(tmp_path, pose_toml(design.poses, "a test"), "design.toml")
    again = load_poses(path)
    assert np.allclose(again.up, design.poses.up) and np.allclose(again.hold_s, design.poses.hold_s)
    text = protocol_markdown(design.poses, "summary")
    assert all(f"\n{k}. " in text for k in range(1, len(design.poses.up) + 1))


def test_cli_design_by_hand_refuses_a_budget_too_short(tmp_path):
    res = CliRunner().invoke(
        main, ["design", "--by-hand", "--budget-min", "1", "-o", str(tmp_path / "h.toml")]
    )
    assert res.exit_code != 0 and "Traceback" not in res.output and "fewer than" in res.output
    assert not (tmp_path / "h.toml").exists()


def test_analyze_of_a_recording_that_lost_a_sample_at_rest_fills_it_only_when_told(tmp_path):
    # The analysis of a recording reads it as calibrate does: a sample lost in the first rest is
    # refused naming --allow-gaps, and with it filled and said.
    runner = CliRunner()
    whole = tmp_path / "hand.csv"
    res = runner.invoke(
        main, ["simulate", "--by-hand", "--poses", "12", "--profile", "mems", "--seed", "3", "-o", str(whole)]
    )
    assert res.exit_code == 0, res.output
    lines = whole.read_text().splitlines()
    first_row = next(i for i, line in enumerate(lines) if line[:1].isdigit())
    lost = tmp_path / "lost.csv"
    lost.write_text("\n".join(lines[: first_row + 200] + lines[first_row + 201 :]) + "\n")  # 2 s in: still
    args = ["analyze", str(lost), "--by-hand", "--profile", "mems", "--json"]
    res = runner.invoke(main, args)
    assert res.exit_code != 0 and "--allow-gaps" in res.output
    res = runner.invoke(main, [*args, "--allow-gaps"])
    assert res.exit_code == 0, res.output
    assert "1 sample(s) the log lost at rest filled before the analysis" in res.stderr
    assert json.loads(res.stdout)["recorded"]
