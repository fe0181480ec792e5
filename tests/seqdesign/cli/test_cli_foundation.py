"""CLI foundation: show and simulate, and clean one-line refusals that write nothing."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import (
    DWELL_S,
    FLIP_S,
    N_POS,
    SPEC_NAMES,
    normal_gravity,
    pre_attitudes,
    rest_window,
    sensor_model,
    table1_gimbal,
    table1_positions,
    table_column_si,
    table_column_units,
)
from refusals import refused

from calib.runlog import read_run
from calib.sim.truth import read_truth
from seqdesign.cli import main


@pytest.fixture
def runner():
    return CliRunner()


def test_help_lists_commands(runner):
    res = runner.invoke(main, ["--help"])
    assert res.exit_code == 0
    for cmd in ("show", "simulate"):
        assert cmd in res.stdout


def test_show_json_matches_table1(runner):
    res = runner.invoke(main, ["show", "paper-9pos", "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)  # stdout holds exactly one JSON document
    pos = doc["positions"]
    assert len(pos) == N_POS
    for p, row, gim in zip(pos, table1_positions(), table1_gimbal(), strict=True):
        assert (p["x"], p["y"], p["z"]) == (row["pre_x"], row["pre_y"], row["pre_z"])
        for key in ("outer_deg", "middle_deg", "inner_deg"):
            # integral table values; the code rounds to 1e-9 deg -> 1e-6 deg.
            assert p[key] == pytest.approx(float(gim[key]), abs=1e-6)
        start, end = rest_window(int(row["position"]))
        assert p["start_s"] == pytest.approx(start, abs=1e-9)
        assert p["end_s"] == pytest.approx(end, abs=1e-9)
    assert doc["duration_s"] == pytest.approx(9 * DWELL_S + 8 * FLIP_S, abs=1e-9)


def test_show_text(runner):
    res = runner.invoke(main, ["show", "paper-9pos"])
    assert res.exit_code == 0, res.output
    assert "9 rest positions" in res.stdout and "8 flips" in res.stdout


def test_simulate_table2_noise_free(runner, tmp_path):
    out = tmp_path / "run.npz"
    res = runner.invoke(main, ["simulate", "paper-9pos", "--table2", "--noise-free", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "Traceback" not in res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz", "run.truth.toml"]
    run = read_run(out)
    # 28 min 12 s at 200 Hz.
    assert run.n_samples == 338400 == int((9 * DWELL_S + 8 * FLIP_S) * 200)
    assert run.sample_rate_hz == 200.0
    np.testing.assert_allclose(np.diff(run.time_s), 0.005, atol=1e-9)
    assert run.latitude_deg == pytest.approx(40.0, abs=1e-12)  # the sequence's site
    truth = read_truth(tmp_path / "run.truth.toml")
    std = table_column_units("table2_simulation", "standard")
    np.testing.assert_allclose(truth.errors.in_units(), [std[n] for n in SPEC_NAMES], rtol=1e-12)
    assert truth.noise is False
    np.testing.assert_array_equal(truth.setup_rotvec, np.zeros(3))
    # The written increments carry the Table 2 errors: mean force over the first rest is
    # (I + S_a + M_a) C_n^b [0, 0, g] + b_a (exact data: rounding only, 1e-12 relative).
    Ea, ba = sensor_model(table_column_si("table2_simulation", "standard"), "accel")
    sel = (run.time_s > 10.0) & (run.time_s <= 170.0)
    f = run.dv_mps[sel].sum(0) / (sel.sum() * 0.005)
    f_true = pre_attitudes()[0].T @ [0.0, 0.0, normal_gravity(math.radians(40.0), 0.0)]
    np.testing.assert_allclose(f, Ea @ f_true + ba, rtol=0, atol=1e-12 * 9.8)


def test_simulate_json_summary(runner, tmp_path):
    out = tmp_path / "r.npz"
    res = runner.invoke(main, ["simulate", "paper-9pos", "--noise-free", "--json", "-o", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["samples"] == 338400 and doc["noise"] is False
    assert doc["profile"] == "navigation"


def write_errors(path, drop=None):
    values = table_column_units("table2_simulation", "standard")
    lines = ["[errors]"] + [f"{n} = {v}" for n, v in values.items() if n != drop]
    path.write_text("\n".join(lines) + "\n", "utf-8")


def test_refuses_unknown_sequence(runner, tmp_path):
    refused(runner, tmp_path, ["simulate", "no-such-seq", "-o", str(tmp_path / "r.npz")], "no-such-seq")
    refused(runner, tmp_path, ["show", "no-such-seq", "--json"], "no-such-seq")


def test_refuses_txt_output(runner, tmp_path):
    refused(runner, tmp_path, ["simulate", "paper-9pos", "-o", str(tmp_path / "run.txt")], ".txt")


def test_refuses_errors_and_table2(runner, tmp_path):
    err = tmp_path / "e.toml"
    write_errors(err)
    refused(
        runner,
        tmp_path,
        ["simulate", "paper-9pos", "--errors", str(err), "--table2", "-o", str(tmp_path / "r.npz")],
        "--errors",
        "--table2",
    )


def test_refuses_errors_file_missing_parameter(runner, tmp_path):
    err = tmp_path / "e.toml"
    write_errors(err, drop="mazy")
    refused(
        runner,
        tmp_path,
        ["simulate", "paper-9pos", "--errors", str(err), "-o", str(tmp_path / "r.npz")],
        "mazy",
        "e.toml",
    )


def test_refuses_unknown_profile(runner, tmp_path):
    refused(
        runner,
        tmp_path,
        ["simulate", "paper-9pos", "--profile", "nosuchprofile", "-o", str(tmp_path / "r.npz")],
        "nosuchprofile",
    )


def test_refuses_bad_sequence_file(runner, tmp_path):
    seq = tmp_path / "bad.toml"
    seq.write_text('start = ["east", "up", "south"]\n[[step]]\naxis = "W"\nangle_deg = 90\n', "utf-8")
    refused(runner, tmp_path, ["show", str(seq)], "bad.toml", "step 1")


def test_errors_file_accepted(runner, tmp_path):
    # The same file with all 21 parameters works and its values reach the truth file.
    err = tmp_path / "e.toml"
    write_errors(err)
    out = tmp_path / "r.npz"
    res = runner.invoke(
        main,
        [
            "simulate",
            "paper-9pos",
            "--errors",
            str(err),
            "--noise-free",
            "--setup-deg",
            "1",
            "-2",
            "3",
            "-o",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    truth = read_truth(tmp_path / "r.truth.toml")
    std = table_column_units("table2_simulation", "standard")
    np.testing.assert_allclose(truth.errors.in_units(), [std[n] for n in SPEC_NAMES], rtol=1e-12)
    np.testing.assert_allclose(np.degrees(truth.setup_rotvec), [1, -2, 3], rtol=1e-12)


def test_the_by_hand_options_default_to_the_library_s_values():
    # The CLI starts without calib.hand (it would load scipy): its options declare the values the
    # library's option objects hold, and this holds them to one another.
    import inspect

    from calib.hand.plan import HAND_PLAN, HAND_POSES
    from calib.hand.simulate import simulate_by_hand
    from seqdesign.cli.simulate import HAND_DEFAULTS
    from seqdesign.cli.verify import verify

    assert HAND_DEFAULTS["translation_m"] == HAND_PLAN.translation_m
    assert HAND_DEFAULTS["wobble_deg"] == HAND_PLAN.wobble_deg
    assert HAND_DEFAULTS["peak_rate_dps"] == HAND_PLAN.peak_rate_dps
    assert HAND_DEFAULTS["oversample"] == inspect.signature(simulate_by_hand).parameters["oversample"].default
    assert next(p.default for p in verify.params if p.name == "poses") == HAND_POSES
