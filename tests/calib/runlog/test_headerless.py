"""A text log without a header row: columns by position, samples evenly spaced at the stated rate."""

from __future__ import annotations

import gzip

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import REPO

from calib.errors import CalibError
from calib.runlog import read_run
from seqdesign.cli import main

MIKOFF = REPO / "tests" / "data" / "mikoff-mpu9150" / "imu0-first2000.log"
MAP = "1=accel_x_mps2,2=accel_y_mps2,3=accel_z_mps2,4=gyro_x_radps,5=gyro_y_radps,6=gyro_z_radps"
SITE = {"latitude_deg": 55.0, "height_m": 100.0}
# Four samples: specific force (m/s^2) then rates (rad/s), as mikoff's logs hold them.
TABLE = np.array(
    [
        [0.1, -0.2, 9.8, 0.01, 0.02, -0.03],
        [0.2, -0.1, 9.7, 0.02, 0.01, -0.02],
        [0.0, 0.3, 9.9, -0.01, 0.00, 0.04],
        [-0.1, 0.0, 9.81, 0.00, -0.02, 0.01],
    ]
)


def _text(sep: str, preamble: str = "") -> str:
    return preamble + "".join(sep.join(repr(float(x)) for x in row) + "\n" for row in TABLE)


@pytest.mark.parametrize("sep", [" ", "   ", "\t", ",", ";"])
def test_rows_by_position_are_evenly_spaced_at_the_stated_rate(tmp_path, sep):
    path = tmp_path / "imu.log"
    path.write_text(_text(sep))
    run = read_run(path, columns=MAP, sample_rate_hz=50.0, **SITE)
    # Sample i ends its interval at (i + 1) / rate; each row is the mean over that interval,
    # so its increment is the row times one period (the rectangular rule of docs/logs-columns.md).
    np.testing.assert_allclose(run.time_s, (np.arange(4) + 1) / 50.0, rtol=1e-15)
    np.testing.assert_allclose(run.dv_mps, TABLE[:, :3] / 50.0, rtol=1e-15)
    np.testing.assert_allclose(run.dtheta_rad, TABLE[:, 3:] / 50.0, rtol=1e-15)
    assert run.sample_rate_hz == 50.0


def test_the_rate_may_be_stated_in_the_file_and_a_mapped_time_column_is_used(tmp_path):
    path = tmp_path / "imu.txt"
    path.write_text(_text(" ", "# sample_rate_hz: 50\n\n"))
    run = read_run(path, columns=MAP, **SITE)
    np.testing.assert_allclose(run.time_s, (np.arange(4) + 1) / 50.0, rtol=1e-15)
    # A time column named by position is the time: 0.02 s steps, no rate needed.
    timed = tmp_path / "timed.dat"
    rows = np.column_stack([(np.arange(4) + 1) * 0.02, TABLE])
    timed.write_text("".join(" ".join(repr(float(x)) for x in r) + "\n" for r in rows))
    shifted = ",".join(f"{int(k) + 1}={v}" for k, v in (p.split("=") for p in MAP.split(",")))
    run = read_run(timed, columns="1=time_s," + shifted, **SITE)
    np.testing.assert_allclose(run.dv_mps, TABLE[:, :3] * 0.02, rtol=1e-12)
    assert abs(run.sample_rate_hz - 50.0) < 1e-9


def test_gzip_and_a_header_still_read_as_before(tmp_path):
    path = tmp_path / "imu.log.gz"
    path.write_bytes(gzip.compress(_text(" ").encode()))
    run = read_run(path, columns=MAP, sample_rate_hz=50.0, **SITE)
    assert len(run.time_s) == 4
    # A first row that is not all numbers is a header, as before: its names are mapped.
    named = tmp_path / "named.log"
    named.write_text("ax,ay,az,gx,gy,gz\n" + _text(","))
    with pytest.raises(CalibError, match="header row lacks columns"):
        read_run(named, columns="ax=accel_x_mps2", sample_rate_hz=50.0, **SITE)


NAMED_MAP = "ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps"


