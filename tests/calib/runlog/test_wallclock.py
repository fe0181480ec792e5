"""Time stamps written as wall-clock times (a PC tool's ``2023-1-1 12:00:01.250``): read as seconds."""

from __future__ import annotations

import numpy as np
import pytest

from calib.errors import CalibError
from calib.runlog import read_run
from calib.runlog.wallclock import clock_seconds

SITE = {"latitude_deg": 45.0, "height_m": 0.0}
MAP = (
    "t=time_s,ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps"
)


def _where(i: int) -> str:
    return f"row {i}"


def test_clock_times_are_seconds_from_the_first_stamps_midnight():
    said = clock_seconds(["12:00:00.000", "12:00:00.010", "12:01:02,5"], _where)
    assert said == [43200.0, 43200.01, 43262.5]  # h*3600 + m*60 + s; a decimal comma read as a point
    iso = clock_seconds(["2023-01-01T12:00:00.000Z", "2023-01-01T12:00:00.010Z"], _where)  # ISO 8601, UTC
    assert iso == [43200.0, 43200.01]
    with pytest.raises(CalibError, match="another time zone"):
        clock_seconds(["12:00:00+01:00", "12:00:01+02:00"], _where)


def test_midnight_is_crossed_by_the_date_or_by_a_stamp_12_hours_back():
    dated = clock_seconds(["2023-12-31 23:59:59.990", "2024-01-01 00:00:00.000"], _where)
    undated = clock_seconds(["23:59:59.990", "00:00:00.000"], _where)
    for said in (dated, undated):
        assert said[1] - said[0] == pytest.approx(0.01, abs=1e-9)


def test_matlab_s_day_month_name_year_stamps_are_the_same_clock_times():
    # MATLAB's datetime default (writetimetable): 14-Nov-2023 22:13:20.030. The same instants as
    # the ISO dates; over a month's end the day count carries on (30 Nov -> 1 Dec: one day).
    named = clock_seconds(["14-Nov-2023 22:13:20.030", "14-Nov-2023 22:13:20.040"], _where)
    iso = clock_seconds(["2023-11-14 22:13:20.030", "2023-11-14 22:13:20.040"], _where)
    assert named == iso == [22 * 3600 + 13 * 60 + 20.03, 22 * 3600 + 13 * 60 + 20.04]
    over = clock_seconds(["30-Nov-2023 23:59:59.990", "01-Dec-2023 00:00:00.000"], _where)
    assert over[1] - over[0] == pytest.approx(0.01, abs=1e-9)
    with pytest.raises(CalibError, match="no such date"):
        clock_seconds(["14-Nox-2023 22:13:20.030"], _where)


def test_a_stamp_written_otherwise_is_refused_naming_its_row():
    with pytest.raises(CalibError, match="no clock time") as err:
        clock_seconds(["12:00:00.000", "12.5"], _where)
    assert err.value.where == "row 1"
    with pytest.raises(CalibError, match="no such date"):
        clock_seconds(["2023-02-30 12:00:00"], _where)
    # A date on some rows only would count a midnight twice (by the date and by the stamp's fall).
    with pytest.raises(CalibError, match="without a date, the first rows with") as err:
        clock_seconds(["2023-01-01 23:59:59.99", "00:00:00.00"], _where)
    assert err.value.where == "row 1"


def test_a_log_stamped_by_the_clock_reads_as_the_same_log_stamped_in_seconds(tmp_path):
    rng = np.random.default_rng(1)
    n = 500
    seconds = 23 * 3600 + 59 * 60 + 58.0 + 0.01 * np.arange(n)  # crosses midnight at row 200
    values = rng.normal(size=(n, 6)) * [0.1, 0.1, 0.1, 0.01, 0.01, 0.01] + [0, 0, 9.8, 0, 0, 0]

    def clock(t: float) -> str:
        day, t = divmod(t, 86400.0)
        return f"2023-1-{1 + int(day)} {int(t // 3600):02d}:{int(t % 3600 // 60):02d}:{t % 60:06.3f}"

    rows = [",".join(f"{x:.6f}" for x in v) for v in values]
    wall = tmp_path / "wall.csv"
    wall.write_text(
        "t,ax,ay,az,gx,gy,gz\n" + "".join(f"{clock(t)},{r}\n" for t, r in zip(seconds, rows, strict=True))
    )
    plain = tmp_path / "plain.csv"
    plain.write_text(
        "t,ax,ay,az,gx,gy,gz\n" + "".join(f"{t:.3f},{r}\n" for t, r in zip(seconds, rows, strict=True))
    )
    a = read_run(wall, columns=MAP, **SITE)
    b = read_run(plain, columns=MAP, **SITE)
    np.testing.assert_array_equal(a.dv_mps, b.dv_mps)
    np.testing.assert_array_equal(a.dtheta_rad, b.dtheta_rad)
    np.testing.assert_allclose(a.time_s - a.time_s[0], b.time_s - b.time_s[0], atol=1e-9)
    assert a.n_samples == n and not a.clock.dropped  # midnight is no gap


