"""Run logs: exact round trips, tolerant where the spec allows, precise refusals."""

from __future__ import annotations

import hashlib
import json
import os
import zipfile

import numpy as np
import pytest

from calib.errors import CalibError
from calib.io import files as fileio
from calib.io.files import atomic_write_bytes, atomic_write_text, sha256_file
from calib.runlog import Run, check_run, make_meta, read_run, write_run

HEADER = "time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps"
META = ["# format: imu-run/1", "# latitude_deg: 39.98", "# height_m: 50", "# sample_rate_hz: 200"]
ROW = "{t},1e-07,-2e-07,3e-07,0.001,0.049,-0.002"


def make_run(n: int = 40, gimbal: bool = False, seed: int = 1) -> Run:
    """A small valid run whose floats need all 17 digits to round-trip."""
    rng = np.random.default_rng(seed)
    time = np.arange(1, n + 1) / 200.0 + 1.0 / 3.0
    meta = make_meta(
        39.98,
        50.0,
        200.0,
        gravity_mps2=9.80123,
        sequence="paper-9pos",
        operator="J. Doe",
        note="kept: unknown key",
    )
    return Run(
        time_s=time,
        dtheta_rad=rng.normal(size=(n, 3)) * 1e-5,
        dv_mps=rng.normal(size=(n, 3)) * 1e-3 + [0.0, 0.0, 0.049],
        meta=meta,
        gimbal_deg=rng.uniform(-400, 400, size=(n, 3)) if gimbal else None,
    )


def csv_text(
    rows: int = 5, meta: list[str] | None = None, header: str = HEADER, body: list[str] | None = None
) -> str:
    meta = META if meta is None else meta
    if body is None:
        body = [ROW.format(t=(i + 1) / 200.0) for i in range(rows)]
    return "\n".join([*meta, header, *body]) + "\n"


