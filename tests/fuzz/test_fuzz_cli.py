"""Fuzzing of the CLI: mutated files of every reader through ``seqdesign``.

Exit 0 or 2, never a traceback, nothing half-written. The mutations, the budget and the
tally: ``fuzzing.py`` and ``fuzz_text.py``.
"""

from __future__ import annotations

import tomllib

import pytest
import tomli_w
from click.testing import CliRunner
from fuzz_fixtures import bases_fixture, report_tally, work_fixture  # noqa: F401 (fixtures)
from fuzz_text import CSV_RULES, TOML_RULES, mutate_tokens
from fuzzing import (
    _current_kind,
    _serial,
    budget,
    case_file,
    event,
    mutate_bytes,
    valid_result,
    valid_run,
    valid_truth,
)
from hypothesis import given, strategies as st

from calib.calibration.result import CalibrationResult
from calib.runlog import read_run, write_run
from calib.sim.truth import read_truth
from seqdesign.cli import main


def _invoke(kind: str, args: list[str]):
    _current_kind[0] = f"CLI {kind}"
    result = CliRunner().invoke(main, args)
    output = result.output
    assert "Traceback" not in output, output
    assert result.exit_code in (0, 2), (result.exit_code, output, result.exception)
    if result.exception is not None:
        assert isinstance(result.exception, SystemExit), repr(result.exception)
    if result.exit_code == 2:
        assert "error: " in output and "Traceback" not in output
        event("CLI exit 2")
    else:
        event("CLI exit 0")
    return result


def _cli_mutation(data, base: bytes, text_rules) -> bytes:
    how = data.draw(st.sampled_from(["bytes", "tokens", "tokens", "none"]), label="mutation")
    if how == "bytes":
        return mutate_bytes(data, base)
    if how == "tokens":
        return mutate_tokens(data, base, text_rules)
    return base  # the valid file: the command must then succeed and write its output


@budget(20)
@given(data=st.data())
def test_cli_show(data, bases, work):
    path = case_file(work, ".toml", _cli_mutation(data, bases["sequence"], TOML_RULES))
    _invoke("sequence", ["show", str(path)])
    _invoke("sequence", ["show", str(path), "--json"])


@budget(20)
@given(data=st.data())
def test_cli_analyze_profile(data, bases, work):
    path = case_file(work, ".toml", _cli_mutation(data, bases["profile"], TOML_RULES))
    _invoke("profile", ["analyze", "paper-9pos", "--profile", str(path), "--tolerance-deg", "0"])


@pytest.mark.parametrize(
    "arw, vrw",
    [
        ("1e-300", "1e-300"),
        ("1e300", "1e300"),
        ("1e200", "10"),
        ("5e-324", "10"),
        ("0.001", "1e-320"),
        ("1" + "0" * 400, "10"),
        ("1e-6", "1e-3"),
        ("100", "1e5"),
        ("1e-6", "1e5"),
        ("100", "1e-3"),
    ],
)
def test_cli_analyze_extreme_profiles(arw, vrw, work):
    """Profiles the reader accepts must analyse; the rest are refused, not crashed on."""
    path = case_file(work, ".toml", f'name = "p"\ngyro_arw_dph = {arw}\naccel_vrw_ug = {vrw}\n'.encode())
    _invoke("profile", ["analyze", "paper-9pos", "--profile", str(path), "--tolerance-deg", "0"])


@budget(20)
@given(data=st.data())
def test_cli_simulate_errors(data, bases, work):
    errors = case_file(work, ".toml", _cli_mutation(data, bases["truth"], TOML_RULES))
    out = work / f"sim{next(_serial):06d}.npz"
    result = _invoke(
        "errors",
        [
            "simulate",
            "paper-9pos",
            "--errors",
            str(errors),
            "-o",
            str(out),
            "--noise-free",
            "--sample-rate-hz",
            "10",
        ],
    )
    truth = out.with_name(out.stem + ".truth.toml")
    if result.exit_code == 2:
        assert not out.exists() and not truth.exists(), "a refused simulate left output behind"
    else:
        valid_run(read_run(out))
        valid_truth(read_truth(truth))
    assert not list(work.glob(f".{out.name}.*")), "temporary file left behind"


@pytest.fixture(scope="module")
def paper_run(work) -> dict[str, bytes]:
    """The paper's sequence simulated at 10 Hz (calibrates in well under a second)."""
    out = work / "paper.npz"
    result = CliRunner().invoke(
        main, ["simulate", "paper-9pos", "--table2", "--seed", "4", "--sample-rate-hz", "10", "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    write_run(read_run(out), work / "paper.csv")
    # The provenance records pytest's command line: fix it, so the cases do not depend on it.
    truth = tomllib.loads((work / "paper.truth.toml").read_text("utf-8"))
    truth["provenance"] = {"tool_version": "fuzz", "command": "seqdesign simulate paper-9pos"}
    return {
        "npz": out.read_bytes(),
        "csv": (work / "paper.csv").read_bytes(),
        "truth": tomli_w.dumps(truth).encode("utf-8"),
    }


@pytest.mark.parametrize("kind", ["csv", "npz", "truth"])
@budget(20)
@given(data=st.data())
def test_cli_calibrate(kind, data, paper_run, work):
    """A mutated run log (or the truth file beside it) through ``calibrate``."""
    if kind == "truth":
        run = case_file(work, ".npz", paper_run["npz"])
        run.with_name(run.stem + ".truth.toml").write_bytes(
            _cli_mutation(data, paper_run["truth"], TOML_RULES)
        )
    elif kind == "csv":
        run = case_file(work, ".csv", _cli_mutation(data, paper_run["csv"], CSV_RULES))
    else:
        how = data.draw(st.sampled_from(["bytes", "bytes", "none"]), label="mutation")
        run = case_file(
            work, ".npz", mutate_bytes(data, paper_run["npz"]) if how == "bytes" else paper_run["npz"]
        )
    out = run.with_name(run.stem + ".result.toml")
    result = _invoke(f"run {kind}", ["calibrate", str(run), "-o", str(out)])
    if result.exit_code == 2:
        assert not out.exists(), "a refused calibrate left a result behind"
    else:
        valid_result(CalibrationResult.load(out))  # what calibrate writes, the reader reads
    assert not list(work.glob(f".{out.name}.*")), "temporary file left behind"


def test_cli_simulate_any_angle(work):
    """Flips that are not multiples of 90 deg load, show and simulate."""
    doc = {
        "name": "odd-angles",
        "start": ["east", "up", "south"],
        "initial_dwell_s": 20.0,
        "step": [
            {"axis": "Z", "angle_deg": 45.0, "dwell_s": 10.0},
            {"axis": "X", "angle_deg": -137.5, "rate_dps": 20.0, "dwell_s": 10.0},
            {"axis": "Y", "angle_deg": 721.0, "rate_dps": 90.0, "dwell_s": 10.0},
        ],
    }
    seq = case_file(work, ".toml", tomli_w.dumps(doc).encode())
    assert _invoke("sequence", ["show", str(seq)]).exit_code == 0
    out = work / "odd.csv"
    assert (
        _invoke(
            "sequence", ["simulate", str(seq), "-o", str(out), "--sample-rate-hz", "10", "--table2"]
        ).exit_code
        == 0
    )
    valid_run(read_run(out))
    valid_truth(read_truth(work / "odd.truth.toml"))