def test_a_header_that_names_no_time_is_read_evenly_spaced_at_the_stated_rate(tmp_path):
    # An Arduino sketch's "ax,ay,az,gx,gy,gz": the same rows as a file without a header.
    named = tmp_path / "named.csv"
    named.write_text("ax,ay,az,gx,gy,gz\n" + _text(","))
    run = read_run(named, columns=NAMED_MAP, sample_rate_hz=50.0, **SITE)
    bare = tmp_path / "bare.csv"
    bare.write_text(_text(","))
    same = read_run(bare, columns=MAP, sample_rate_hz=50.0, **SITE)
    np.testing.assert_array_equal(run.time_s, same.time_s)
    np.testing.assert_array_equal(run.dtheta_rad, same.dtheta_rad)
    np.testing.assert_array_equal(run.dv_mps, same.dv_mps)
    # Without the rate nothing says when the rows were taken: the refusal asks for it.
    with pytest.raises(CalibError, match="names no time column") as err:
        read_run(named, columns=NAMED_MAP, **SITE)
    assert "--sample-rate-hz" in err.value.fix


def test_a_time_column_the_map_left_out_is_not_replaced_by_the_rate(tmp_path):
    # Its stamps would show a gap that evenly spaced rows hide: the map must name it.
    rows = np.column_stack([(np.arange(4) + 1) * 0.02, TABLE])
    path = tmp_path / "timed.csv"
    path.write_text(
        "stamp,ax,ay,az,gx,gy,gz\n" + "".join(",".join(repr(float(x)) for x in r) + "\n" for r in rows)
    )
    with pytest.raises(CalibError, match="column 'stamp' looks like a time") as err:
        read_run(path, columns=NAMED_MAP, sample_rate_hz=50.0, **SITE)
    assert "stamp=time_s" in err.value.fix and "stamp=counter" in err.value.fix
    # Named otherwise: host milliseconds that repeat now and then (two rows read at once), or
    # clock times, are times too.
    for first, stamps in (
        ("host", ["1000", "1020", "1020", "1060"]),
        ("when", [f"12:00:0{k}.000" for k in range(4)]),
    ):
        other = tmp_path / f"{first}.csv"
        other.write_text(
            f"{first},ax,ay,az,gx,gy,gz\n"
            + "".join(
                f"{s}," + ",".join(repr(float(x)) for x in r) + "\n"
                for s, r in zip(stamps, TABLE, strict=True)
            )
        )
        with pytest.raises(CalibError, match=f"column '{first}' looks like a time"):
            read_run(other, columns=NAMED_MAP, sample_rate_hz=50.0, **SITE)


def test_a_column_that_never_changes_is_no_time_whatever_its_name(tmp_path):
    # A board's ultrasonic sensors, not fitted, log zeros as uS1, uS2 ...: "us" is a time word, but
    # a time that never moves times nothing. The rows are read at the rate stated, as without them.
    path = tmp_path / "board.csv"
    path.write_text(
        "uS1,ax,ay,az,gx,gy,gz\n" + "".join("0," + ",".join(repr(float(x)) for x in r) + "\n" for r in TABLE)
    )
    run = read_run(path, columns=NAMED_MAP, sample_rate_hz=50.0, **SITE)
    assert np.allclose(np.diff(run.time_s), 0.02)


def test_a_logger_s_preamble_above_its_header_is_read_as_such_and_samples_above_it_are_told(tmp_path):
    # Lines of text above the line the map names (tomisuarez2/ImuCalibration's "Fs,100") are the
    # logger's preamble: said, and the rows read as if they were commented out.
    path = tmp_path / "logger.csv"
    path.write_text("Fs,100\nLogging Type,0\nax,ay,az,gx,gy,gz\n" + _text(","))
    with pytest.warns(UserWarning, match=r"lines 1-2 above the header row \(line 3\) read as the logger's"):
        run = read_run(path, columns=NAMED_MAP, sample_rate_hz=50.0, **SITE)
    path.write_text("# Fs,100\n# Logging Type,0\nax,ay,az,gx,gy,gz\n" + _text(","))
    commented = read_run(path, columns=NAMED_MAP, sample_rate_hz=50.0, **SITE)
    np.testing.assert_array_equal(run.dv_mps, commented.dv_mps)
    # A row of numbers above the names is no preamble (samples before a header?): told, not skipped.
    path.write_text("1,2,3,4,5,6\nax,ay,az,gx,gy,gz\n" + _text(","))
    with pytest.raises(CalibError, match="they are on line 2") as err:
        read_run(path, columns=NAMED_MAP, sample_rate_hz=50.0, **SITE)
    assert "put '#' before the 1 line(s) above line 2" in err.value.fix


