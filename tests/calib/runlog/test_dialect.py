"""Rows as loggers write them: tags, names in a comment, spaces, quotes, a header written again."""

from __future__ import annotations

import numpy as np
import pytest

from calib.errors import CalibError
from calib.runlog import read_run

SITE = {"latitude_deg": 55.0, "height_m": 100.0}
NAMES = ("ax", "ay", "az", "gx", "gy", "gz")
BY_NAME = "ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps"
BY_POSITION = "1=accel_x_mps2,2=accel_y_mps2,3=accel_z_mps2,4=gyro_x_radps,5=gyro_y_radps,6=gyro_z_radps"
BY_POSITION_AFTER_TIME = (
    "2=accel_x_mps2,3=accel_y_mps2,4=accel_z_mps2,5=gyro_x_radps,6=gyro_y_radps,7=gyro_z_radps"
)
# Four samples: specific force (m/s^2) then rates (rad/s).
TABLE = np.array(
    [
        [0.1, -0.2, 9.8, 0.01, 0.02, -0.03],
        [0.2, -0.1, 9.7, 0.02, 0.01, -0.02],
        [0.0, 0.3, 9.9, -0.01, 0.00, 0.04],
        [-0.1, 0.0, 9.81, 0.00, -0.02, 0.01],
    ]
)
TIME = (np.arange(4) + 1) * 0.02  # 50 Hz, each stamp the end of its sample's interval


def _rows(sep: str, prefix: str = "", timed: bool = False) -> list[str]:
    return [
        prefix + sep.join(repr(float(x)) for x in ([t] if timed else []) + list(row)) + "\n"
        for t, row in zip(TIME, TABLE, strict=True)
    ]


def _assert_the_table(run) -> None:
    # Each row is the mean over its 20 ms interval: its increment is the row times the period.
    np.testing.assert_allclose(run.time_s, TIME, rtol=1e-12)
    np.testing.assert_allclose(run.dv_mps, TABLE[:, :3] * 0.02, rtol=1e-12)
    np.testing.assert_allclose(run.dtheta_rad, TABLE[:, 3:] * 0.02, rtol=1e-12)


def test_a_tag_before_every_row_is_no_header(tmp_path):
    # An Arduino sketch's Serial.print("a/g:\t") before each row's numbers: the same text on
    # every row is a tag, so the file has no header and its columns go by position.
    path = tmp_path / "serial.txt"
    path.write_text("".join(_rows("\t", prefix="a/g:\t")))
    by_position = ",".join(f"{i + 2}={v.split('=')[1]}" for i, v in enumerate(BY_NAME.split(",")))
    _assert_the_table(read_run(path, columns=by_position, sample_rate_hz=50.0, **SITE))


@pytest.mark.parametrize("mark", ["# ", "% ", "#"])
def test_names_in_a_comment_line_above_headerless_rows_are_mapped_by_position(tmp_path, mark):
    # numpy's savetxt writes "# t ax ...", MATLAB "% t ax ...": the names a user maps.
    path = tmp_path / "saved.txt"
    path.write_text(mark + " ".join(("t",) + NAMES) + "\n" + "".join(_rows(" ", timed=True)))
    with pytest.warns(UserWarning, match="named in this comment line"):
        run = read_run(path, columns="t=time_s," + BY_NAME, **SITE)
    _assert_the_table(run)


def test_a_header_of_names_between_spaces_reads_with_its_rows(tmp_path):
    path = tmp_path / "spaced.dat"
    path.write_text("t   " + "  ".join(NAMES) + "\n" + "".join(_rows("   ", timed=True)))
    with pytest.warns(UserWarning, match="separated by spaces"):
        run = read_run(path, columns="t=time_s," + BY_NAME, **SITE)
    _assert_the_table(run)


def test_quoted_fields_lose_their_quotes_and_a_quoted_decimal_comma_is_a_point(tmp_path):
    path = tmp_path / "export.csv"
    header = ",".join(f'"{n}"' for n in ("t",) + NAMES) + "\n"
    rows = [
        ",".join(f'"{x!r}"'.replace(".", ",") for x in [float(t), *row]) + "\n"
        for t, row in zip(TIME, TABLE.tolist(), strict=True)
    ]
    path.write_text(header + "".join(rows))
    with pytest.warns(UserWarning, match="double quotes"):
        run = read_run(path, columns="t=time_s," + BY_NAME, **SITE)
    _assert_the_table(run)