def test_a_file_without_header_whose_time_is_a_date_and_a_clock_time_reads_by_position(tmp_path):
    # White space between the date and the time, and between the fields: one time field still.
    seconds = 12 * 3600.0 + 0.01 * np.arange(4)
    rows = [
        "0.1 -0.2 9.8 0.01 0.02 -0.03",
        "0.2 -0.1 9.7 0.02 0.01 -0.02",
        "0.0 0.3 9.9 -0.01 0.0 0.04",
        "-0.1 0.0 9.81 0.0 -0.02 0.01",
    ]
    path = tmp_path / "log.txt"
    path.write_text("".join(f"2023-1-1 12:00:00.0{k}0  {r}\n" for k, r in enumerate(rows)))
    by_position = (
        "1=time_s,2=accel_x_mps2,3=accel_y_mps2,4=accel_z_mps2,5=gyro_x_radps,6=gyro_y_radps,7=gyro_z_radps"
    )
    run = read_run(path, columns=by_position, sample_rate_hz=100.0, **SITE)
    np.testing.assert_allclose(run.time_s - run.time_s[0], seconds - seconds[0], atol=1e-9)
    np.testing.assert_allclose(run.dv_mps[:, 2] * 100.0, [9.8, 9.7, 9.9, 9.81], rtol=1e-12)


def test_a_tab_separated_file_with_decimal_commas_reads_them_as_points(tmp_path):
    path = tmp_path / "log.tsv"  # a spreadsheet's "tab-separated values"
    body = "".join(f"0,0{k}\t0,1\t-0,2\t9,8\t0,01\t0,02\t-0,03\n" for k in range(1, 5))
    path.write_text("t\tax\tay\taz\tgx\tgy\tgz\n" + body)
    with pytest.warns(UserWarning, match="tabs with decimal commas"):
        run = read_run(path, columns=MAP, **SITE)
    np.testing.assert_allclose(run.dv_mps[:, 2] / np.diff(run.time_s, prepend=0.0), 9.8, rtol=1e-9)


def test_a_stamp_in_two_columns_reads_as_one_and_either_half_alone_is_named(tmp_path):
    # ROS 2's `ros2 topic echo --csv` writes a header's stamp as sec,nanosec. Read as one stamp:
    # exact integers, ns; either half alone is named as such, not taken for a wrong rate or a
    # clock that goes back.
    ns = 1_700_000_000_153_296_000 + 9_999_000 * np.arange(400, dtype=np.int64)
    rows = [f"{t // 10**9},{t % 10**9},imu_link,0.01,-0.02,0.03,0.1,0.2,9.8" for t in ns]
    path = tmp_path / "ros2.csv"
    path.write_text("\n".join(rows) + "\n")
    sensors = "4=gyro_x_radps,5=gyro_y_radps,6=gyro_z_radps,7=accel_x_mps2,8=accel_y_mps2,9=accel_z_mps2"
    site = {"latitude_deg": 45.0, "height_m": 0.0}
    with pytest.warns(UserWarning, match=r"the time from two columns, '1' \(s\) and '2' \(ns\), read as one"):
        run = read_run(path, columns="1=time_s,2=time_ns," + sensors, **site)
    # To the stamps' own 1 ns (the run is put on its fitted clock, period to 1e-12).
    np.testing.assert_allclose(run.time_s - run.time_s[0], (ns - ns[0]) * 1e-9, rtol=0, atol=1e-9)
    # A float64 at 1.7e9 s resolves 2.4e-7 s: over these 4 s, the rate to 1e-7.
    assert run.sample_rate_hz == pytest.approx(1e9 / 9_999_000, rel=1e-7)
    for half, said in (("1=time_s", "holds whole seconds only"), ("2=time_ns", "restarts every second")):
        with pytest.raises(CalibError, match=said) as err:
            read_run(path, columns=f"{half}," + sensors, **site)
        assert "sec=time_s,nanosec=time_ns" in err.value.fix
    # A fraction of a second beyond one second is no such stamp: refused at its line.
    path.write_text(
        rows[0] + "\n" + rows[1].replace(",163295000,", ",1163295000,") + "\n" + "\n".join(rows[2:])
    )
    with pytest.raises(CalibError, match="needs whole numbers, the second below 1000000000") as err:
        read_run(path, columns="1=time_s,2=time_ns," + sensors, **site)
    assert err.value.where.endswith("line 2")


def test_milliseconds_after_a_third_colon_are_read_as_such():
    # Physics Toolbox writes 23:13:20:030; three digits after the colon are milliseconds.
    got = clock_seconds(["23:13:20:030", "23:13:20:040", "23:13:21:005"], str)
    np.testing.assert_allclose(got, [83600.03, 83600.04, 83601.005], rtol=0, atol=1e-9)


def test_a_clock_time_in_no_form_read_is_refused_naming_the_forms(tmp_path):
    # WitMotion's software writes "2023-11-4 8:5:9:30" (unpadded; are the 30 ms or 300 ms?): not
    # guessed, refused with the forms that are read.
    path = tmp_path / "wit.csv"
    rows = [f"2023-11-4 8:5:{s}:30,0.01,0.02,0.03,0.0,0.0,1.0" for s in range(1, 9)]
    path.write_text("time,gx,gy,gz,ax,ay,az\n" + "\n".join(rows) + "\n")
    columns = "time=time_s,gx=gyro_x_dps,gy=gyro_y_dps,gz=gyro_z_dps,ax=accel_x_g,ay=accel_y_g,az=accel_z_g"
    with pytest.raises(CalibError, match="nor a clock time this tool reads") as err:
        read_run(path, columns=columns, latitude_deg=45.0, height_m=0.0)
    assert "HH:MM:SS.fff or HH:MM:SS:fff" in err.value.fix