@pytest.mark.parametrize(
    ("kwargs", "said"),
    [
        ({"sample_rate_hz": 50.0}, "no header row .* by position 1..6"),
        ({"columns": MAP}, "no time column.*--sample-rate-hz"),
        ({"columns": "ax=accel_x_mps2", "sample_rate_hz": 50.0}, "'ax'.* by position, 1 to 6"),
        ({"columns": "1=accel_x_mps2,2=accel_y_mps2", "sample_rate_hz": 50.0}, "gyro on 0 of 3"),
    ],
)
def test_a_headerless_file_is_refused_naming_what_it_lacks(tmp_path, kwargs, said):
    path = tmp_path / "imu.log"
    path.write_text(_text(" "))
    with pytest.raises(CalibError, match=said):
        read_run(path, **SITE, **kwargs)


def test_bad_rows_are_named_by_the_files_own_line(tmp_path):
    path = tmp_path / "imu.log"
    lines = _text(" ", "# a comment\n").splitlines()
    short, bad = list(lines), list(lines)
    short[3] = "1 2 3 4 5"
    bad[4] = bad[4].replace("0.0", "x", 1)
    path.write_text("\n".join(short) + "\n")
    with pytest.raises(CalibError, match=r"line 4 \(sample 2\): row has 5 fields, the first row has 6"):
        read_run(path, columns=MAP, sample_rate_hz=50.0, **SITE)
    path.write_text("\n".join(bad) + "\n")
    with pytest.raises(CalibError, match=r"line 5, column \d \(sample 3\): field 'x' is not a number"):
        read_run(path, columns=MAP, sample_rate_hz=50.0, **SITE)


def test_mikoffs_real_log_reads_as_its_numbers():
    run = read_run(MIKOFF, columns=MAP, sample_rate_hz=100.0, **SITE)
    table = np.loadtxt(MIKOFF)
    assert len(run.time_s) == len(table) == 2000
    np.testing.assert_allclose(run.time_s[-1], 20.0, rtol=1e-15)  # 2000 samples at 100 Hz
    # Each increment is the row times its interval t_k - t_{k-1}, the difference of two float
    # times (k + 1) / 100: exact to a few 1e-13 relative, not to the last bit.
    np.testing.assert_allclose(run.dv_mps * 100.0, table[:, :3], rtol=1e-12)
    np.testing.assert_allclose(run.dtheta_rad * 100.0, table[:, 3:], rtol=1e-12)
    # Physics, not the file's bytes: held in the hand at the start, so |f| is gravity to a few
    # tenths of a m/s^2 (a MEMS unit's uncalibrated scale and bias, and the hand), and the rates a
    # fraction of a rad/s (read as deg/s they would be 57 times smaller: under 0.01).
    f = np.linalg.norm(run.dv_mps[:100] * 100.0, axis=1).mean()
    assert abs(f - 9.81) < 0.5
    w = np.abs(run.dtheta_rad * 100.0).max()
    assert 0.05 < w < 35.0


def test_the_cli_calibrates_a_headerless_log_and_refuses_in_one_line(tmp_path):
    args = ["calibrate", str(MIKOFF), "--latitude", "55", "--height", "100", "--columns", MAP]
    r = CliRunner().invoke(main, args)
    assert r.exit_code != 0 and "Traceback" not in r.output
    assert "--sample-rate-hz" in r.output and len(r.output.strip().splitlines()) == 1
    # These 20 s held in the hand leave the 21 unobserved: the CLI gets past the reader to the fit's
    # own refusal (the whole log calibrates: docs/logs-columns.md).
    r = CliRunner().invoke(main, [*args, "--sample-rate-hz", "100", "--by-hand", "--profile", "mems"])
    assert "Traceback" not in r.output
    assert "no header" not in r.output and "no time column" not in r.output
    assert "2000 samples, 20.0 s" in r.output