def test_a_header_written_again_among_the_rows_is_left_out_naming_its_line(tmp_path):
    path = tmp_path / "appended.csv"
    header = ",".join(("t",) + NAMES) + "\n"
    rows = _rows(",", timed=True)
    path.write_text(header + "".join(rows[:2]) + header + "".join(rows[2:]))
    with pytest.warns(UserWarning, match=r"line\(s\) 4 repeat the header"):
        run = read_run(path, columns="t=time_s," + BY_NAME, **SITE)
    _assert_the_table(run)
    # A logger that started again with its clock from zero: two sessions, refused by the clock.
    again = tmp_path / "restarted.csv"
    again.write_text(header + "".join(rows[:2]) + header + "".join(rows[:2]))
    with pytest.warns(UserWarning, match="repeat the header"), pytest.raises(CalibError):
        read_run(again, columns="t=time_s," + BY_NAME, **SITE)


def test_a_ros_header_starting_with_a_percent_sign_is_a_header(tmp_path):
    # rostopic echo -p writes "%time,field...": no space after the '%', so no comment.
    path = tmp_path / "ros.csv"
    path.write_text("%time," + ",".join(NAMES) + "\n" + "".join(_rows(",", timed=True)))
    _assert_the_table(read_run(path, columns="%time=time_s," + BY_NAME, **SITE))


def test_a_sep_line_a_device_preamble_and_a_units_row_are_read_as_such(tmp_path):
    # Shimmer's Consensys export: Excel's "sep=\t" first, the names, then a row of units. Movella
    # DOT's: "sep=," and "Key:,value" lines, a blank line, then the names (and a trailing comma).
    shimmer = tmp_path / "shimmer.csv"
    header = "\t".join(("t", *NAMES))
    units = "\t".join(("s", "m/(s^2)", "m/(s^2)", "m/(s^2)", "rad/s", "rad/s", "rad/s"))
    shimmer.write_text(f'"sep=\\t"\n{header}\n{units}\n' + "".join(_rows("\t", timed=True)))
    with pytest.warns(UserWarning) as said:
        run = read_run(shimmer, columns="t=time_s," + BY_NAME, **SITE)
    said = [str(w.message) for w in said]
    assert any("line 1 above the header row (line 2) read as the logger's preamble" in m for m in said)
    assert any("line 3: a row of no numbers under the header (s, m/(s^2)" in m for m in said)
    _assert_the_table(run)
    dot = tmp_path / "dot.csv"
    preamble = "sep=,\nDeviceTag:,Xsens DOT,,,,,,\nStartTime:,2023-11-14 23:13:20.030 +0100,,,,,,\n\n"
    dot.write_text(
        preamble
        + ",".join(("t", *NAMES))
        + ",\n"
        + "".join(r.rstrip("\n") + ",\n" for r in _rows(",", timed=True))
    )
    with pytest.warns(UserWarning, match=r"lines 1-4 above the header row \(line 5\)"):
        _assert_the_table(read_run(dot, columns="t=time_s," + BY_NAME, **SITE))


def test_a_name_in_a_comment_line_may_be_mapped_with_its_mark(tmp_path):
    # EuRoC's "#timestamp [ns],w_RS_S_x [rad s^-1],...": its first name carries the comment's '#'.
    path = tmp_path / "data.csv"
    path.write_text("#t [s]," + ",".join(NAMES) + "\n" + "".join(_rows(",", timed=True)))
    for first in ("#t [s]", "t [s]"):
        with pytest.warns(UserWarning, match="named in this comment line"):
            _assert_the_table(read_run(path, columns=f"{first}=time_s," + BY_NAME, **SITE))


def _plotter_rows() -> list[str]:
    """The table as an Arduino's Serial Plotter prints it: t:20000,ax:0.1,... (time in us)."""
    labels = ("t", *NAMES)
    return [
        ",".join(f"{k}:{v!r}" for k, v in zip(labels, (round(t * 1e6), *map(float, row)), strict=True))
        for t, row in zip(TIME, TABLE, strict=True)
    ]


