"""Two CSV files, one per sensor (calib.runlog.csvpair), as a phone's or a driver's logger writes them.

The physics held: written at one rate with one set of stamps the pair reads back as the one-file
log of the same samples, exactly; at two rates, the gyro's samples are its own and a rest's mean
specific force is the accelerometer's; a logger's mistakes are refused naming the file and the fix.
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
EPOCH_NS = 1_700_000_000_000_000_000
G0 = 9.80665


def _samples(n: int = 3000, rate_hz: float = 100.0):
    """A unit at rest for 10 s, turning about a tilted axis for 10 s, at rest again: rates, forces."""
    rng = np.random.default_rng(11)
    t = np.arange(1, n + 1) / rate_hz
    w = np.zeros((n, 3))
    turning = (t > 10.0) & (t <= 20.0)
    w[turning] = np.radians([20.0, -10.0, 30.0]) * np.sin(np.pi * (t[turning] - 10.0) / 10.0)[:, None]
    w += rng.normal(scale=1e-3, size=(n, 3))
    f = np.array([0.3, -0.2, 9.79]) + rng.normal(scale=0.02, size=(n, 3))
    return t, w, f


def _write(path: Path, header: str, stamps_ns: np.ndarray, values: np.ndarray) -> None:
    body = np.char.mod("%.12g", values)
    rows = [",".join([str(s), *r]) for s, r in zip(stamps_ns, body, strict=True)]
    path.write_text(header + "\n" + "\n".join(rows) + "\n")


def _ns(t: np.ndarray) -> np.ndarray:
    return (np.rint(t * 1e9) + EPOCH_NS).astype(np.int64)


def test_one_rate_one_set_of_stamps_reads_as_the_one_file_log(tmp_path):
    # The pair and the one file hold the same samples on the same stamps: every gyro interval is an
    # accelerometer interval, so carrying the running sum onto it gives back each increment (to the
    # rounding of a running sum of 3000 increments of 0.1 m/s: 1e-13 m/s).
    t, w, f = _samples()
    _write(tmp_path / "gyro.csv", "t,gx,gy,gz", _ns(t), w)
    _write(tmp_path / "acc.csv", "t,ax,ay,az", _ns(t), f)
    one = tmp_path / "one.csv"
    _write(one, "time_ns,gyro_x_radps,gyro_y_radps,gyro_z_radps,accel_x_mps2,accel_y_mps2,accel_z_mps2",
           _ns(t), np.column_stack([w, f]))  # fmt: skip
    columns = "t=time_ns,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps,ax=accel_x_mps2,ay=accel_y_mps2"
    columns += ",az=accel_z_mps2"
    pair = read_run(tmp_path / "acc.csv", gyro_path=tmp_path / "gyro.csv", columns=columns, **SITE)
    same = read_run(one, **SITE)
    assert "two clocks" in pair.meta["streams"]
    assert pair.n_samples == same.n_samples
    np.testing.assert_allclose(pair.time_s, same.time_s, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(pair.dtheta_rad, same.dtheta_rad)
    np.testing.assert_allclose(pair.dv_mps, same.dv_mps, rtol=0, atol=1e-12)


def test_a_pair_stamped_with_clock_times_reads_as_the_pair_stamped_in_seconds(tmp_path):
    # MATLAB Mobile's sensors written with writetimetable: 'Timestamp' as 14-Nov-2023 22:13:20.030.
    # The same stamps in seconds from that midnight give the same samples.
    t, w, f = _samples()
    t0 = 22 * 3600 + 13 * 60 + 20.0
    clock = [
        f"14-Nov-2023 {int((t0 + x) // 3600):02d}:{int((t0 + x) % 3600 // 60):02d}:{(t0 + x) % 60:06.3f}"
        for x in t
    ]
    for name, values in (("gyro", w), ("acc", f)):
        body = np.char.mod("%.12g", values)
        (tmp_path / f"{name}_clock.csv").write_text(
            "Timestamp,X,Y,Z\n"
            + "\n".join(",".join([c, *r]) for c, r in zip(clock, body, strict=True))
            + "\n"
        )
        secs = np.char.mod("%.3f", t0 + t)
        (tmp_path / f"{name}_s.csv").write_text(
            "Timestamp,X,Y,Z\n" + "\n".join(",".join([c, *r]) for c, r in zip(secs, body, strict=True)) + "\n"
        )
    columns = "Timestamp=time_s,X=gyro_x_radps,Y=gyro_y_radps,Z=gyro_z_radps,X=accel_x_mps2,Y=accel_y_mps2"
    columns += ",Z=accel_z_mps2"
    by_clock = read_run(
        tmp_path / "acc_clock.csv", gyro_path=tmp_path / "gyro_clock.csv", columns=columns, **SITE
    )
    by_secs = read_run(tmp_path / "acc_s.csv", gyro_path=tmp_path / "gyro_s.csv", columns=columns, **SITE)
    np.testing.assert_allclose(by_clock.time_s, by_secs.time_s, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(by_clock.dtheta_rad, by_secs.dtheta_rad)
    np.testing.assert_allclose(by_clock.dv_mps, by_secs.dv_mps, rtol=0, atol=1e-12)


def test_a_phone_loggers_files_whose_axes_are_both_called_x_y_z(tmp_path):
    # A phone's sensor logger writes each sensor as time (epoch ns), seconds elapsed, then z, y, x:
    # one map names each file's x, y, z for its own sensor. The gyro read back is the gyro written,
    # axis for axis (z, y, x reordered), the accelerometer the accelerometer (one set of stamps:
    # exact to the running sum's rounding, 1e-13 m/s).
    t, w, f = _samples()
    for name, values in (("Gyroscope.csv", w), ("Accelerometer.csv", f)):
        table = np.column_stack([t - t[0], values[:, ::-1]])
        _write(tmp_path / name, "time,seconds_elapsed,z,y,x", _ns(t), table)
    columns = "time=time_ns,x=gyro_x_radps,y=gyro_y_radps,z=gyro_z_radps,"
    columns += "x=accel_x_mps2,y=accel_y_mps2,z=accel_z_mps2"
    run = read_run(
        tmp_path / "Accelerometer.csv", gyro_path=tmp_path / "Gyroscope.csv", columns=columns, **SITE
    )
    np.testing.assert_allclose(run.dtheta_rad, w / 100.0, rtol=1e-11)
    np.testing.assert_allclose(run.dv_mps, f / 100.0, rtol=0, atol=1e-12)


def test_a_pair_under_a_loggers_preamble_line_reads_as_without_it(tmp_path):
    # An Android logger's files (Navigation_HW's): a line naming the sensor above each header, and
    # the map naming each file's own columns. Found by those names, as the one-file reader does.
    t, w, f = _samples()
    _write(tmp_path / "g.csv", "timestamp,gx,gy,gz", _ns(t), w)
    _write(tmp_path / "a.csv", "timestamp,ax,ay,az", _ns(t), f)
    for name, sensor in (("g", "gyroscope-icm20690"), ("a", "accelerometer-icm20690")):
        text = (tmp_path / f"{name}.csv").read_text()
        (tmp_path / f"{name}_pre.csv").write_text(f"{sensor},invensense,2020-02-18_14-18-28.815\n" + text)
    columns = "timestamp=time_ns,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps,ax=accel_x_mps2"
    columns += ",ay=accel_y_mps2,az=accel_z_mps2"
    plain = read_run(tmp_path / "a.csv", gyro_path=tmp_path / "g.csv", columns=columns, **SITE)
    with pytest.warns(
        UserWarning, match="line 1 above the header row .line 2. read as the logger's preamble"
    ):
        pre = read_run(tmp_path / "a_pre.csv", gyro_path=tmp_path / "g_pre.csv", columns=columns, **SITE)
    np.testing.assert_array_equal(pre.time_s, plain.time_s)
    np.testing.assert_array_equal(pre.dtheta_rad, plain.dtheta_rad)
    np.testing.assert_array_equal(pre.dv_mps, plain.dv_mps)


def test_phyphox_files_with_quoted_names_and_their_units_in_them(tmp_path):
    # phyphox exports each sensor with its names in double quotes ("Time (s)"): a quoted name is
    # its content, so the map names it without quotes. Same samples, same stamps: read back exactly.
    t, w, f = _samples()
    files = {
        "Gyroscope.csv": ('"Time (s)","Gyroscope x (rad/s)","Gyroscope y (rad/s)","Gyroscope z (rad/s)"', w),
        "Accelerometer.csv": (
            '"Time (s)","Acceleration x (m/s^2)","Acceleration y (m/s^2)","Acceleration z (m/s^2)"',
            f,
        ),
    }
    for name, (header, values) in files.items():
        body = np.char.mod("%.12g", values)
        rows = [",".join([f"{s:.9f}", *r]) for s, r in zip(t - t[0] + 0.01, body, strict=True)]
        (tmp_path / name).write_text(header + "\n" + "\n".join(rows) + "\n")
    columns = "Time (s)=time_s," + ",".join(
        [f"Gyroscope {a} (rad/s)=gyro_{a}_radps" for a in "xyz"]
        + [f"Acceleration {a} (m/s^2)=accel_{a}_mps2" for a in "xyz"]
    )
    run = read_run(
        tmp_path / "Accelerometer.csv", gyro_path=tmp_path / "Gyroscope.csv", columns=columns, **SITE
    )
    np.testing.assert_allclose(run.dtheta_rad, w / 100.0, rtol=1e-11)
    np.testing.assert_allclose(run.dv_mps, f / 100.0, rtol=0, atol=1e-12)


def test_an_accelerometer_at_half_rate_in_g_keeps_each_rests_mean_force(tmp_path):
    # The accelerometer's pairs averaged (50 Hz) and written in g, stamped 4 ms late, the gyro in
    # deg/s: the gyro's increments are its own (to the 12 digits written), and over the first rest
    # (1-9 s) the mean specific force is the accelerometer's own mean there to 1e-4 m/s^2: the
    # running sum keeps every stretch's integral, only the stretch's ends move, by 4 ms (a
    # 0.02 m/s^2 sample noise over 8 s of 50 Hz averages to 3e-3; 4 ms of it at each end, 1e-5).
    t, w, f = _samples()
    _write(tmp_path / "gyro.csv", "time_ns,gyro_x_dps,gyro_y_dps,gyro_z_dps", _ns(t), np.degrees(w))
    slow = f.reshape(-1, 2, 3).mean(axis=1)
    _write(tmp_path / "acc.csv", "time_ns,accel_x_g,accel_y_g,accel_z_g", _ns(t[1::2] + 0.004), slow / G0)
    run = read_run(tmp_path / "acc.csv", gyro_path=tmp_path / "gyro.csv", **SITE)
    assert "50 Hz" in run.meta["streams"] and "100 Hz" in run.meta["streams"]
    # The gyro's first interval, (0, 10 ms], begins before the accelerometer's first, (4, 24 ms]:
    # left out, so the run starts at the gyro's second sample.
    first = 1
    np.testing.assert_allclose(run.dtheta_rad, w[first : first + run.n_samples] / 100.0, rtol=1e-10)
    t_run = run.time_s - run.time_s[0] + t[first]
    rest = (t_run > 1.0) & (t_run <= 9.0)
    mean = run.dv_mps[rest].sum(axis=0) / (rest.sum() * run.dt_nominal)
    own = slow[(t[1::2] + 0.004 > 1.0) & (t[1::2] + 0.004 <= 9.0)].mean(axis=0)
    np.testing.assert_allclose(mean, own, rtol=0, atol=1e-4)


@pytest.mark.parametrize(
    ("acc_header", "gyro_header", "columns", "parts"),
    [
        # the accelerometer's file holds the gyro too: a one-file log given as two
        ("time_s,accel_x_mps2,accel_y_mps2,accel_z_mps2,gyro_x_radps,gyro_y_radps,gyro_z_radps",
         "time_s,gyro_x_radps,gyro_y_radps,gyro_z_radps", None,
         ["acc.csv", "accelerometer file also holds the gyro", "give one file with both sensors"]),
        # a column map naming a column neither file has (a typo)
        ("t,ax,ay,az", "t,gx,gy,gz",
         "t=time_s,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps,ax=accel_x_mps2,ay=accel_y_mps2,"
         "az=accel_z_mps2,temp=counter",
         ["'temp'", "neither file's header has"]),
        # one file's x mapped twice (a typo for y)
        ("t,x,y,z", "t,x,y,z",
         "t=time_s,x=gyro_x_radps,x=gyro_y_radps,z=gyro_z_radps,x=accel_x_mps2,y=accel_y_mps2,"
         "z=accel_z_mps2",
         ["gyro file's column 'x' twice", "one gyro and one accelerometer column"]),
        # a sample counter and no time
        ("counter,accel_x_mps2,accel_y_mps2,accel_z_mps2", "counter,gyro_x_radps,gyro_y_radps,gyro_z_radps",
         None, ["sample counter gives no time", "give each file its time column"]),
        # the gyro's file lacks an axis
        ("time_s,accel_x_mps2,accel_y_mps2,accel_z_mps2", "time_s,gyro_x_radps,gyro_y_radps", None,
         ["gyro.csv", "gyro_z_radps"]),
    ],
)  # fmt: skip
def test_a_pair_a_logger_got_wrong_is_refused_naming_the_file_and_the_fix(
    tmp_path, acc_header, gyro_header, columns, parts
):
    n = 200
    t = np.arange(1, n + 1) / 100.0
    (tmp_path / "acc.csv").write_text(
        acc_header + "\n" + "\n".join(",".join([f"{s:.2f}"] + ["0.1"] * (acc_header.count(","))) for s in t)
    )
    (tmp_path / "gyro.csv").write_text(
        gyro_header + "\n" + "\n".join(",".join([f"{s:.2f}"] + ["0.0"] * (gyro_header.count(","))) for s in t)
    )
    args = ["calibrate", str(tmp_path / "acc.csv"), "--gyro-file", str(tmp_path / "gyro.csv")]
    args += ["--latitude", "45", "--height", "0", "-o", str(tmp_path / "out.toml")]
    if columns:
        args += ["--columns", columns]
    refused(CliRunner(), tmp_path, args, *parts)


def test_a_pair_without_headers_mapped_by_position_reads_as_with_them(tmp_path):
    # OpenCamera-Sensors writes each sensor's rows as x,y,z,timestamp_ns and no header: mapped by
    # position, the pair is the same samples as the same files with names.
    t, w, f = _samples()
    for name, values in (("gyro", w), ("acc", f)):
        body = np.char.mod("%.12g", values)
        rows = [",".join([*r, str(s)]) for s, r in zip(_ns(t), body, strict=True)]
        (tmp_path / f"{name}.csv").write_text("\n".join(rows) + "\n")
        (tmp_path / f"{name}_named.csv").write_text("x,y,z,t\n" + "\n".join(rows) + "\n")
    by_position = (
        "4=time_ns,1=gyro_x_radps,2=gyro_y_radps,3=gyro_z_radps,1=accel_x_mps2,2=accel_y_mps2,3=accel_z_mps2"
    )
    pair = read_run(tmp_path / "acc.csv", gyro_path=tmp_path / "gyro.csv", columns=by_position, **SITE)
    by_name = by_position.replace("4=", "t=").replace("1=", "x=").replace("2=", "y=").replace("3=", "z=")
    named = read_run(
        tmp_path / "acc_named.csv", gyro_path=tmp_path / "gyro_named.csv", columns=by_name, **SITE
    )
    np.testing.assert_array_equal(pair.dtheta_rad, named.dtheta_rad)
    np.testing.assert_array_equal(pair.dv_mps, named.dv_mps)


def test_a_span_covers_its_ends_to_a_thousandth_of_a_period():
    # phyphox's two files on one host clock, each put on its own fitted clock, came out 1.2e-8 of
    # a period apart (measured on imu_tk's Xsens recording written so): the first and the last
    # gyro samples were left out for it. Within a thousandth of a period they are covered; half
    # a period later (earlier), the first (last) gyro sample is not.
    from calib.runlog.streams import inside

    period = 1.0 / 100.0099963
    gyro = 0.0173 + period * np.arange(51_175)
    for apart, kept in ((1.2e-8, 51_175), (-1.2e-8, 51_175), (0.5, 51_174), (-0.5, 51_174)):
        assert inside(gyro + apart * period, period, gyro).sum() == kept


@pytest.mark.filterwarnings("ignore:.*fields separated by spaces")  # said on stderr, not the point here
def test_a_pair_without_headers_mapped_for_one_file_only_is_told_to_map_the_others_positions(tmp_path):
    # imu_tk-style text files in SI (t x y z each): a map naming positions 2-4 for the
    # accelerometer alone leaves the gyro's file with no column of its own; said so, with the fix.
    t, w, f = _samples()
    for name, values in (("acc.txt", f), ("gyro.txt", w)):
        body = np.char.mod("%.9g", np.column_stack([t, values]))
        (tmp_path / name).write_text("\n".join(" ".join(r) for r in body) + "\n")
    columns = "1=time_s,2=accel_x_mps2,3=accel_y_mps2,4=accel_z_mps2,5=gyro_x_radps"
    with pytest.raises(CalibError) as err:
        read_run(tmp_path / "acc.txt", gyro_path=tmp_path / "gyro.txt", columns=columns, **SITE)
    assert "gyro's file has no header row" in str(err.value)
    assert "2=gyro_x_radps,3=gyro_y_radps,4=gyro_z_radps" in str(err.value)