def write_text(tmp_path, text: str, name: str = "run.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def refusal(path, *parts: str, allow_gaps: bool = False) -> str:
    """Read ``path``, expect a CalibError naming the file and every part; return the message."""
    with pytest.raises(CalibError) as info:
        read_run(path, allow_gaps=allow_gaps)
    message = str(info.value)
    assert path.name in message
    for part in parts:
        assert part in message, f"{part!r} not in {message!r}"
    return message


def save_npz(tmp_path, name: str = "run.npz", **arrays):
    path = tmp_path / name
    np.savez(path, **arrays)
    return path


def npz_arrays(run: Run) -> dict:
    return {
        "time_s": run.time_s,
        "dtheta_rad": run.dtheta_rad,
        "dv_mps": run.dv_mps,
        "meta": json.dumps(run.meta),
    }


def assert_same(a: Run, b: Run) -> None:
    for name in ("time_s", "dtheta_rad", "dv_mps"):
        got, want = getattr(a, name), getattr(b, name)
        assert got.dtype == np.float64 and np.array_equal(got, want), name
    if b.gimbal_deg is None:
        assert a.gimbal_deg is None
    else:
        assert np.array_equal(a.gimbal_deg, b.gimbal_deg)
    assert a.meta == b.meta
    assert list(a.meta) == list(b.meta)


# --------------------------------------------------------------------------
# Round trips and tolerated variations
# --------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".CSV", ".Npz"])
@pytest.mark.parametrize("gimbal", [False, True])
def test_round_trip_is_exact(tmp_path, suffix, gimbal):
    run = make_run(gimbal=gimbal)
    path = tmp_path / f"run{suffix}"
    write_run(run, path)
    back = read_run(path)
    assert_same(back, run)
    assert back.source == str(path)
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left over


def test_csv_starts_with_format_and_keeps_unknown_keys(tmp_path):
    path = tmp_path / "run.csv"
    write_run(make_run(), path)
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "# format: imu-run/1"
    assert "# operator: J. Doe" in lines
    assert "# note: kept: unknown key" in lines
    assert lines[8] == HEADER


def test_properties(tmp_path):
    path = write_text(tmp_path, csv_text(rows=4))
    run = read_run(path)
    assert run.latitude_deg == 39.98 and run.height_m == 50.0
    assert run.sample_rate_hz == 200.0 and run.dt_nominal == 0.005
    assert run.gravity_mps2 is None and run.sequence_name is None
    assert run.n_samples == 4
    assert run.duration_s == pytest.approx(0.02)
    full = make_run()
    assert full.gravity_mps2 == 9.80123 and full.sequence_name == "paper-9pos"


def test_column_order_and_extra_columns(tmp_path):
    header = (
        "note,dv_z_mps,dv_y_mps,dv_x_mps,inner_deg,time_s,middle_deg,dtheta_z_rad,"
        "dtheta_y_rad,outer_deg,dtheta_x_rad,temp_c"
    )
    body = [
        f"ok {i},{0.3 + i},{0.2 + i},{0.1 + i},{i}.3,{(i + 1) / 200},{i}.2,"
        f"{3e-7 * i},{2e-7 * i},{i}.1,{1e-7 * i},21.5"
        for i in range(3)
    ]
    run = read_run(write_text(tmp_path, csv_text(header=header, body=body)))
    assert np.array_equal(run.time_s, [0.005, 0.01, 0.015])
    assert np.array_equal(run.dv_mps[2], [2.1, 2.2, 2.3])
    assert np.array_equal(run.dtheta_rad[1], [1e-7, 2e-7, 3e-7])
    assert np.array_equal(run.gimbal_deg[1], [1.1, 1.2, 1.3])


def test_crlf_bom_comments_and_blank_lines(tmp_path):
    text = csv_text(rows=3, meta=["# A comment line without a colon", "", *META])
    text = text.replace("\n", "\r\n") + "\r\n\r\n"
    path = tmp_path / "run.csv"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    run = read_run(path)
    assert run.n_samples == 3 and run.meta["format"] == "imu-run/1"


def test_blank_line_in_body_keeps_line_numbers(tmp_path):
    body = [ROW.format(t=0.005), "", ROW.format(t=0.01), ROW.format(t=float("nan"))]
    path = write_text(tmp_path, csv_text(body=body))
    # meta 1-4, header 5, rows on 6, (blank 7), 8, 9
    refusal(path, "line 9", "column time_s", "sample 2", "not a finite number")


def test_npz_meta_numbers_and_extra_arrays_accepted(tmp_path):
    run = make_run()
    arrays = npz_arrays(run)
    arrays["meta"] = json.dumps(
        {"format": "imu-run/1", "latitude_deg": 39.98, "height_m": 50, "sample_rate_hz": 200.0}
    )
    path = save_npz(tmp_path, temperature=np.zeros(3), **arrays)
    back = read_run(path)
    assert back.latitude_deg == 39.98 and back.height_m == 50.0
    assert back.meta["sample_rate_hz"] == "200.0"


def test_npz_is_uncompressed_and_pickle_free(tmp_path):
    path = tmp_path / "run.npz"
    write_run(make_run(gimbal=True), path)
    with zipfile.ZipFile(path) as archive:
        assert {i.compress_type for i in archive.infolist()} == {zipfile.ZIP_STORED}
        assert sorted(archive.namelist()) == [
            "dtheta_rad.npy",
            "dv_mps.npy",
            "gimbal_deg.npy",
            "meta.npy",
            "time_s.npy",
        ]
    with np.load(path, allow_pickle=False) as loaded:
        assert json.loads(str(loaded["meta"]))["format"] == "imu-run/1"


# --------------------------------------------------------------------------
# CSV refusals
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "meta, parts",
    [
        # A file without '# format:' is a logger's file (tests/calib/runlog/test_columns.py) and reads.
        (["# format: imu-run/2", *META[1:]], ["line 1", "unknown format 'imu-run/2'"]),
        ([META[0], META[2], META[3]], ["'latitude_deg' is missing", "# latitude_deg:"]),
        ([META[0], META[1], META[3]], ["'height_m' is missing"]),
        (META[:3], ["'sample_rate_hz' is missing"]),
        ([*META[:3], "# sample_rate_hz: 200 Hz"], ["line 4", "'200 Hz', not a number"]),
        ([*META[:3], "# sample_rate_hz: 0"], ["line 4", "not positive"]),
        ([*META[:3], "# sample_rate_hz: -100"], ["line 4", "not positive"]),
        ([META[0], "# latitude_deg: 91", *META[2:]], ["line 2", "outside [-90, 90]"]),
        ([META[0], "# latitude_deg: nan", *META[2:]], ["line 2", "not a finite number"]),
        ([*META[:2], "# height_m: inf", META[3]], ["line 3", "not a finite number"]),
        ([*META, "# gravity_mps2: -9.8"], ["line 5", "gravity_mps2", "not positive"]),
        ([*META, "# gravity_mps2: NaN"], ["line 5", "gravity_mps2", "not a finite number"]),
        ([*META, "# height_m: 60"], ["line 5", "appears twice", "line 3"]),
        ([*META, "# : value"], ["line 5", "no key"]),
    ],
)
def test_bad_metadata(tmp_path, meta, parts):
    refusal(write_text(tmp_path, csv_text(meta=meta)), *parts)


