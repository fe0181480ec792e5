"""Physical sanity checks on runs and estimator guards: each gives the message a user sees."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.runlog import Run, write_run
from calib.sequence.definition import sequence_from_dict
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate
from seqdesign.cli import main

LAT = math.radians(40.0)
RATE = 50.0  # Hz: enough for every check, fast to calibrate


@pytest.fixture(scope="module")
def good_run():
    doc = {
        "name": "short",
        "start": ["east", "up", "south"],
        "initial_dwell_s": 40.0,
        "step": [
            {"axis": a, "angle_deg": g, "dwell_s": 40.0}
            for a, g in [
                ("Z", 90),
                ("Y", 90),
                ("X", -90),
                ("Y", -90),
                ("Y", -90),
                ("X", -90),
                ("Y", -90),
                ("Z", 90),
            ]
        ],
    }
    seq = sequence_from_dict(doc, "short")
    run, _ = simulate(
        seq,
        SimConfig(latitude_rad=LAT, sample_rate_hz=RATE),
        ErrorModel.from_table2(),
        load_profile("navigation"),
        options=SimOptions(seed=5),
    )
    return run


def _calibrate(run, tmp_path, name="bad.npz"):
    path = tmp_path / name
    write_run(run, path)
    out = tmp_path / "res.toml"
    r = CliRunner().invoke(main, ["calibrate", str(path), "-o", str(out)])
    assert "Traceback" not in r.output
    return r, out


def _variant(run, **arrays):
    fields = dict(
        time_s=run.time_s, dtheta_rad=run.dtheta_rad, dv_mps=run.dv_mps, meta=dict(run.meta), gimbal_deg=None
    )
    fields.update(arrays)
    return Run(**fields)


def test_good_run_passes_every_check(good_run, tmp_path):
    r, out = _calibrate(good_run, tmp_path, "good.npz")
    assert r.exit_code == 0, r.output
    assert out.exists()


def test_gyro_in_degrees_is_refused(good_run, tmp_path):
    r, out = _calibrate(_variant(good_run, dtheta_rad=np.degrees(good_run.dtheta_rad)), tmp_path)
    assert r.exit_code == 2 and "rad/s" in r.output and "degrees" in r.output
    assert not out.exists()


def test_gyro_rates_instead_of_increments_are_refused(good_run, tmp_path):
    # Rates logged as increments are RATE times too big: a 10 deg/s flip reads 8.7 rad/s.
    run = _variant(good_run, dtheta_rad=good_run.dtheta_rad * RATE)
    r, out = _calibrate(run, tmp_path)
    assert r.exit_code == 2 and "increments" in r.output
    assert not out.exists()


def test_accelerometer_in_g_is_refused(good_run, tmp_path):
    r, out = _calibrate(_variant(good_run, dv_mps=good_run.dv_mps / 9.80665), tmp_path)
    assert r.exit_code == 2 and "look like g*s" in r.output
    assert not out.exists()


def test_specific_force_instead_of_increments_is_refused(good_run, tmp_path):
    r, out = _calibrate(_variant(good_run, dv_mps=good_run.dv_mps * RATE), tmp_path)
    assert r.exit_code == 2 and "not increments" in r.output


def test_gravity_far_from_the_site_is_refused(good_run, tmp_path):
    run = _variant(good_run)
    run.meta["gravity_mps2"] = "9.60"  # 2 % low: no accelerometer error explains that
    r, out = _calibrate(run, tmp_path)
    assert r.exit_code == 2 and "gravity at the site" in r.output


def test_saturated_channel_is_refused(good_run, tmp_path):
    dv = good_run.dv_mps.copy()
    peak = np.abs(dv[:, 0]).max()
    dv[1000:1020, 0] = peak  # clipped for 20 samples
    r, out = _calibrate(_variant(good_run, dv_mps=dv), tmp_path)
    assert r.exit_code == 2 and "stuck at" in r.output and "sample 1000" in r.output


def test_rest_that_moves_is_refused(good_run, tmp_path):
    dv = good_run.dv_mps.copy()
    n0 = int(55 * RATE)  # inside the second rest (49..89 s)
    rng = np.random.default_rng(0)
    dv[n0 : n0 + 500] += rng.normal(0, 0.05, (500, 3)) / RATE  # 0.05 m/s^2 vibration
    r, out = _calibrate(_variant(good_run, dv_mps=dv), tmp_path)
    assert r.exit_code == 2 and "is not at rest" in r.output and "rest 2" in r.output


def test_fit_stopped_early_reports_not_converged(good_run):
    from calib.fit.estimator import fit_run
    from calib.fit.options import FitOptions
    from calib.nav.site import Site

    # One Gauss-Newton step cannot absorb the ~15 deg gyrocompassing error that Table 2's
    # 3 deg/h gyro bias causes: the fit must say it has not converged (the CLI then
    # refuses to write a result) rather than return numbers as if it had.
    fit = fit_run(
        good_run, Site(LAT, 9.8016969), load_profile("navigation"), options=FitOptions(max_iterations=1)
    )
    assert not fit.converged
    assert fit.history[-1]["max_step_sigma"] > 1.0


def test_run_that_cannot_observe_parameters_is_refused_by_name(tmp_path):
    # Spinning about a vertical Z never lets X or Y see gravity: sax, say (and the
    # z accelerometer's bias vs scale factor) are unobservable. The CLI must name
    # them, not print numbers.
    doc = {
        "name": "spin",
        "start": ["east", "north", "up"],
        "initial_dwell_s": 40.0,
        "step": [{"axis": "Z", "angle_deg": 90.0, "dwell_s": 40.0} for _ in range(4)],
    }
    seq = sequence_from_dict(doc, "spin")
    run, _ = simulate(
        seq,
        SimConfig(latitude_rad=LAT, sample_rate_hz=RATE),
        ErrorModel.zero(),
        load_profile("navigation"),
        options=SimOptions(seed=2),
    )
    r, out = _calibrate(run, tmp_path, "spin.npz")
    assert r.exit_code == 2 and "cannot observe" in r.output
    for name in ("sax", "say", "saz"):
        assert name in r.output
    assert not out.exists()


def test_profile_too_optimistic_inflates_sigmas_and_says_so(good_run, tmp_path):
    # The run carries the navigation profile's noise; calibrating with a profile of half
    # that noise density makes the whitened residual power ~4 per degree of freedom.
    # The tool must say so and scale every sigma by sqrt(chi2/dof) (Birge ratio).
    import json

    prof = tmp_path / "half.toml"
    prof.write_text('name = "half"\ngyro_arw_dph = 0.0005\naccel_vrw_ug = 5.0\n')
    path = tmp_path / "r.npz"
    write_run(good_run, path)
    r = CliRunner().invoke(
        main,
        ["calibrate", str(path), "--profile", str(prof), "-o", str(tmp_path / "half.toml.res"), "--json"],
    )
    assert r.exit_code == 0, r.output
    assert "warning: residuals are" in r.stderr and "sigmas inflated" in r.stderr
    doc = json.loads(r.stdout)
    chi2 = doc["fit"]["chi2_per_dof"]
    assert 3.0 < chi2 < 5.0  # 4 expected; +-25 % covers the ARW/VRW mix of this short run
    assert doc["fit"]["sigma_scale"] == pytest.approx(math.sqrt(chi2))
    r2 = CliRunner().invoke(main, ["calibrate", str(path), "-o", str(tmp_path / "nav.res"), "--json"])
    nav = json.loads(r2.stdout)
    assert nav["fit"]["sigma_scale"] == 1.0
    # Halving the noise halves the raw sigmas; the Birge scaling brings them back near the
    # navigation profile's (within the 25 % the chi2 estimate allows).
    for name in ("bgx", "sax", "mgxy"):
        ratio = doc["parameters"][name]["sigma"] / nav["parameters"][name]["sigma"]
        assert 0.75 < ratio < 1.25, (name, ratio)


def test_polar_site_is_refused_with_the_reason(good_run, tmp_path):
    run = _variant(good_run)
    run.meta["latitude_deg"] = "89.5"
    r, out = _calibrate(run, tmp_path)
    assert r.exit_code == 2 and "of a pole" in r.output and not out.exists()


def test_sequence_with_flips_too_slow_to_detect_is_refused(tmp_path):
    from calib.errors import CalibError

    doc = {
        "name": "slow",
        "start": ["east", "up", "south"],
        "step": [{"axis": "Z", "angle_deg": 90.0, "rate_dps": 0.5}],
    }
    with pytest.raises(CalibError, match="cannot be told from rest"):
        sequence_from_dict(doc, "slow.toml")
