"""``profile fit`` on a simulated static log (known noise) and on the real ADIS log."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import ADIS, needs

from calib.model.error_model import ErrorModel
from calib.noise.profiles import NoiseProfile, load_profile
from calib.runlog import Run, read_run, write_run
from calib.sequence.definition import Sequence, Step
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate
from seqdesign.cli import main

# The simulated unit: white noise and a first-order GM bias on every axis.
TRUE = NoiseProfile(
    "truth",
    gyro_arw_dph=0.1,
    accel_vrw_ug=50.0,
    gyro_bias_instability_dph=5.0,
    gyro_bias_correlation_s=10.0,
    accel_bias_instability_ug=50.0,
    accel_bias_correlation_s=10.0,
)

STATIC_S = 3000.0  # 300 GM correlation times


def static_log(path: Path, seed: int = 3) -> Path:
    """A static log from our simulator: 3000 s at 100 Hz, X east, Y south, Z down.

    The sequence's one flip comes after the static part, which is all we keep.
    """
    seq = Sequence(
        name="static",
        start=("east", "south", "down"),
        steps=(Step("Z", 90.0, 10.0, 1.0),),
        initial_dwell_s=STATIC_S,
    )
    run, _ = simulate(
        seq,
        SimConfig(latitude_rad=math.radians(51.08), sample_rate_hz=100.0),
        ErrorModel.zero(),
        TRUE,
        options=SimOptions(seed=seed),
    )
    keep = run.time_s <= STATIC_S
    meta = {k: v for k, v in run.meta.items() if k != "sequence"}
    write_run(
        Run(time_s=run.time_s[keep], dtheta_rad=run.dtheta_rad[keep], dv_mps=run.dv_mps[keep], meta=meta),
        path,
    )
    return path


@pytest.mark.slow
def test_simulated_static_log_recovers_the_noise(tmp_path):
    log = static_log(tmp_path / "static.npz")
    out = tmp_path / "unit.toml"
    result = CliRunner().invoke(main, ["profile", "fit", str(log), "-o", str(out), "--no-plot"])
    assert result.exit_code == 0, result.output
    doc = tomllib.loads(out.read_text())
    fit = doc["fit"]
    # White noise: 3e5 samples put ~1 % scatter on N; 10 % is the bound.
    np.testing.assert_allclose(fit["gyro"]["arw_dph"], TRUE.gyro_arw_dph, rtol=0.10)
    np.testing.assert_allclose(fit["accel"]["vrw_ug"], TRUE.accel_vrw_ug, rtol=0.10)
    # GM: 300 correlation times give ~8 % (1-sigma) scatter near the peak; 25 % is the
    # issue's bound (about 3 sigma).
    np.testing.assert_allclose(fit["gyro"]["gm_sigma_dph"], 5.0, rtol=0.25)
    np.testing.assert_allclose(fit["accel"]["gm_sigma_ug"], 50.0, rtol=0.25)
    np.testing.assert_allclose(fit["gyro"]["gm_correlation_s"], 10.0, rtol=0.25)
    np.testing.assert_allclose(fit["accel"]["gm_correlation_s"], 10.0, rtol=0.25)
    # The file is a profile the other commands accept, its scalars the worst axis.
    prof = load_profile(out)
    assert prof.gyro_arw_dph == max(fit["gyro"]["arw_dph"])
    assert prof.has_gauss_markov
    # Noise-free errors: the accelerometer bias along the up is 0 to the noise
    # (VRW 50 ug/sqrt(Hz) over 3000 s averages to ~1 ug; the GM adds ~50 ug / sqrt(150)).
    assert abs(fit["accel"]["bias_ug"][2]) < 20.0


@pytest.mark.slow
def test_a_gm_whose_sigma_and_time_are_not_determined_apart_is_not_written(tmp_path):
    # The README's 20-min static log of a white-noise (`mems`) unit, the draw of seed 34: the
    # gyro deviation fitted over 10-97 s scatters up at its last taus, and the minimax GM
    # followed it with sigma 1142 deg/h over 769,000 s, far beyond the taus fitted, where a GM
    # shows only as a rate random walk (sigma^2 / tau); the file it wrote did not load. The
    # unit has no GM: none may be written, and the file must load.
    seq = tmp_path / "static.toml"
    seq.write_text(
        'name = "static"\nstart = ["east", "south", "down"]\ninitial_dwell_s = 1200\n'
        '[[step]]\naxis = "Z"\nangle_deg = 0.001\ndwell_s = 0\n'
    )
    log, out = tmp_path / "static.npz", tmp_path / "myimu.toml"
    runner = CliRunner()
    sim = ["simulate", str(seq), "--profile", "mems", "--sample-rate-hz", "100", "--seed", "34"]
    result = runner.invoke(main, sim + ["--latitude", "51.08", "--height", "1100", "-o", str(log)])
    assert result.exit_code == 0, result.output
    result = runner.invoke(main, ["profile", "fit", str(log), "-o", str(out), "--no-plot"])
    assert result.exit_code == 0, result.output
    prof = load_profile(out)
    assert prof.gyro_bias_instability_dph == 0.0
    assert "not determined apart" in out.read_text()


def independent_oadev(rate: np.ndarray, m: int) -> float:
    """Overlapping Allan deviation at m samples, straight from its definition (no allantools)."""
    phase = np.concatenate([[0.0], np.cumsum(rate)])
    d = phase[2 * m :] - 2 * phase[m:-m] + phase[: -2 * m]
    return math.sqrt(np.mean(d**2) / 2.0) / m


@pytest.mark.slow
@needs(ADIS)
def test_adis_log_against_an_independent_allan_deviation(tmp_path):
    out = tmp_path / "adis.toml"
    result = CliRunner().invoke(
        main, ["profile", "fit", str(ADIS), "--latitude", "51.08", "-o", str(out), "--no-plot", "--json"]
    )
    assert result.exit_code == 0, result.output
    text = out.read_text()
    fit = tomllib.loads(text)["fit"]
    # The fit follows the curve: every axis within +-25 % over its stated range, which
    # runs from the shortest taus (0.02 s; 0.04 s on the z gyro, whose 0.02-0.03 s
    # disturbance is not quantisation) to beyond 500 s; no quantisation, no GM on a
    # bound (the accelerometers' 0.56 Hz disturbance is a sinusoid, not a 1 s GM).
    for sensor in ("gyro", "accel"):
        for j in range(3):
            lo, hi = fit[sensor]["fit_ratio"][j]
            assert 0.75 <= lo <= hi <= 1.25, (sensor, j, lo, hi)
            start, end = fit[sensor]["fit_tau_s"][j]
            assert start < 0.045 and end >= 500.0, (sensor, j, start, end)
            tc = fit[sensor]["gm_correlation_s"][j]
            assert tc == 0.0 or tc > 1.01, (sensor, j, tc)
    assert fit["gyro"]["quantisation_urad"] == [0.0, 0.0, 0.0]
    assert all(0.5 < f < 0.6 for f in fit["accel"]["sinusoid_hz"])
    # The profile's single GM follows the worst axis over 10 s on, and says how well
    # and what it leaves out, in the file's opening comment too.
    table = fit["profile"]
    assert table["gyro_tau_s"][0] >= 10.0 and table["accel_tau_s"][0] >= 10.0
    assert 0.8 <= table["gyro_ratio"][0] and table["gyro_ratio"][1] <= 1.2
    assert 0.7 <= table["accel_ratio"][0] and table["accel_ratio"][1] <= 1.35
    assert "rate random walk" in " ".join(table["gyro_not_modelled"])
    opening = text.split("\nname = ")[0]
    assert "# gyro: not modelled by the scalars: " in opening and "rate random walk" in opening
    run = read_run(ADIS, latitude_deg=51.08, height_m=1100.0)
    dt = run.dt_nominal
    # The independent white region: 0.04-0.16 s (m = 4..16), where this curve's slope
    # is -1/2 on every channel (checked below); the accelerometers' disturbance starts at ~0.3 s and
    # the gyros' shortest taus are bent by the sensor's filter.
    ms = np.array([4, 6, 8, 11, 16])
    for sensor, data, key, unit in (
        ("gyro", run.dtheta_rad, "arw_dph", math.radians(1) / 60),
        ("accel", run.dv_mps, "vrw_ug", 9.80665e-6),
    ):
        for j in range(3):
            rate = data[:, j] / dt
            adev = np.array([independent_oadev(rate, m) for m in ms])
            # Over these two octaves the slope is -1/2 (point to point it wiggles on
            # the quantised gyro z).
            slope = math.log(adev[-1] / adev[0]) / math.log(ms[-1] / ms[0])
            assert abs(slope + 0.5) < 0.1, (sensor, j, slope)
            white = np.exp(np.mean(np.log(adev * np.sqrt(ms * dt)))) / unit
            assert fit[sensor][key][j] == pytest.approx(white, rel=0.15), (sensor, j)
    # The bias instability is the floor: B * 0.664 is the minimum of the independent
    # deviation over octaves from 1 s to a tenth of the log (the floor is broad, so
    # octave sampling misses it by a few %; 15 %).
    octaves = 2 ** np.arange(7, 17)
    for sensor, data, key, unit in (
        ("gyro", run.dtheta_rad, "bias_instability_dph", math.radians(1) / 3600),
        ("accel", run.dv_mps, "bias_instability_ug", 9.80665e-6),
    ):
        for j in range(3):
            floor = min(independent_oadev(data[:, j] / dt, int(m)) for m in octaves)
            assert fit[sensor][key][j] * 0.6643 == pytest.approx(floor / unit, rel=0.15)


def test_refusals_through_the_cli(tmp_path):
    log = tmp_path / "logger.csv"
    log.write_text(
        "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_g,accel_y_g,accel_z_g\n"
        + "".join(f"{i / 100},0,0,0,0,0,-1\n" for i in range(1, 50))
    )
    runner = CliRunner()
    out = tmp_path / "p.toml"
    result = runner.invoke(main, ["profile", "fit", str(log), "-o", str(out)])
    assert result.exit_code == 2
    assert "lacks 'latitude_deg'" in result.output and "--latitude" in result.output
    result = runner.invoke(main, ["profile", "fit", str(log), "--latitude", "51", "-o", str(out)])
    assert result.exit_code == 2 and "49 samples" in result.output
    bad = tmp_path / "bad.csv"
    bad.write_text(log.read_text().replace("accel_y_g", "accel_y_gee"))
    result = runner.invoke(main, ["profile", "fit", str(bad), "--latitude", "51", "-o", str(out)])
    assert result.exit_code == 2
    assert "column 'accel_y_gee' has unknown unit 'gee'" in result.output
    result = runner.invoke(main, ["profile", "fit", str(log), "--latitude", "51", "-o", "p.txt"])
    assert result.exit_code == 2 and ".toml" in result.output
    assert not out.exists()
    assert "Traceback" not in result.output
