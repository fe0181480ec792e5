"""Site gravity (issue 14): the accelerometer scale factors are only as good as the gravity assumed."""

from __future__ import annotations

import json
import math

import pytest
from click.testing import CliRunner
from conftest import normal_gravity

from seqdesign.cli import main


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    path = tmp_path_factory.mktemp("g") / "run.npz"
    res = CliRunner().invoke(
        main,
        ["simulate", "paper-9pos", "--table2", "--noise-free", "--sample-rate-hz", "50", "-o", str(path)],
    )
    assert res.exit_code == 0, res.output
    return path


def _fit(run, *extra):
    res = CliRunner().invoke(
        main, ["calibrate", str(run), "--json", "-o", str(run.with_suffix(".r.toml"))] + list(extra)
    )
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout), res.stderr


def test_a_gravity_error_is_a_common_scale_factor_error_no_fit_notices(run):
    g0 = normal_gravity(math.radians(40.0), 0.0)
    right, stderr = _fit(run)
    assert right["gravity"]["source"] == "normal"
    assert right["gravity"]["value_mps2"] == pytest.approx(g0, rel=1e-9)
    # The paper's 1 ppm requirement rests on modelled gravity: the tool says so.
    assert "normal gravity" in stderr and "1.02 ppm" in stderr
    wrong, _ = _fit(run, "--gravity", repr(g0 * (1 + 100e-6)))
    assert wrong["gravity"]["source"] == "measured"
    # f_meas = (1 + s) f_true with f_true = g0 fitted against g0 (1 + 1e-4): every axis's scale
    # factor absorbs -1e-4 (-100 ppm, to first order), and the residuals cannot tell.
    for name in ("sax", "say", "saz"):
        shift = wrong["parameters"][name]["value"] - right["parameters"][name]["value"]
        assert shift == pytest.approx(-100.0, abs=0.5), name
    for name in ("bgx", "mgxy", "bax", "mayx"):  # nothing else moves beyond its noise-free error
        shift = wrong["parameters"][name]["value"] - right["parameters"][name]["value"]
        assert abs(shift) < right["parameters"][name]["requirement"] / 20, name
    assert wrong["fit"]["residual_rms_mps"] < 1e-6  # a perfect fit either way
    # 1 mGal = 1e-5 m/s^2 moves each scale factor by 1e-5 / g.
    assert right["gravity"]["ppm_per_mgal"] == pytest.approx(1e-5 / g0 * 1e6, rel=1e-9)


def test_a_simulated_run_s_site_carries_its_gravity_and_where_it_came_from():
    """``SimConfig.site``: WGS-84 normal gravity at the latitude and height unless one is given."""
    from calib.sequence.kinematics import SimConfig

    lat = math.radians(52.0)
    normal = SimConfig(latitude_rad=lat, height_m=1000.0).site
    # the conventions' formula typed in from conventions.md, not the code's own earth.gravity
    assert normal.gravity_mps2 == pytest.approx(normal_gravity(lat, 1000.0), rel=1e-12)
    assert normal.gravity_source == "normal" and normal.latitude_rad == lat
    measured = SimConfig(latitude_rad=lat, height_m=1000.0, gravity_mps2=9.81).site
    assert measured.gravity_mps2 == 9.81 and measured.gravity_source == "measured"
    # the Earth rate at the site: 15.04 deg/h, its vertical part sin(lat) of it
    assert measured.omega_ie_n[2] == pytest.approx(7.292115e-5 * math.sin(lat), rel=1e-6)


def test_where_gravity_came_from_does_not_make_another_site():
    """The source is a label: the same latitude and gravity are one site to every cache keyed on it."""
    from calib.nav.jacobian import step_model
    from calib.nav.site import Site

    normal, measured = Site(0.7, 9.80, "normal"), Site(0.7, 9.80, "measured")
    assert normal == measured and hash(normal) == hash(measured)
    assert step_model(normal) is step_model(measured)  # built once, not once per label
    assert Site(0.7, 9.81) != normal  # a different gravity is a different site
