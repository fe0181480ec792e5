"""``compare A.result.toml B.result.toml``: two calibrations of one unit (the paper's Table 3)."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from seqdesign.cli import main


def _calibrated(folder, seed, errors_args):
    run = folder / f"run{seed}.npz"
    res = CliRunner().invoke(
        main,
        ["simulate", "paper-9pos", "--seed", str(seed), "--sample-rate-hz", "50", "-o", str(run)]
        + errors_args,
    )
    assert res.exit_code == 0, res.output
    out = folder / f"run{seed}.result.toml"
    res = CliRunner().invoke(main, ["calibrate", str(run), "-o", str(out)])
    assert res.exit_code == 0, res.output
    return out


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rep")
    shifted = folder / "shifted.toml"
    # The same unit with its x gyro bias moved by 0.1 deg/h: ~30 combined sigmas.
    from conftest import SPEC_NAMES, table_column_units

    table2 = table_column_units("table2_simulation", "standard")
    shifted.write_text(
        "[errors]\n" + "".join(f"{n} = {table2[n] + (0.1 if n == 'bgx' else 0.0)}\n" for n in SPEC_NAMES)
    )
    return (
        _calibrated(folder, 1, ["--table2"]),
        _calibrated(folder, 2, ["--table2"]),
        _calibrated(folder, 3, ["--errors", str(shifted)]),
    )


@pytest.mark.slow
def test_two_runs_of_one_unit_agree_and_a_changed_unit_is_flagged(results):
    a, b, changed = results
    res = CliRunner().invoke(main, ["compare", str(a), str(b), "--json"])
    assert res.exit_code == 0, res.output
    same = json.loads(res.stdout)
    # Independent noise, honest sigmas: chi2 over 21 is rarely beyond its 1 % tail.
    assert same["dof"] == 21 and same["p_value"] > 0.01 and same["flagged"] == []
    res = CliRunner().invoke(main, ["compare", str(a), str(changed), "--json"])
    moved = json.loads(res.stdout)
    assert moved["flagged"] == ["bgx"]
    assert moved["parameters"]["bgx"]["difference"] == pytest.approx(0.1, abs=0.02)


def test_compare_refuses_a_result_mixed_with_a_sequence(results):
    res = CliRunner().invoke(main, ["compare", str(results[0]), "paper-9pos"])
    assert res.exit_code == 2 and "exactly two result files" in res.stderr
