"""Intel RealSense motion logs (calib.runlog.realsense): a block per motion stream in one file.

The physics held: the blocks of rs-data-collect and rs-convert read back as the two files of the
same samples on the same stamps (the one reading of two streams); a file without one of the motion
streams, or given a column map, is refused saying what to do. The layouts are librealsense's
(tools/data-collect/rs-data-collect.h, tools/convert/converters/converter-csv.cpp).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from refusals import refused

from calib.errors import CalibError
from calib.runlog import read_run

SITE = {"latitude_deg": 45.4, "height_m": 0.0}
EPOCH_MS = 1_629_056_886_217.829


def _streams():
    """A camera at rest for 4 s, turning 3 s about a tilted axis, at rest 4 s: the gyro at 400 Hz,
    the accelerometer at 250 Hz, each on its own stamps (ms), values rounded as the tools write them."""
    rng = np.random.default_rng(5)
    out = {}
    for key, rate in (("Gyro", 400.0), ("Accel", 250.0)):
        t = np.arange(1, int(11.0 * rate) + 1) / rate + (0.0 if key == "Gyro" else 0.0013)
        if key == "Gyro":
            v = np.zeros((t.size, 3))
            turning = (t > 4.0) & (t <= 7.0)
            v[turning] = np.radians([40.0, -20.0, 60.0]) * np.sin(np.pi * (t[turning] - 4.0) / 3.0)[:, None]
            v += rng.normal(scale=2e-3, size=v.shape)
        else:
            v = np.array([-0.09, 0.17, 9.83]) + rng.normal(scale=0.02, size=(t.size, 3))
        out[key] = (np.round(t * 1e3, 3), np.round(v, 3))
    return out


def _collect_file(path: Path, streams: dict) -> None:
    """As rs-data-collect writes it: the configuration, a camera's block, then Gyro before Accel."""
    lines = ["Configuration:", "Stream Type,Stream Name,Format,FPS,Width,Height",
             "Accel,Accel,MOTION_XYZ32F,250", "Gyro,Gyro,MOTION_XYZ32F,400", "Depth,Depth,Z16,30,640,480",
             "", "", "Stream Type,Index,F#,HW Timestamp (ms),Host Timestamp(ms)", "",
             f"Depth,0,6,{EPOCH_MS + 37.5:.3f},30.014"]  # fmt: skip
    for key in ("Gyro", "Accel"):
        t, v = streams[key]
        lines += ["", "Stream Type,Index,F#,HW Timestamp (ms),Host Timestamp(ms),3DOF_x,3DOF_y,3DOF_z", ""]
        lines += [
            f"{key},0,{i + 1},{EPOCH_MS + s:.3f},{s + 2.5:.3f},{x:.3f},{y:.3f},{z:.3f}"
            for i, (s, (x, y, z)) in enumerate(zip(t, v, strict=True))
        ]
    path.write_text("\n".join(lines))  # no line end after the last row, as the tool writes it


def _pair(tmp_path: Path, streams: dict, stamp=lambda ms: f"{EPOCH_MS + ms:.3f}") -> tuple[Path, Path, str]:
    paths = {}
    for key, name in (("Gyro", "gyro"), ("Accel", "acc")):
        t, v = streams[key]
        rows = [f"{stamp(s)},{x:.3f},{y:.3f},{z:.3f}" for s, (x, y, z) in zip(t, v, strict=True)]
        paths[key] = tmp_path / f"{name}.csv"
        paths[key].write_text(f"t,{name}x,{name}y,{name}z\n" + "\n".join(rows) + "\n")
    cols = "t=time_ms,gyrox=gyro_x_radps,gyroy=gyro_y_radps,gyroz=gyro_z_radps"
    cols += ",accx=accel_x_mps2,accy=accel_y_mps2,accz=accel_z_mps2"
    return paths["Accel"], paths["Gyro"], cols


