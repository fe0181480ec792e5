"""Any grade of unit (issue 14): a MEMS unit's large errors calibrate, wrong units are still caught."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import SPEC_NAMES

from seqdesign.cli import main

# A MEMS unit before calibration (the sizes): 1000 deg/h and 20 mg biases, scale
# factors of 0.5 %, misalignments of a few hundred arcsec.
MEMS_ERRORS = dict(
    zip(
        SPEC_NAMES,
        [
            1000.0,
            -800.0,
            600.0,
            5000.0,
            -4000.0,
            3000.0,
            600.0,
            -500.0,
            400.0,
            700.0,
            -600.0,
            300.0,
            20000.0,
            -15000.0,
            10000.0,
            5000.0,
            -3000.0,
            4000.0,
            500.0,
            -400.0,
            600.0,
        ],
        strict=True,
    )
)


@pytest.fixture(scope="module")
def mems_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mems")
    errors = folder / "errors.toml"
    errors.write_text("[errors]\n" + "".join(f"{k} = {v}\n" for k, v in MEMS_ERRORS.items()))
    run = folder / "run.npz"
    res = CliRunner().invoke(
        main,
        [
            "simulate",
            "paper-9pos",
            "--errors",
            str(errors),
            "--noise-free",
            "--sample-rate-hz",
            "50",
            "-o",
            str(run),
        ],
    )
    assert res.exit_code == 0, res.output
    return run


def test_mems_sized_errors_are_recovered_exactly(mems_run, tmp_path):
    res = CliRunner().invoke(
        main,
        [
            "calibrate",
            str(mems_run),
            "--profile",
            "tactical",
            "--requirements",
            "mems",
            "--json",
            "-o",
            str(tmp_path / "r.toml"),
        ],
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["requirements"] == "mems" and doc["fit"]["converged"]
    for name, e in doc["parameters"].items():
        # Noise-free: exact to 1/20 of the (MEMS) requirement, as for navigation grade.
        assert abs(e["error"]) < e["requirement"] / 20, (name, e["error"])


def test_the_paper_requirements_still_refuse_mems_biases_as_implausible(mems_run, tmp_path):
    res = CliRunner().invoke(main, ["calibrate", str(mems_run), "-o", str(tmp_path / "r.toml")])
    assert res.exit_code == 2 and "Earth rate" in res.stderr


@pytest.mark.parametrize(
    "scale, sensor, needle",
    [
        (np.degrees(1.0), "dtheta_rad", "degrees"),  # gyro increments written in degrees
        (1.0 / 9.80665, "dv_mps", "g*s"),  # velocity increments written in g*s
    ],
)
def test_wrong_units_are_caught_whatever_the_class(mems_run, tmp_path, scale, sensor, needle):
    from calib.runlog import read_run, write_run

    run = read_run(mems_run)
    setattr(run, sensor, getattr(run, sensor) * scale)
    path = tmp_path / "wrong.npz"
    write_run(run, path)
    res = CliRunner().invoke(
        main,
        [
            "calibrate",
            str(path),
            "--profile",
            "tactical",
            "--requirements",
            "mems",
            "-o",
            str(tmp_path / "r.toml"),
        ],
    )
    assert res.exit_code == 2 and needle in res.stderr, res.stderr