def test_empty_file(tmp_path):
    refusal(write_text(tmp_path, ""), "empty")
    refusal(write_text(tmp_path, " \n\n"), "empty")


def test_no_header(tmp_path):
    refusal(write_text(tmp_path, "\n".join(META) + "\n"), "no header row")


def test_no_data_rows(tmp_path):
    refusal(write_text(tmp_path, csv_text(body=[])), "line 5", "no", "data rows")


def test_fewer_than_two_samples(tmp_path):
    refusal(write_text(tmp_path, csv_text(rows=1)), "1 sample", "at least 2")


def test_missing_column_is_named(tmp_path):
    header = HEADER.replace(",dv_y_mps", ",speed")
    body = [ROW.format(t=0.005), ROW.format(t=0.01)]
    refusal(write_text(tmp_path, csv_text(header=header, body=body)), "line 5", "'dv_y_mps'")


def test_column_names_are_case_sensitive(tmp_path):
    header = HEADER.replace("time_s", "Time_S")
    refusal(write_text(tmp_path, csv_text(header=header)), "'time_s'", "'Time_S' should be")


def test_partial_gimbal_columns(tmp_path):
    header = HEADER + ",outer_deg,inner_deg"
    body = [ROW.format(t=(i + 1) / 200) + ",0,0" for i in range(3)]
    refusal(write_text(tmp_path, csv_text(header=header, body=body)), "middle_deg")


def test_duplicate_column(tmp_path):
    header = HEADER + ",time_s"
    body = [ROW.format(t=(i + 1) / 200) + ",0" for i in range(3)]
    refusal(write_text(tmp_path, csv_text(header=header, body=body)), "'time_s' appears twice")


@pytest.mark.parametrize("bad_row", [ROW.format(t=0.015) + ",7", "0.015,1e-07,-2e-07"])
def test_wrong_number_of_fields(tmp_path, bad_row):
    body = [ROW.format(t=0.005), ROW.format(t=0.01), bad_row, ROW.format(t=0.02)]
    refusal(write_text(tmp_path, csv_text(body=body)), "line 8", "sample 2", "the header has 7")


def test_a_last_row_the_logger_left_unfinished_is_left_out_and_said(tmp_path):
    # A logger stopped mid-write: the last row is short and has no line end. The samples
    # before it read exactly as from the file without it; the warning names its line.
    body = [ROW.format(t=(i + 1) / 200.0) for i in range(6)]
    whole = write_text(tmp_path, csv_text(body=body), "whole.csv")
    cut = write_text(tmp_path, csv_text(body=body).rstrip("\n") + "\n0.035,1e-07,-2", "cut.csv")
    with pytest.warns(UserWarning, match=r"cut.csv, line 12: the last row has 3 of 7 fields and no line end"):
        got = read_run(cut)
    want = read_run(whole)
    assert got.n_samples == 6
    assert np.array_equal(got.dtheta_rad, want.dtheta_rad) and np.array_equal(got.dv_mps, want.dv_mps)
    # The same short row ended by a line end was written so: refused, as is a short row inside.
    refusal(
        write_text(tmp_path, csv_text(body=[*body, "0.035,1e-07,-2"]), "ended.csv"), "line 12", "has 3 fields"
    )
    inside = [*body[:3], "0.02,1e-07,-2", *body[3:]]
    refusal(write_text(tmp_path, csv_text(body=inside).rstrip("\n"), "inside.csv"), "line 9", "has 3 fields")