def test_rows_a_serial_link_garbled_are_lost_samples_under_allow_gaps(tmp_path):
    # A serial logger that lost bytes: row 100 cut short, rows 200 and 201 run together (a line end
    # lost: 6 + 3 fields). Refused as they are; with allow_gaps each is left out as the samples
    # it stood for (one, and two), so the count steps over them and every other row keeps its
    # place on the rate's clock (a unit at rest: the gaps are filled there).
    rng = np.random.default_rng(3)
    rows = np.array([0.1, -0.2, 9.8, 0.0, 0.0, 0.0]) + rng.normal(0.0, 1e-3, (300, 6))
    text = [" ".join(repr(float(x)) for x in r) for r in rows]
    lines = text[:99] + [" ".join(text[99].split()[:4])] + text[100:199]
    lines += [text[199] + " " + " ".join(text[200].split()[:3])] + text[201:]
    path = tmp_path / "serial.log"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(CalibError) as err:
        read_run(path, columns=MAP, sample_rate_hz=100.0, **SITE)
    assert "line 100 (sample 99): row has 4 fields" in err.value.message
    assert "the CLI's --allow-gaps" in err.value.fix
    with pytest.warns(UserWarning, match=r"2 row\(s\) of the wrong width \(line\(s\) 100, 200\) left out"):
        run = read_run(path, columns=MAP, sample_rate_hz=100.0, allow_gaps=True, **SITE)
    assert run.n_samples == 300
    np.testing.assert_allclose(run.time_s, (np.arange(300) + 1) / 100.0, rtol=0, atol=1e-12)  # filled: k T
    kept = np.setdiff1d(np.arange(300), [99, 199, 200])
    np.testing.assert_allclose(run.dv_mps[kept], rows[kept, :3] / 100.0, rtol=1e-15)
    assert [count for _, count in run.clock.dropped] == [1, 2]
    # The same rows under a header that names no time (an Arduino sketch's): read alike.
    named = tmp_path / "named.csv"
    named.write_text("ax,ay,az,gx,gy,gz\n" + "\n".join(line.replace(" ", ",") for line in lines) + "\n")
    names = "ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps"
    with pytest.warns(UserWarning, match=r"line\(s\) 101, 201\) left out"):  # below the header
        same = read_run(named, columns=names, sample_rate_hz=100.0, allow_gaps=True, **SITE)
    np.testing.assert_array_equal(same.dv_mps, run.dv_mps)


def test_a_garbled_row_under_a_header_with_a_time_is_left_out_under_allow_gaps(tmp_path):
    # A logger's file with a header and stamps: a row cut short on the wire is refused naming
    # allow_gaps, and left out with it, its stamp's absence a lost sample the clock counts.
    noise = np.random.default_rng(2).normal(0.0, 1e-3, (400, 6))  # a still unit's, as a sensor shows it
    still = np.array([0.001, -0.002, 0.003, 0.05, 0.02, 9.81]) + noise
    rows = [f"{10 * (k + 1)}," + ",".join(repr(float(x)) for x in r) for k, r in enumerate(still)]
    rows[200] = "2010,0.001,-0.0"
    path = tmp_path / "logger.csv"
    path.write_text("t,gx,gy,gz,ax,ay,az\n" + "\n".join(rows) + "\n")
    names = "t=time_ms,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps,"
    names += "ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2"
    with pytest.raises(CalibError) as err:
        read_run(path, columns=names, **SITE)
    assert "line 202 (sample 200)" in err.value.where and "the CLI's --allow-gaps" in err.value.fix
    with pytest.warns(UserWarning, match=r"1 row\(s\) of the wrong width \(line\(s\) 202\) left out"):
        run = read_run(path, columns=names, allow_gaps=True, **SITE)
    assert run.n_samples == 400 and [count for _, count in run.clock.dropped] == [1]  # filled at rest
