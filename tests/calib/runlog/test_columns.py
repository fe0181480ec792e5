"""Run-log columns as loggers name them: quantity_axis_unit, free order, gzip, options."""

from __future__ import annotations

import gzip

import numpy as np
import pytest

from calib.errors import CalibError
from calib.model.params import STANDARD_GRAVITY
from calib.runlog import read_run

RATE = np.array([[0.5, -0.25, 2.0], [1.0, 0.0, -3.0], [0.0, 0.75, 0.25], [0.1, 0.2, 0.3]])  # deg/s
FORCE = np.array([[0.01, 0.0, -1.0], [0.0, -0.02, -1.01], [0.005, 0.0, -0.99], [0.0, 0.0, -1.0]])  # g
TIMES = np.array([0.01, 0.02, 0.03, 0.04])  # uniform: a two-period step is a dropped sample


def logger_text(
    header=(
        "time_s",
        "accel_z_g",
        "gyro_x_dps",
        "gyro_y_dps",
        "gyro_z_dps",
        "accel_x_g",
        "accel_y_g",
        "temp_c",
    ),
    preamble="",
) -> str:
    values = {"time_s": TIMES, "temp_c": np.full(4, 25.0)}
    for j, axis in enumerate("xyz"):
        values[f"gyro_{axis}_dps"] = RATE[:, j]
        values[f"gyro_{axis}_radps"] = np.radians(RATE[:, j])
        values[f"accel_{axis}_g"] = FORCE[:, j]
        values[f"accel_{axis}_mps2"] = FORCE[:, j] * STANDARD_GRAVITY
    rows = [",".join(repr(float(values[h][i])) for h in header) for i in range(4)]
    return preamble + ",".join(header) + "\n" + "\n".join(rows) + "\n"


def expected_increments():
    # Rectangular rule: rate of the sample times (t_k - t_{k-1}); the first sample
    # lasts the nominal period 1 / (median step) = 0.01 s.
    dt = np.array([0.01, 0.01, 0.01, 0.01])[:, None]
    return np.radians(RATE) * dt, FORCE * STANDARD_GRAVITY * dt