# The notice is asserted where it is the point (or is not its point), and kept out of the summary.
@pytest.mark.filterwarnings("ignore:.*rows of label.value pairs:UserWarning")
def test_rows_of_label_value_pairs_read_with_their_labels_as_the_header(tmp_path):
    # An Arduino's Serial Plotter lines: "t:20000,ax:0.1,...". A row that breaks the pattern is
    # refused at the file's own line.
    path = tmp_path / "plotter.txt"
    rows = _plotter_rows()
    path.write_text("\n".join(rows) + "\n")
    columns = "t=time_us," + BY_NAME
    with pytest.warns(UserWarning, match=r"rows of label:value pairs \(t, ax, ay, \.\.\.\)"):
        _assert_the_table(read_run(path, columns=columns, **SITE))
    # A capture that begins mid-row: its cut first line is left out, said; the rest read.
    path.write_text("gx:0.5,gy:0.1,gz:0.2\n" + "\n".join(rows) + "\n")
    with pytest.warns(UserWarning, match=r"line 1: the first row holds the last 3 of the 7 labels"):
        _assert_the_table(read_run(path, columns=columns, **SITE))
    path.write_text("\n".join(rows[:2] + [rows[2].replace("ay:", "ay=")] + rows[3:]) + "\n")
    with pytest.raises(CalibError) as err:
        read_run(path, columns=columns, **SITE)
    assert "line 3" in err.value.where


def test_rows_of_numbers_among_the_same_text_read_by_position(tmp_path):
    # A sketch's serial prints: "Scaled. Acc (mg) [ -00003.69,  00013.09, ... ], Gyr (DPS) [ ...",
    # numbers padded to a sign, a status line above; an Arduino IDE's clock before each row.
    def printed(row):
        a, w = ", ".join(f"{x:+010.2f}" for x in row[:3]), ", ".join(f"{x:+010.4f}" for x in row[3:])
        return f"Scaled. Acc (mps2) [ {a} ], Gyr (rad/s) [ {w} ], Tmp (C) [ 00027.31 ]"

    path = tmp_path / "capture.txt"
    path.write_text(
        "Initialization of the sensor returned: All is well.\n" + "\n".join(map(printed, TABLE)) + "\n"
    )
    with pytest.warns(UserWarning, match=r"read as 7 columns by position; line 1 above them left out"):
        run = read_run(path, columns=BY_POSITION, sample_rate_hz=50.0, **SITE)
    _assert_the_table(run)
    clocks = [f"00:00:{t:06.3f} -> {printed(row)}" for t, row in zip(TIME, TABLE, strict=True)]
    # A status line of as many words as the rows have fields is no header of them.
    path.write_text("00:00:00.000 -> Sensor found: All is well.\n" + "\n".join(clocks) + "\n")
    with pytest.warns(UserWarning, match="read as 8 columns by position"):
        _assert_the_table(read_run(path, columns="1=time_s," + BY_POSITION_AFTER_TIME, **SITE))
    # A table with a text column (ROS 2's frame_id) is no such print: read as its fields.
    table = tmp_path / "ros.csv"
    table.write_text(
        "".join(
            f"{float(t)!r},imu_link," + ",".join(repr(float(x)) for x in row) + "\n"
            for t, row in zip(TIME, TABLE, strict=True)
        )
    )
    columns = (
        "1=time_s,3=accel_x_mps2,4=accel_y_mps2,5=accel_z_mps2,6=gyro_x_radps,7=gyro_y_radps,8=gyro_z_radps"
    )
    _assert_the_table(read_run(table, columns=columns, **SITE))


def test_clock_times_with_their_dates_are_no_text_around_numbers(tmp_path):
    # MATLAB's "14-Nov-2023 23:13:20.040" (a month's name among digits) before numbers: a table's
    # time column, not a sketch's print; read as it was before the prints were.
    path = tmp_path / "matlab.csv"
    rows = [
        f"14-Nov-2023 00:00:{t:06.3f}," + ",".join(repr(float(x)) for x in row)
        for t, row in zip(TIME, TABLE, strict=True)
    ]
    path.write_text("\n".join(rows) + "\n")
    _assert_the_table(read_run(path, columns="1=time_s," + BY_POSITION_AFTER_TIME, **SITE))


# The notice is asserted where it is the point (or is not its point), and kept out of the summary.
@pytest.mark.filterwarnings("ignore:.*rows of label.value pairs:UserWarning")
def test_a_serial_capture_cut_mid_value_keeps_its_labels(tmp_path):
    # A capture that begins inside a value ("6409,gx:0.5,...": the rest of some "t:..." field).
    path = tmp_path / "plotter.txt"
    rows = _plotter_rows()
    path.write_text("6409,gx:0.5,gy:0.1,gz:0.2\n" + "\n".join(rows) + "\n")
    with pytest.warns(UserWarning, match=r"line 1: the first row holds the last 3 of the 7 labels"):
        _assert_the_table(read_run(path, columns="t=time_us," + BY_NAME, **SITE))