def test_an_rs_data_collect_file_reads_as_the_two_files_of_its_samples(tmp_path):
    # The same samples on the same stamps: the block file and the pair are one reading (exact).
    streams = _streams()
    _collect_file(tmp_path / "rs.csv", streams)
    acc, gyro, cols = _pair(tmp_path, streams)
    rs = read_run(tmp_path / "rs.csv", **SITE)
    pair = read_run(acc, gyro_path=gyro, columns=cols, **SITE)
    assert "two clocks" in rs.meta["streams"]
    assert rs.n_samples == pair.n_samples
    np.testing.assert_array_equal(rs.time_s, pair.time_s)
    np.testing.assert_array_equal(rs.dtheta_rad, pair.dtheta_rad)
    np.testing.assert_array_equal(rs.dv_mps, pair.dv_mps)
    # At rest the mean specific force is the accelerometer's own (the camera's 9.83 m/s^2 on z);
    # 1000 samples of 0.02 m/s^2 noise: 3 sigma of the mean is 2e-3 m/s^2, and rounding to 1e-3 adds little.
    rate = float(rs.meta["sample_rate_hz"])
    assert abs(rs.dv_mps[: int(3.5 * rate), 2].mean() * rate - 9.83) < 3e-3
    # The note gives the gyro's mean rate, 400 Hz (to the 1 us rounding of the stamps over 11 s).
    assert "gyro's at 400 Hz" in rs.meta["streams"]


def test_an_rs_convert_file_is_read_with_its_stamps_in_microseconds(tmp_path):
    # rs-convert writes the frames' metadata stamps, microseconds under a header that says ms,
    # with a backend stamp and no Index column: read as the pair stamped in microseconds.
    streams = _streams()
    lines = []
    for key in ("Gyro", "Accel"):
        t, v = streams[key]
        lines += ["", "", "Stream Type,F#,HW Timestamp (ms),Backend Timestamp(ms),Host Timestamp(ms),"
                  "3DOF_x,3DOF_y,3DOF_z"]  # fmt: skip
        lines += [
            f"{key},{i + 1},{round((EPOCH_MS + s) * 1e3)},{round(s * 1e3)},{round(EPOCH_MS + s)},"
            f"{x:.3f},{y:.3f},{z:.3f}"
            for i, (s, (x, y, z)) in enumerate(zip(t, v, strict=True))
        ]
    (tmp_path / "rs_imu_pose.csv").write_text("\n".join(lines) + "\n")
    acc, gyro, cols = _pair(tmp_path, streams, lambda ms: round((EPOCH_MS + ms) * 1e3))
    rs = read_run(tmp_path / "rs_imu_pose.csv", **SITE)
    pair = read_run(acc, gyro_path=gyro, columns=cols.replace("time_ms", "time_us"), **SITE)
    assert abs(float(rs.meta["sample_rate_hz"]) - 400.0) < 0.01
    np.testing.assert_array_equal(rs.time_s, pair.time_s)
    np.testing.assert_array_equal(rs.dtheta_rad, pair.dtheta_rad)
    np.testing.assert_array_equal(rs.dv_mps, pair.dv_mps)


def test_a_realsense_file_without_its_accelerometer_is_refused_saying_what_to_record(tmp_path):
    streams = _streams()
    _collect_file(tmp_path / "rs.csv", streams)
    text = (tmp_path / "rs.csv").read_text().replace("\nAccel,0,", "\nColor,0,")
    (tmp_path / "gyro_only.csv").write_text(text)
    with pytest.raises(CalibError) as err:
        read_run(tmp_path / "gyro_only.csv", **SITE)
    assert "without the Accel stream's rows" in str(err.value)
    assert "the gyro and the accelerometer both" in str(err.value)


def test_a_column_map_for_a_realsense_file_is_refused_by_the_cli(tmp_path):
    _collect_file(tmp_path / "rs.csv", _streams())
    args = ["calibrate", str(tmp_path / "rs.csv"), "--by-hand", "--profile", "mems", "--latitude", "45",
            "--height", "0", "--columns", "3DOF_x=gyro_x_radps", "-o", "out.toml"]  # fmt: skip
    refused(CliRunner(), tmp_path, args, "names its columns itself", "the CLI's --columns")


def test_a_conversion_for_a_realsense_file_is_refused(tmp_path):
    # Its values are the SDK's, in SI: a conversion of counts given with it is a mistake, not ignored.
    _collect_file(tmp_path / "rs.csv", _streams())
    args = ["calibrate", str(tmp_path / "rs.csv"), "--by-hand", "--profile", "mems", "--latitude", "45",
            "--height", "0", "--conversion", "si", "-o", "out.toml"]  # fmt: skip
    refused(CliRunner(), tmp_path, args, "in SI already", "leave out the conversion")