def test_a_whole_last_row_with_decimal_commas_is_kept(tmp_path):
    # Semicolons between fields, commas in the numbers: the last row, written whole but
    # without a line end, has as many fields as the row before (a whole number has no comma).
    header = HEADER.replace(",", ";")
    body = [ROW.format(t=(i + 1) / 200.0).replace(",", ";").replace(".", ",") for i in range(6)]
    body[-1] = body[-1].replace("0,001", "1")  # a field written as a whole number
    path = write_text(tmp_path, "\n".join([*META, header, *body]), "euro.csv")
    with pytest.warns(UserWarning, match="decimal commas") as said:
        run = read_run(path)
    assert run.n_samples == 6 and not any("left out" in str(w.message) for w in said)


def test_a_gzip_log_cut_mid_write_reads_its_whole_lines_and_says_so(tmp_path):
    import gzip

    body = [ROW.format(t=(i + 1) / 200.0) for i in range(4000)]
    text = csv_text(body=body).encode()
    packed = gzip.compress(text)
    cut = tmp_path / "cut.csv.gz"
    cut.write_bytes(packed[: len(packed) // 2])
    with pytest.warns(UserWarning, match="gzip stream ends early"):
        got = read_run(cut)
    # The whole rows before the cut, in order, each as written (its stamp (i + 1) / 200).
    n = got.n_samples
    assert 1000 < n < 4000
    assert np.array_equal(got.time_s, (np.arange(n) + 1) / 200.0)
    assert np.allclose(got.dv_mps[-1], [0.001, 0.049, -0.002], rtol=0, atol=1e-15)
    # A gzip cut within its first block holds no line: refused as unreadable, naming the file.
    stub = tmp_path / "stub.csv.gz"
    stub.write_bytes(packed[:12])
    refusal(stub, "cannot read the file")


def test_non_numeric_field(tmp_path):
    body = [ROW.format(t=(i + 1) / 200) for i in range(6)]
    body[4] = body[4].replace("0.049", "0.0x49")
    refusal(
        write_text(tmp_path, csv_text(body=body)),
        "line 10",
        "column dv_y_mps",
        "sample 4",
        "'0.0x49' is not a number",
    )


def test_comment_inside_data_is_a_bad_field(tmp_path):
    body = [ROW.format(t=0.005), "# pause", ROW.format(t=0.01)]
    refusal(write_text(tmp_path, csv_text(body=body)), "line 7")


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_non_finite_sample(tmp_path, value):
    body = [ROW.format(t=(i + 1) / 200) for i in range(6)]
    body[3] = body[3].replace("-2e-07", value)
    refusal(
        write_text(tmp_path, csv_text(body=body)),
        "line 9",
        "column dtheta_y_rad",
        "sample 3",
        "not a finite number",
    )


def test_non_utf8_refused(tmp_path):
    path = tmp_path / "run.csv"
    text = csv_text(meta=[*META, "# operator: J. Doe"])
    path.write_bytes(text.encode("utf-8").replace(b"Doe", "Dö".encode("latin-1")))
    refusal(path, "line 5", "not valid UTF-8", "save the file as UTF-8")


def test_time_must_strictly_increase(tmp_path):
    # A repeated time with other increments is not a copy of a sample, and a clock that keeps the
    # period elsewhere does not stamp two samples alike: refused where it happens.
    times = [0.005, 0.01, 0.015, 0.015, 0.02]
    body = [ROW.format(t=t) for t in times]
    body[3] = body[3].replace("1e-07", "2e-07", 1)
    path = write_text(tmp_path, csv_text(body=body))
    refusal(path, "line 9", "sample 3", "two samples at one time", "time_s = 0.015 follows 0.015")
    times = [0.005, 0.01, 0.008, 0.02]
    path = write_text(tmp_path, csv_text(body=[ROW.format(t=t) for t in times]))
    refusal(path, "line 8", "sample 2", "time goes backwards")


def test_exact_duplicate_rows_are_named_and_removed_when_allowed(tmp_path):
    times = [0.005, 0.01, 0.015, 0.015, 0.02]
    path = write_text(tmp_path, csv_text(body=[ROW.format(t=t) for t in times]))
    refusal(path, "line 9", "sample 3", "1 sample(s) duplicated: 1 at t = 0.015 s", "--allow-gaps")
    run = read_run(path, allow_gaps=True)
    assert run.n_samples == 4 and run.clock.duplicates == [(0.015, 1)]


def test_dropped_samples_are_each_named(tmp_path):
    # Steps of 7 and 30 periods: 6 and 29 samples lost.
    times = [0.005, 0.01, 0.015, 0.05, 0.055, 0.205, 0.21]
    path = write_text(tmp_path, csv_text(body=[ROW.format(t=t) for t in times]))
    refusal(
        path,
        "line 9",
        "sample 3",
        "35 sample(s) dropped",
        "6 at t = 0.02 s",
        "29 at t = 0.06 s",
        "--allow-gaps",
    )
    run = read_run(path, allow_gaps=True)
    assert run.n_samples == 42  # filled: the IMU's own count from 0.005 to 0.21 s


def test_two_period_step_is_one_dropped_sample(tmp_path):
    # 0.3 s is 60 periods at 200 Hz; a step of exactly 2 periods (with float rounding)
    # is one sample lost, not jitter.
    times = [0.3 + k * 0.005 for k in range(5)] + [0.33, 0.335]
    path = write_text(tmp_path, csv_text(body=[ROW.format(t=t) for t in times]))
    refusal(path, "1 sample(s) dropped: 1 at t = 0.325 s")


def test_time_step_that_is_no_whole_number_of_periods_is_refused(tmp_path):
    times = [0.005, 0.01, 0.0175, 0.0225]
    path = write_text(tmp_path, csv_text(body=[ROW.format(t=t) for t in times]))
    # Half a period behind the count from sample 2 on, and staying: neither jitter nor lost samples.
    refusal(path, "line 8", "sample 2", "0.50 periods", allow_gaps=True)
    times = [0.005, 0.01, 0.015, 0.02, 1e300]
    path = write_text(tmp_path, csv_text(body=[ROW.format(t=t) for t in times]))
    refusal(path, "line 10", "sample 4", "the time jumps by", allow_gaps=True)


def test_missing_file_and_unknown_suffix(tmp_path):
    with pytest.raises(CalibError, match="file not found"):
        read_run(tmp_path / "absent.csv")
    with pytest.raises(CalibError, match="absent.npz"):
        read_run(tmp_path / "absent.npz")
    with pytest.raises(CalibError, match=r"run\.xlsx.*unknown run log type"):
        read_run(write_text(tmp_path, csv_text(), name="run.xlsx"))
    # A logger's text log (.txt, .log, .dat) is read by the CSV reader's rules.
    assert read_run(write_text(tmp_path, csv_text(), name="run.txt")).time_s.size > 0
    with pytest.raises(CalibError, match="unknown run log type"):
        write_run(make_run(), tmp_path / "run.h5")
    assert not (tmp_path / "run.h5").exists()


# --------------------------------------------------------------------------
# NPZ refusals
# --------------------------------------------------------------------------


def test_npz_missing_arrays(tmp_path):
    arrays = npz_arrays(make_run())
    del arrays["dv_mps"], arrays["meta"]
    refusal(save_npz(tmp_path, **arrays), "lacks arrays", "'dv_mps'", "'meta'")


@pytest.mark.parametrize(
    "name, shape", [("time_s", (40, 1)), ("dtheta_rad", (40, 2)), ("dv_mps", (39, 3)), ("gimbal_deg", (3,))]
)
def test_npz_wrong_shapes(tmp_path, name, shape):
    arrays = npz_arrays(make_run())
    arrays[name] = np.zeros(shape)
    refusal(save_npz(tmp_path, **arrays), f"array '{name}'", f"{shape}")


def test_npz_non_numeric_array(tmp_path):
    arrays = npz_arrays(make_run())
    arrays["time_s"] = np.array(["a"] * 40)
    refusal(save_npz(tmp_path, **arrays), "array 'time_s'", "not real numbers")


def test_npz_truncated_and_foreign_files(tmp_path):
    path = tmp_path / "run.npz"
    write_run(make_run(), path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    refusal(path, "not a readable NPZ archive")
    path.write_bytes(b"")
    refusal(path, "not a readable NPZ archive")
    path.write_bytes(b"time_s,dv\n1,2\n")
    refusal(path, "not a readable NPZ archive")
    np.save(tmp_path / "single.npy", np.zeros(3))
    os.replace(tmp_path / "single.npy", path)
    refusal(path, "not an NPZ archive")


def test_npz_corrupted_member(tmp_path):
    path = tmp_path / "run.npz"
    write_run(make_run(), path)
    data = bytearray(path.read_bytes())
    # Flip bytes inside dv_mps' data: the zip CRC check must catch it.
    start = data.find(b"dv_mps.npy") + 200
    data[start : start + 8] = b"\x00" * 8
    path.write_bytes(bytes(data))
    refusal(path, "cannot read the archive")


def test_npz_refuses_pickle(tmp_path):
    arrays = npz_arrays(make_run())
    arrays["meta"] = np.array([{"format": "imu-run/1"}], dtype=object)
    refusal(save_npz(tmp_path, **arrays), "cannot read the archive", "pickle")


@pytest.mark.parametrize(
    "meta, part",
    [
        ("{not json", "not valid JSON"),
        ('["format", "imu-run/1"]', "not an object"),
        ('{"format": "imu-run/1", "x": null}', "meta key 'x'"),
        (np.zeros(2), "not one JSON string"),
    ],
)
def test_npz_bad_meta(tmp_path, meta, part):
    arrays = npz_arrays(make_run())
    arrays["meta"] = meta
    refusal(save_npz(tmp_path, **arrays), part)


def test_npz_meta_rules_name_the_key(tmp_path):
    run = make_run()
    run.meta["latitude_deg"] = "-95"
    refusal(save_npz(tmp_path, **npz_arrays(run)), "meta key 'latitude_deg'", "outside")


def test_npz_non_finite_names_element(tmp_path):
    run = make_run()
    run.dv_mps[17, 1] = np.nan
    run.dtheta_rad[20, 0] = np.inf
    refusal(save_npz(tmp_path, **npz_arrays(run)), "dv_mps[17, 1]", "not a finite number")


def test_npz_gap_and_order(tmp_path):
    run = make_run()
    run.time_s[25:] += 1.0
    message = refusal(save_npz(tmp_path, **npz_arrays(run)), "200 sample(s) dropped", "time_s[25]")
    assert "allow_gaps (the CLI's --allow-gaps)" in message
    assert read_run(tmp_path / "run.npz", allow_gaps=True).n_samples == 240
    run.time_s[30] = run.time_s[29]
    refusal(save_npz(tmp_path, **npz_arrays(run)), "time_s[30]", allow_gaps=True)


# --------------------------------------------------------------------------
# Writing: validation and atomicity
# --------------------------------------------------------------------------


def test_write_refuses_invalid_runs(tmp_path):
    run = make_run()
    run.dv_mps[3, 2] = np.nan
    with pytest.raises(CalibError, match=r"dv_mps\[3, 2\]"):
        write_run(run, tmp_path / "run.csv")
    run = make_run()
    del run.meta["format"]
    with pytest.raises(CalibError, match="format"):
        write_run(run, tmp_path / "run.npz")
    run = make_run()
    run.meta["bad: key"] = "x"
    with pytest.raises(CalibError, match="cannot be written"):
        write_run(run, tmp_path / "run.csv")
    assert list(tmp_path.iterdir()) == []


def test_gaps_may_be_written(tmp_path):
    run = make_run()
    run.time_s[10:] += 0.5
    write_run(run, tmp_path / "run.csv")
    with pytest.raises(CalibError, match="dropped"):
        check_run(run)
    assert read_run(tmp_path / "run.csv", allow_gaps=True).n_samples == 140
    run.time_s[10:] += 0.505  # 201 samples lost: more than the neighbours can stand for
    write_run(run, tmp_path / "run.csv")
    refusal(tmp_path / "run.csv", "201 samples lost", "split the log", allow_gaps=True)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
@pytest.mark.parametrize("failure", [KeyboardInterrupt, OSError])
def test_failed_write_leaves_nothing(tmp_path, monkeypatch, suffix, failure):
    def broken_fsync(fd):
        raise failure("simulated failure mid-write")

    monkeypatch.setattr(fileio.os, "fsync", broken_fsync)
    path = tmp_path / f"run{suffix}"
    expected = KeyboardInterrupt if failure is KeyboardInterrupt else CalibError
    with pytest.raises(expected):
        write_run(make_run(), path)
    assert list(tmp_path.iterdir()) == []


def test_failed_write_keeps_old_file(tmp_path, monkeypatch):
    path = tmp_path / "result.toml"
    atomic_write_text(path, "old = 1\n")

    def broken_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(fileio.os, "replace", broken_replace)
    with pytest.raises(CalibError, match="result.toml.*No space left"):
        atomic_write_text(path, "new = 2\n")
    assert path.read_text() == "old = 1\n"
    assert list(tmp_path.iterdir()) == [path]


def test_atomic_write_permissions_and_missing_directory(tmp_path):
    path = tmp_path / "a.bin"
    atomic_write_bytes(path, b"\x00\x01")
    assert path.read_bytes() == b"\x00\x01"
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
    with pytest.raises(CalibError, match="no_such_dir"):
        atomic_write_bytes(tmp_path / "no_such_dir" / "a.bin", b"x")


def test_sha256_file(tmp_path):
    path = tmp_path / "data.bin"
    path.write_bytes(b"imu" * 1000)
    assert sha256_file(path) == hashlib.sha256(b"imu" * 1000).hexdigest()
    with pytest.raises(CalibError, match="missing.bin"):
        sha256_file(tmp_path / "missing.bin")


def test_csv_fallback_reads_what_float_reads(tmp_path):
    # np.loadtxt rejects '1_0'; the precise fallback parser then decides.
    body = [ROW.format(t=0.005), ROW.format(t=0.01).replace("0.001", "0.00_1")]
    run = read_run(write_text(tmp_path, csv_text(body=body)))
    assert run.dv_mps[1, 0] == 0.001


def test_make_meta_round_trips_numbers():
    meta = make_meta(0.1 + 0.2, -12.5, 100)
    assert float(meta["latitude_deg"]) == 0.1 + 0.2
    assert list(meta)[0] == "format"
    check_run(Run(np.array([0.01, 0.02]), np.zeros((2, 3)), np.zeros((2, 3)), meta))


def test_big_csv_is_fast_enough(tmp_path):
    # A 20,000-sample slice; the 336,000-sample timing is in the module report.
    n = 20_000
    run = Run(
        np.arange(1, n + 1) / 200.0,
        np.full((n, 3), 1e-7),
        np.full((n, 3), 0.049),
        make_meta(40.0, 0.0, 200.0),
    )
    path = tmp_path / "run.csv"
    write_run(run, path)
    assert read_run(path).n_samples == n
    assert path.read_bytes().count(b"\n") == n + 5