def test_logger_csv_in_degrees_and_g_any_order(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text(logger_text())
    run = read_run(path, latitude_deg=51.08, height_m=1100.0, allow_gaps=True)
    dtheta, dv = expected_increments()
    np.testing.assert_allclose(run.dtheta_rad, dtheta, rtol=1e-15, atol=0)
    np.testing.assert_allclose(run.dv_mps, dv, rtol=1e-15, atol=0)
    assert run.sample_rate_hz == 100.0 and run.latitude_deg == 51.08
    assert run.meta["format"] == "imu-run/1"


def test_si_rates_and_gzip_read_the_same(tmp_path):
    header = ("time_s", *(f"gyro_{a}_radps" for a in "xyz"), *(f"accel_{a}_mps2" for a in "xyz"))
    path = tmp_path / "log.csv.gz"
    path.write_bytes(gzip.compress(logger_text(header).encode()))
    run = read_run(path, latitude_deg=51.08, height_m=0.0, allow_gaps=True)
    dtheta, dv = expected_increments()
    np.testing.assert_allclose(run.dtheta_rad, dtheta, rtol=1e-14)
    np.testing.assert_allclose(run.dv_mps, dv, rtol=1e-14)


def test_increments_in_degrees(tmp_path):
    header = "time_s,dtheta_x_deg,dtheta_y_deg,dtheta_z_deg,dv_x_mps,dv_y_mps,dv_z_mps"
    path = tmp_path / "log.csv"
    path.write_text(
        "# latitude_deg: 10\n# height_m: 0\n" + header + "\n0.01,1,2,3,0,0,-0.098\n0.02,1,2,3,0,0,-0.098\n"
    )
    run = read_run(path)
    np.testing.assert_allclose(run.dtheta_rad[0], np.radians([1, 2, 3]), rtol=1e-15)


@pytest.mark.parametrize(
    "change, parts",
    [
        (("gyro_y_dps", "gyro_y"), ["column 'gyro_y' has no unit", "radps, dps"]),
        (("accel_x_g", "accel_x_ms2"), ["column 'accel_x_ms2' has unknown unit 'ms2'", "mps2, g"]),
        (("gyro_z_dps", "speed"), ["lacks column 'gyro_z_dps'"]),
        (("temp_c", "dtheta_x_rad"), ["gyro is given twice", "dtheta_x_rad", "gyro_x_dps"]),
        (("time_s", "time_min"), ["'time_min'", "unknown time unit 'min'", "time_ms"]),
        (("temp_c", "time_ms"), ["the time is given twice", "'time_s'", "'time_ms'"]),
    ],
)
def test_bad_columns_are_named(tmp_path, change, parts):
    path = tmp_path / "log.csv"
    text = logger_text().replace(change[0], change[1], 1)
    path.write_text(text)
    with pytest.raises(CalibError) as info:
        read_run(path, latitude_deg=51.0, height_m=0.0, allow_gaps=True)
    for part in parts:
        assert part in info.value.message
    assert "line 1" in info.value.message


def test_missing_site_lists_every_key(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text(logger_text())
    with pytest.raises(CalibError) as info:
        read_run(path, allow_gaps=True)
    message = info.value.message
    assert "lacks 'latitude_deg', 'height_m'" in message
    assert "latitude_deg (the CLI's --latitude DEG)" in message and "# latitude_deg: 51.08" in message


def test_option_that_contradicts_the_file_is_refused(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text(logger_text(preamble="# latitude_deg: 40\n# height_m: 0\n"))
    assert read_run(path, latitude_deg=40.0, allow_gaps=True).latitude_deg == 40.0
    with pytest.raises(CalibError, match="says latitude_deg = 40 but the option gives 51"):
        read_run(path, latitude_deg=51.0, allow_gaps=True)


def test_declared_run_logs_keep_their_contract(tmp_path):
    # A file that declares imu-run/1 must still state its rate (files.md).
    path = tmp_path / "log.csv"
    path.write_text(logger_text(preamble="# format: imu-run/1\n# latitude_deg: 40\n# height_m: 0\n"))
    with pytest.raises(CalibError, match="'sample_rate_hz' is missing"):
        read_run(path, allow_gaps=True)


# The notice is asserted where it is the point (or is not its point), and kept out of the summary.
@pytest.mark.filterwarnings("ignore:.*iOS logger's acceleration:UserWarning")
def test_a_negated_name_reverses_the_axis_and_an_ios_logger_s_acceleration_is_warned_of(tmp_path):
    # iOS gives the acceleration as -1 g on z lying face up (Apple's sign); mapped negated it is
    # the specific force, +1 g up. Rates in counts and in units negate alike.
    names = ["t", "accelerometerAccelerationX(G)", "accelerometerAccelerationY(G)"]
    names += ["accelerometerAccelerationZ(G)", "gx", "gy", "gz"]
    rows = [
        f"{t},{-f[0]},{-f[1]},{-f[2]},{w[0]},{w[1]},{w[2]}"
        for t, f, w in zip(TIMES, FORCE, RATE, strict=True)
    ]
    (tmp_path / "ios.csv").write_text(",".join(names) + "\n" + "\n".join(rows) + "\n")
    gyro = "gx=gyro_x_dps,gy=gyro_y_dps,gz=-gyro_z_dps"
    negated = "t=time_s," + ",".join(f"{n}=-accel_{a}_g" for n, a in zip(names[1:4], "xyz", strict=True))
    run = read_run(tmp_path / "ios.csv", columns=negated + "," + gyro, latitude_deg=45.0, height_m=0.0)
    assert np.allclose(run.dv_mps / 0.01, FORCE * STANDARD_GRAVITY, rtol=1e-12, atol=0)
    assert np.allclose(run.dtheta_rad / 0.01, np.radians(RATE) * [1, 1, -1], rtol=1e-12, atol=0)
    plain = negated.replace("=-accel", "=accel")
    with pytest.warns(UserWarning, match=r"iOS logger's acceleration.*=-accel_x_g"):
        read_run(tmp_path / "ios.csv", columns=plain + "," + gyro, latitude_deg=45.0, height_m=0.0)
    # One axis given twice, once negated, is refused by column.
    twice = negated.replace("=-accel_y_g", "=accel_x_g")
    with pytest.raises(CalibError, match="accel_x is given twice: columns 2 and 3"):
        read_run(tmp_path / "ios.csv", columns=twice + "," + gyro, latitude_deg=45.0, height_m=0.0)
