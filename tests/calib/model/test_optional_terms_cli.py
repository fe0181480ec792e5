"""The optional terms through the CLI: simulate --extra, calibrate --with, analyze --with."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from refusals import refused

from calib.calibration.result import CalibrationResult
from calib.model.optional_terms import GROUP_NAMES, OptionalTerms
from seqdesign.cli import main


@pytest.fixture
def runner():
    return CliRunner()


def test_calibrate_with_terms_lists_them_after_the_21_and_round_trips(runner, tmp_path):
    run = tmp_path / "run.npz"
    res = runner.invoke(
        main,
        [
            "simulate",
            "paper-9pos",
            "--table2",
            "--noise-free",
            "--sample-rate-hz",
            "50",
            "--extra",
            "rxx=3,k2y=20,dt_ga=0.5",
            "-o",
            str(run),
        ],
    )
    assert res.exit_code == 0, res.output
    res = runner.invoke(main, ["calibrate", str(run), "--with", "lever-arm,k2,time-offset", "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    names = list(doc["parameters"])
    extras = OptionalTerms(GROUP_NAMES)
    assert names[21:] == list(extras.names)  # after the 21, in canonical order
    assert doc["parameters"]["rxx"]["unit"] == "cm"
    assert doc["parameters"]["dt_ga"]["unit"] == "ms"
    # Noise-free: the simulated terms come back (1/20 of their typical sizes; see test_optional_terms).
    assert doc["parameters"]["rxx"]["value"] == pytest.approx(3.0, abs=0.05)
    assert doc["parameters"]["k2y"]["value"] == pytest.approx(20.0, abs=0.5)
    assert doc["parameters"]["dt_ga"]["value"] == pytest.approx(0.5, abs=0.005)
    assert doc["parameters"]["rzy"]["truth"] == 0.0
    assert doc["fit"]["extras"] == list(GROUP_NAMES)
    back = CalibrationResult.load(doc["result"])
    assert back.extras == extras
    assert back.extra_values[0] == pytest.approx(0.03, abs=5e-4)  # rxx in m
    assert np.all(back.extra_sigma > 0)


def test_analyze_with_terms_reports_cost_and_observability(runner):
    res = runner.invoke(
        main, ["analyze", "paper-9pos", "--with", "k2,time-offset", "--json", "--tolerance-deg", "0"]
    )
    assert res.exit_code == 0, res.output
    d = json.loads(res.stdout)["extras"]
    assert d["terms"] == ["k2", "time-offset"]
    # Adding unknowns never shrinks a marginal sigma (Schur complement).
    assert all(e["sigma_increase"] >= 1 - 1e-9 for e in d["parameters"].values())
    assert set(d["extra_parameters"]) == {"k2x", "k2y", "k2z", "dt_ga"}
    assert all(e["verdict"] in ("observable", "weak", "unobservable") for e in d["extra_parameters"].values())


def test_bad_terms_are_refused_without_writing(runner, tmp_path):
    refused(runner, tmp_path, ["analyze", "paper-9pos", "--with", "lever-arms"], "lever-arms", "--with")
    refused(
        runner,
        tmp_path,
        ["simulate", "paper-9pos", "-o", str(tmp_path / "r.npz"), "--extra", "rxx=abc"],
        "rxx=abc",
        "--extra",
    )
    refused(
        runner, tmp_path, ["simulate", "paper-9pos", "-o", str(tmp_path / "r.npz"), "--extra", "rqq=1"], "rqq"
    )
    refused(
        runner,
        tmp_path,
        ["simulate", "paper-9pos", "-o", str(tmp_path / "r.npz"), "--extra", "dt_ga=500"],
        "dt_ga",
        "plausible",
    )
