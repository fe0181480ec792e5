"""Loggers whose IMU headers are known (calib.runlog.loggers.KNOWN_HEADERS): read without a map.

EuRoC's imu0.csv (its header in a comment), ROS's ``rostopic echo -p`` and a ROS or ROS 2 bag's
IMU topic exported to CSV name their columns by a convention with fixed units (rad/s, m/s^2,
ns): each reads as the file of the same samples under the grammar's names, exactly, and says
which convention it read; a map given is the user's, and wins.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from calib.runlog import read_run

SITE = {"latitude_deg": 45.0, "height_m": 0.0}
N = 1500
STAMP0_NS = 1_403_636_579_758_555_392


def _samples():
    rng = np.random.default_rng(3)
    t = STAMP0_NS + np.arange(N, dtype=np.int64) * 5_000_000
    w = rng.normal(0.0, 1e-3, (N, 3))
    w[500:900] += np.radians([30.0, -20.0, 10.0])  # a turn, so the file is more than a rest
    f = np.array([0.1, -0.2, 9.8]) + rng.normal(0.0, 0.02, (N, 3))
    return t, w, f


def _write(path, header: str, rows):
    path.write_text(header + "\n" + "\n".join(rows) + "\n")


def _fmt(values) -> list[str]:
    return [f"{v:.9g}" for v in values]


def _axes(prefix: str, suffix: str = "") -> str:
    return ",".join(f"{prefix}{a}{suffix}" for a in "xyz")


def _files(tmp_path):
    t, w, f = _samples()
    values = [[*_fmt(a), *_fmt(b)] for a, b in zip(w, f, strict=True)]
    ros = _axes("angular_velocity.") + "," + _axes("linear_acceleration.")
    headers = {
        "ours": "time_ns," + _axes("gyro_", "_radps") + "," + _axes("accel_", "_mps2"),
        "euroc": "#timestamp [ns]," + _axes("w_RS_S_", " [rad s^-1]") + "," + _axes("a_RS_S_", " [m s^-2]"),
        "rostopic": "%time,field.header.seq,field.header.stamp,field.header.frame_id,"
        + _axes("field.orientation.")
        + ",field.orientation.w,"
        + ",".join("field." + n for n in ros.split(",")),
        "bag": "Time,header.seq,header.stamp.secs,header.stamp.nsecs,header.frame_id," + ros,
        "bag2": "Time,header.seq,header.stamp.sec,header.stamp.nanosec,header.frame_id," + ros,
    }
    logged = t + 731_000  # when the message was logged: 731 us after the sensor's stamp
    rows = {
        "ours": [[str(s), *v] for s, v in zip(t, values, strict=True)],
        "euroc": [[str(s), *v] for s, v in zip(t, values, strict=True)],
        "rostopic": [
            [str(g), str(i), str(s), "imu_link", "0", "0", "0", "1", *v]
            for i, (g, s, v) in enumerate(zip(logged, t, values, strict=True))
        ],
    }
    for key in ("bag", "bag2"):
        rows[key] = [
            [f"{g / 1e9:.6f}", str(i), str(s // 10**9), str(s % 10**9), "imu", *v]
            for i, (g, s, v) in enumerate(zip(logged, t, values, strict=True))
        ]
    files = {key: tmp_path / f"{key}.csv" for key in headers}
    for key, path in files.items():
        _write(path, headers[key], [",".join(r) for r in rows[key]])
    return files.pop("ours"), files


@pytest.mark.parametrize("logger", ["euroc", "rostopic", "bag", "bag2"])
# The other notes on stderr (a commented header, a stamp of two columns) are not the point here.
@pytest.mark.filterwarnings("ignore:.*(named in this comment line|read as one stamp)")
def test_a_known_loggers_header_reads_as_the_same_samples_under_our_names(tmp_path, logger):
    ours, files = _files(tmp_path)
    same = read_run(ours, **SITE)
    with pytest.warns(UserWarning, match="read as its convention says"):
        run = read_run(files[logger], **SITE)
    # The sensor's stamp, not the time it was logged (731 us later in the ROS files).
    np.testing.assert_array_equal(run.time_s, same.time_s)
    np.testing.assert_array_equal(run.dtheta_rad, same.dtheta_rad)
    np.testing.assert_array_equal(run.dv_mps, same.dv_mps)


def test_a_map_given_for_a_known_header_is_the_users(tmp_path):
    # The user maps the logging time instead of the message's stamp: their map is read, unsaid.
    _, files = _files(tmp_path)
    columns = "%time=time_ns," + ",".join(
        [f"field.angular_velocity.{a}=gyro_{a}_radps" for a in "xyz"]
        + [f"field.linear_acceleration.{a}=accel_{a}_mps2" for a in "xyz"]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = read_run(files["rostopic"], columns=columns, **SITE)
    assert run.n_samples == N


def test_phyphoxs_two_files_read_as_the_same_samples_under_our_names(tmp_path):
    # phyphox exports each sensor to its own file, names in quotes, times in s, values in E notation.
    t, w, f = _samples()
    seconds = (t - STAMP0_NS) / 1e9 + 0.0031
    files = {}
    for sensor, head, values in (
        ("acc", '"Acceleration {} (m/s^2)"', f),
        ("gyro", '"Gyroscope {} (rad/s)"', w),
    ):
        header = '"Time (s)",' + ",".join(head.format(a) for a in "xyz")
        rows = [",".join(f"{v:.9E}" for v in (s, *r)) for s, r in zip(seconds, values, strict=True)]
        files[sensor] = tmp_path / f"{sensor}.csv"
        _write(files[sensor], header, rows)
        ours = "t," + ",".join(f"{sensor}_{a}" for a in "xyz")
        _write(tmp_path / f"{sensor}_ours.csv", ours, rows)
    columns = "t=time_s," + ",".join(
        [f"gyro_{a}=gyro_{a}_radps" for a in "xyz"] + [f"acc_{a}=accel_{a}_mps2" for a in "xyz"]
    )
    same = read_run(tmp_path / "acc_ours.csv", gyro_path=tmp_path / "gyro_ours.csv", columns=columns, **SITE)
    with pytest.warns(UserWarning, match="phyphox's export"):
        run = read_run(files["acc"], gyro_path=files["gyro"], **SITE)
    np.testing.assert_array_equal(run.time_s, same.time_s)
    np.testing.assert_array_equal(run.dtheta_rad, same.dtheta_rad)
    np.testing.assert_array_equal(run.dv_mps, same.dv_mps)
