"""Separability on a sequence that does not observe everything: Z flips only (issue 17).

Start ``east, up, south``; every flip turns about body Z. So Z points south
throughout, while X and Y turn in the east-up plane. Worked out by hand
from what each parameter multiplies (conventions.md's sensor model):

* accelerometers: X and Y each see +g and -g -> bax, sax, bay, say
  estimable; the y accelerometer sees f_x while Y is horizontal and X
  vertical, with both signs -> mayx estimable; Z never sees gravity -> saz
  multiplies zero, and baz (a constant horizontal reading along south) is a
  tilt about east -> neither estimable; mazx, mazy (z senses f_x, f_y) look
  like the tilt the X/Y gyros' Z-misalignments cause during the flips -> not
  separable;
* gyros: only turns about Z -> sgz estimable, sgx and sgy not (they would
  multiply only the Earth rate, far below any requirement); mgxz, mgyz go
  with mazx, mazy above; mgxy, mgyx, mgzx, mgzy would need turns about X or
  Y; X and Y are horizontal (east, west) at some rests with both signs, so
  their drifts tilt the platform visibly -> bgx, bgy estimable; Z is always
  south, so its drift about a fixed horizontal axis is one with the Z gyro's
  misalignment terms the sequence cannot separate -> bgz not estimable.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from seqdesign.cli import main

ESTIMABLE = {"bgx", "bgy", "sgz", "bax", "bay", "sax", "say", "mayx"}

Z_FLIPS = """name = "z-flips"
start = ["east", "up", "south"]
initial_dwell_s = 120
""" + "".join(
    f"""
[[step]]
axis = "Z"
angle_deg = {a}
dwell_s = 120
"""
    for a in (90, 90, 90, 90, -90, -90)
)


@pytest.fixture(scope="module")
def z_flips(tmp_path_factory):
    path = tmp_path_factory.mktemp("zflips") / "z-flips.toml"
    path.write_text(Z_FLIPS)
    return path


@pytest.fixture(scope="module")
def analysis(z_flips):
    res = CliRunner().invoke(main, ["analyze", str(z_flips), "--json", "--tolerance-deg", "0"])
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def test_analyze_names_exactly_the_estimable_parameters(analysis):
    assert set(analysis["estimable"]) == ESTIMABLE
    assert set(analysis["not_estimable"]) == set(analysis["parameters"]) - ESTIMABLE
    for name, e in analysis["parameters"].items():
        assert e["estimable"] == (name in ESTIMABLE)
        if e["estimable"]:
            assert e["sigma"] is not None and np.isfinite(e["sigma"])
        else:
            assert e["ratio"] is None  # JSON has no inf: not estimable has no ratio
            assert e["unobserved_directions"] and e["needs"]
    # The worst is taken among the estimable parameters only (it used to be "bgx", null).
    assert analysis["worst"]["name"] in ESTIMABLE and analysis["worst"]["ratio"] > 0
    # Z never sees gravity: saz is a direction of its own.
    assert "+1.00*saz" in analysis["unobservable"]


def test_analyze_text_names_them_and_what_motion_would_help(z_flips):
    res = CliRunner().invoke(main, ["analyze", str(z_flips), "--tolerance-deg", "0"])
    assert res.exit_code == 0, res.output
    assert "NOT ESTIMABLE on their own:" in res.stdout
    assert "saz: body Z must see +g and -g" in res.stdout
    assert "sgx: turn about body X" in res.stdout
    assert "cannot separate 13 of 21 parameters" in res.stdout


# The paper's Table 2 values on the parameters this sequence can estimate, zero on the rest:
# the unestimable ones are null only to first order, so Table 2's 100" misalignments left
# unestimated would leak into sgz at second order ((4.8e-4 rad)^2 ~ 0.2 ppm).
TABLE2_ESTIMABLE = {
    "bgx": 3.0,
    "bgy": 3.0,
    "sgz": 50.0,
    "bax": 3000.0,
    "bay": 3000.0,
    "sax": 30.0,
    "say": 30.0,
    "mayx": 50.0,
}


@pytest.fixture(scope="module")
def z_run(z_flips, tmp_path_factory):
    folder = tmp_path_factory.mktemp("zrun")
    errors = folder / "errors.toml"
    from conftest import SPEC_NAMES

    errors.write_text("[errors]\n" + "".join(f"{k} = {TABLE2_ESTIMABLE.get(k, 0.0)}\n" for k in SPEC_NAMES))
    run = folder / "run.npz"
    res = CliRunner().invoke(
        main, ["simulate", str(z_flips), "--errors", str(errors), "--noise-free", "-o", str(run)]
    )
    assert res.exit_code == 0, res.output
    return run


def test_calibrate_refuses_naming_the_same_parameters(z_run, tmp_path):
    out = tmp_path / "r.toml"
    for extra in ([], ["--json"]):
        res = CliRunner().invoke(main, ["calibrate", str(z_run), "-o", str(out)] + extra)
        assert res.exit_code == 2
        assert "cannot observe" in res.stderr
        named = res.stderr.split("cannot estimate ")[1].split(" on their own")[0].split(", ")
        assert set(named) == {
            "bgz",
            "sgx",
            "sgy",
            "mgxy",
            "mgxz",
            "mgyx",
            "mgyz",
            "mgzx",
            "mgzy",
            "baz",
            "saz",
            "mazx",
            "mazy",
        }
        assert not out.exists()


def test_partial_fit_recovers_the_estimable_with_the_analysers_sigma(z_run, analysis, tmp_path):
    out = tmp_path / "r.toml"
    res = CliRunner().invoke(main, ["calibrate", str(z_run), "--partial", "--json", "-o", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert set(doc["fit"]["not_estimable"]) == set(analysis["not_estimable"])
    for name, e in doc["parameters"].items():
        if name in ESTIMABLE:
            # Noise-free: the estimable part is recovered exactly (1/20 of the requirement,
            # the bound the 21-parameter noise-free test uses).
            assert abs(e["error"]) < e["requirement"] / 20, name
            # The analyser's nominal sigma is the estimator's: same model, same weights.
            # 2 %: the analyser's 5 s rest intervals against the estimator's 1 s.
            assert e["sigma"] == pytest.approx(analysis["parameters"][name]["sigma"], rel=0.02)
        else:
            assert e["sigma"] is None and e["estimable"] is False
    from calib.calibration.result import CalibrationResult

    back = CalibrationResult.load(out)
    assert set(back.not_estimable) == set(analysis["not_estimable"])
