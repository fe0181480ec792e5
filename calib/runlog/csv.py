"""The CSV run log: read (``.csv``, ``.csv.gz``, a logger's columns) and write.

A refusal names the file and the 1-based line number counted from the top of
the file, plus the column and the 0-based sample index.
"""

from __future__ import annotations

import itertools
import os
import warnings
from dataclasses import replace

import numpy as np

from calib.errors import CalibError

from .checks import check_meta, check_samples
from .clipping import clip_mask, sensor_clipping
from .clock import sampled_at_stamps, stamps_rate
from .columns import (
    COUNTER,
    ColumnPlan,
    apply_column_map,
    parse_column_map,
    plan_columns,
    time_unit_suspect,
    to_increments,
)
from .conversion import Conversion, sensor_si
from .counter import counter_suspect, counter_time
from .dialect import (
    labelled_rows,
    past_preamble,
    templated_rows,
    to_commas,
    unquoted,
    without_repeated_headers,
    without_units_row,
)
from .format import ARRAY_COLUMNS, FORMAT, GIMBAL_COLUMNS, REQUIRED_COLUMNS, REQUIRED_META
from .headerless import Garbled, by_commented_names, mapped_header, with_header, with_row_counter
from .loggers import apple_sign_warning, known_header_map, with_logger_rate
from .paths import read_bytes
from .polled import own_intervals
from .rollover import mended, said_rollover
from .run import Run, meta_float
from .text import decode_lines, header_names, is_comment, without_cut_last_row
from .wallclock import with_seconds, with_split_stamp


class _CsvLocator:
    """Names places in a CSV file: 1-based line numbers, column names, sample index."""

    def __init__(
        self,
        name: str,
        key_lines: dict[str, int],
        sample_lines: np.ndarray,
        columns: dict[str, tuple[str, ...]] | None = None,
    ):
        self.name = name
        self.key_lines = key_lines
        self.sample_lines = sample_lines
        self.columns = {**ARRAY_COLUMNS, **(columns or {})}  # the file's own column names

    def key(self, key: str) -> str:
        line = self.key_lines.get(key)
        return self.name if line is None else f"{self.name}, line {line}"

    def sample(self, array: str, index: int, component: int | None = None) -> str:
        text = f"{self.name}, line {int(self.sample_lines[index])}"
        if component is not None or array == "time_s":
            text += f", column {self.columns[array][component or 0]}"
        return text + f" (sample {index})"


def read_csv(
    path: str | os.PathLike,
    allow_gaps: bool,
    options: dict | None = None,
    columns=None,
    conversion: Conversion | None = None,
) -> Run:
    """Read a CSV run log (see module docstring for how places are named).

    ``columns`` maps the file's column names to the grammar's
    (:func:`calib.runlog.columns.parse_column_map`); ``options`` holds
    ``latitude_deg``, ``height_m`` and ``sample_rate_hz`` for a file without
    them; ``conversion`` turns columns in raw counts into SI.
    """
    name = str(path)
    mapping = parse_column_map(columns, name)
    apple = apple_sign_warning(mapping, name)
    if apple is not None:
        warnings.warn(apple, stacklevel=2)
    lines = without_cut_last_row(decode_lines(read_bytes(path), name), name)
    meta, key_lines, header_index = parse_preamble(lines, name)
    header_index = past_preamble(lines, header_index, mapping, name)
    lines, labelled = labelled_rows(lines, header_index, name)
    lines, header_index = templated_rows(lines, header_index, name)  # a sketch's serial prints
    lines = without_units_row(lines, header_index, name)
    lines = without_repeated_headers(unquoted(lines, header_index, name), header_index, name)
    mapping = mapping or known_header_map(lines, header_index, name)  # EuRoC's, ROS's
    mapping = by_commented_names(lines, header_index, mapping, name)
    # A file without a header row gets one of positions.
    lines, added = with_header(lines, header_index, mapping, meta, options or {}, name, allow_gaps)
    added += labelled
    lines = to_commas(lines, header_index, name)
    lines, mapping = with_split_stamp(lines, header_index, mapping, name, added)  # ROS 2's sec,nanosec
    stated = (options or {}).get("sample_rate_hz") is not None or "sample_rate_hz" in meta
    names = mapped_header(lines, header_index, mapping, name)
    lines = with_row_counter(lines, header_index, names, stated, name, allow_gaps, added)
    plan, has_gimbal, positions = _parse_header(lines[header_index], header_index + 1, name, mapping)
    options = with_logger_rate(options or {}, plan, stated, lines, header_index, name)
    rows, row_lines = _data_rows(lines, header_index + 1)
    row_lines = row_lines - added  # the file's own line numbers
    if not rows:
        raise CalibError(
            "the header row is not followed by any data rows",
            f"{name}, line {header_index + 1}",
            "a run log needs one row per sample",
        )
    n_fields = len(lines[header_index].split(","))
    rows, row_lines = _check_field_counts(rows, row_lines, n_fields, name, allow_gaps)
    at = lambda i: f"{name}, line {int(row_lines[i])} (sample {i})"  # noqa: E731
    rows, plan = with_seconds(rows, plan.time, plan, at)  # a time column of HH:MM:SS.fff
    wanted = [plan.time, *plan.gyro.positions, *plan.accel.positions]
    if has_gimbal:
        wanted += [positions[c] for c in GIMBAL_COLUMNS]
    all_names = header_names(lines[header_index])
    data = _parse_numbers(rows, row_lines, wanted, all_names, name)
    tname = all_names[plan.time]
    place = lambda i: f"{name}, line {int(row_lines[i])}, column {tname} (sample {i})"  # noqa: E731
    rate_line = f"{name}, line {key_lines.get('sample_rate_hz')}"
    time_s = _time_column(data[:, 0], rows, plan, tname, (meta, options, rate_line), allow_gaps, place)
    _fill_meta(meta, options, time_s, name, header_index + 1, (plan.time_name, all_names[plan.time]))
    own: dict[str, tuple[str, ...]] = {  # the file's own names, as messages name columns
        "time_s": (all_names[plan.time],),
        "dtheta_rad": tuple(all_names[i] for i in plan.gyro.positions),
        "dv_mps": tuple(all_names[i] for i in plan.accel.positions),
    }
    locate = _CsvLocator(name, key_lines, row_lines, own)
    check_meta(meta, locate)
    dt = 1.0 / meta_float(meta, "sample_rate_hz", name)
    counts = plan.gyro.is_counts or plan.accel.is_counts
    where = f"{name}, line {header_index + 1}"
    gyro, accel = (
        sensor_si(data[:, c], s, conversion, where) for c, s in ((_G, plan.gyro), (_A, plan.accel))
    )
    if conversion is not None and not counts:
        raise CalibError(
            "a conversion file is given, and no column is in raw counts",
            where,
            "leave out the conversion, or name the columns in counts (gyro_x_counts, accel_x_counts, ...)",
        )
    if counts and conversion is not None:  # sensor_si refused counts without one
        meta.update(conversion.meta())
    interval: float | np.ndarray = dt
    if (plan.gyro.is_rate or plan.accel.is_rate) and sampled_at_stamps(time_s, 1.0 / dt):
        interval = own_intervals(time_s)  # a polling logger: each rate over its own interval
    run = Run(
        time_s=time_s,
        dtheta_rad=np.ascontiguousarray(to_increments(gyro, plan.gyro, time_s, interval)),
        dv_mps=np.ascontiguousarray(to_increments(accel, plan.accel, time_s, interval)),
        meta=meta,
        gimbal_deg=np.ascontiguousarray(data[:, 7:10]) if has_gimbal else None,
        source=name,
        gyro_columns=tuple(zip(own["dtheta_rad"], plan.gyro.names, strict=True)),
        conversion=conversion if counts else None,
        clipped=clip_mask(
            sensor_clipping(data[:, _G], plan.gyro, conversion, dt, name),
            sensor_clipping(data[:, _A], plan.accel, conversion, dt, name),
            len(time_s),
        ),
    )
    # The clock the checks found goes with the run: clock.settle does not find it again.
    time_name = None if plan.time_name == COUNTER else plan.time_name
    return replace(run, clock=check_samples(run, locate, allow_gaps, time_name))


_G, _A = slice(1, 4), slice(4, 7)  # the gyro's and the accelerometer's columns in the parsed table


def _time_column(
    column, rows, plan: ColumnPlan, file_name: str, given, allow_gaps: bool, place
) -> np.ndarray:
    """The time in seconds of the time column, or of a sample counter at the stated rate.

    ``given`` is the file's metadata, the reader's options (``sample_rate_hz``
    from either) and the place of the metadata's rate; ``place(i)`` names row ``i``.
    A column in seconds that is a counter (steps of exactly 1 at a rate that is not
    1 Hz) is refused
    (:func:`calib.runlog.counter.counter_suspect`).
    """
    meta, options, key_place = given
    rate = options.get("sample_rate_hz")
    if rate is None and "sample_rate_hz" in meta:
        try:
            rate = float(meta["sample_rate_hz"])
        except ValueError:  # refused below naming its line (check_meta); a counter needs it now
            if plan.time_name == COUNTER:
                rate = meta_float(meta, "sample_rate_hz", key_place)
    if plan.time_name == COUNTER:
        return counter_time(column, rate, allow_gaps, place, file_name)
    time_s = time_in_seconds(column, rows, plan.time, plan.ticks_per_second, file_name, place, allow_gaps)
    suspect = counter_suspect(time_s, rate, file_name) if plan.time_name == "time_s" else None
    if suspect is not None:
        raise CalibError(suspect.what, place(1), suspect.fix)
    return time_s


def time_in_seconds(
    parsed: np.ndarray, rows: list[str], position: int, ticks: int, column: str, locate, allow_gaps=False
) -> np.ndarray:
    """The time column in seconds.

    ``parsed`` is the column as floats, ``rows`` the data rows, ``position`` the
    column's and ``ticks`` its unit's ticks per second; ``column`` its name and
    ``locate(i)`` row ``i``'s place, for the rollover's warning. Seconds stay as parsed.
    Integer stamps in ms, us or ns are split into whole seconds and the rest in
    integers first, so an epoch-sized stamp is not rounded as a float of ticks
    (to 256 ns) before the division rounds it again. A fixed-width tick clock that
    rolls over (a 32-bit ``micros()``) is counted on, a stamp garbled on the way mended under
    ``allow_gaps`` and refused otherwise (:mod:`calib.runlog.rollover`).
    """
    if ticks == 1:
        return np.ascontiguousarray(mended(parsed, allow_gaps, column, locate))
    try:
        stamps = np.loadtxt(rows, delimiter=",", comments=None, dtype=np.int64, usecols=[position], ndmin=1)
    except (ValueError, OverflowError):
        return mended(parsed, allow_gaps, column, locate) / ticks  # decimals: one division, correctly rounded
    stamps = said_rollover(mended(stamps, allow_gaps, column, locate), column, locate)
    whole, rest = np.divmod(stamps, ticks)
    return whole.astype(np.float64) + rest / ticks


def _fill_meta(
    meta: dict[str, str],
    options: dict,
    time_s: np.ndarray,
    name: str,
    header_line: int,
    time_column: tuple[str, str],
) -> None:
    """Site keys from options; for a logger's file (no format line) also format and rate.

    A file declaring ``imu-run/1`` keeps the contract of files.md: its sample rate
    must be written in it. A logger's file gets the rate from its time stamps
    (:func:`calib.runlog.clock.stamps_rate`; refused when the median step says the
    time column's unit is not its name's) and a
    message listing every key still missing, with an example preamble.
    ``time_column`` is the time column's name as read and the file's own name.
    """
    for key, value in options.items():
        if value is None:
            continue
        if key in meta:
            try:
                same = float(meta[key]) == float(value)
            except ValueError:
                same = False
            if not same:
                raise CalibError(
                    f"the file says {key} = {meta[key]} but the option gives {value:g}",
                    name,
                    "drop the option, or correct the file",
                )
            continue
        meta[key] = repr(float(value))
    if "format" in meta:
        return
    meta["format"] = FORMAT
    if "sample_rate_hz" not in meta and time_s.size >= 2:
        step = float(np.median(np.diff(time_s)))
        suspect = time_unit_suspect(step, time_column[0], time_s.size, file_name=time_column[1])
        if suspect is not None:
            raise CalibError(suspect.what, f"{name}, line {header_line}", suspect.fix)
        rate = stamps_rate(time_s)
        if rate > 0:
            # The stamps' own rate is the nominal one (docs/logs.md, the clock). Fitted over the run
            # it is good to ~1e-12; 12 digits keep its ppm and write a clean 100 Hz as 100.0.
            meta["sample_rate_hz"] = repr(float(f"{rate:.12g}"))
    missing = [k for k in REQUIRED_META[1:] if k not in meta]
    if missing:
        options_hint = {
            "latitude_deg": "latitude_deg (the CLI's --latitude DEG)",
            "height_m": "height_m (the CLI's --height M)",
            "sample_rate_hz": "a time column that increases",
        }
        raise CalibError(
            "the file lacks " + ", ".join(f"'{k}'" for k in missing),
            f"{name}, line {header_line}",
            "give " + ", ".join(options_hint[k] for k in missing) + ", or write them above the "
            "header, e.g. '# latitude_deg: 51.08', '# height_m: 1100', '# sample_rate_hz: 100'",
        )


def parse_preamble(lines: list[str], name: str) -> tuple[dict[str, str], dict[str, int], int]:
    """Collect ``# key: value`` lines up to the header row (``//`` lines are comments too).

    Returns
    -------
    meta : dict of str to str
        Metadata in file order.
    key_lines : dict of str to int
        1-based line of each key.
    header_index : int
        0-based index of the header row.
    """
    meta: dict[str, str] = {}
    key_lines: dict[str, int] = {}
    for index, line in enumerate(lines):
        stripped = line.strip()
        if not stripped:
            continue
        if not is_comment(stripped):
            return meta, key_lines, index
        if stripped.startswith("//"):
            continue  # a C-style logger's comment: its "key: value" lines are not ours
        key, colon, value = stripped[1:].partition(":")
        if not colon:
            continue  # a plain comment line
        key = key.strip()
        if not key:
            raise CalibError(
                "metadata line has no key before ':'", f"{name}, line {index + 1}", "write '# key: value'"
            )
        if key in meta:
            raise CalibError(
                f"metadata key '{key}' appears twice (first on line {key_lines[key]})",
                f"{name}, line {index + 1}",
                "keep one of the two lines",
            )
        meta[key] = value.strip()
        key_lines[key] = index + 1
    raise CalibError(
        "no header row after the metadata", name, "add the header row: " + ",".join(REQUIRED_COLUMNS)
    )


def _parse_header(
    line: str, line_number: int, name: str, mapping: dict[str, str]
) -> tuple[ColumnPlan, bool, dict[str, int]]:
    """The columns of the header row (:mod:`calib.runlog.columns`, column map applied) and the gimbal's."""
    where = f"{name}, line {line_number}"
    names = apply_column_map(header_names(line), mapping, where)
    plan = plan_columns(names, where)
    positions: dict[str, int] = {}
    for position, column in enumerate(names):
        if column in positions and column in GIMBAL_COLUMNS:
            raise CalibError(
                f"column '{column}' appears twice in the header", where, "keep one of the two columns"
            )
        positions.setdefault(column, position)
    gimbal = [c for c in GIMBAL_COLUMNS if c in positions]
    if gimbal and len(gimbal) < 3:
        absent = [c for c in GIMBAL_COLUMNS if c not in positions]
        raise CalibError(
            f"header row has gimbal column{'s' if len(gimbal) > 1 else ''} "
            f"{', '.join(gimbal)} but lacks {', '.join(absent)}",
            where,
            "give all three of " + ",".join(GIMBAL_COLUMNS) + " or none",
        )
    return plan, bool(gimbal), positions


def _data_rows(lines: list[str], first: int) -> tuple[list[str], np.ndarray]:
    """Non-blank lines after the header and their 1-based line numbers."""
    body = lines[first:]
    blank = [i for i, line in enumerate(body) if not line.strip()]
    if not blank:
        return body, np.arange(first + 1, first + 1 + len(body))
    keep = np.ones(len(body), dtype=bool)
    keep[blank] = False
    numbers = np.flatnonzero(keep) + first + 1
    return [line for line, k in zip(body, keep.tolist(), strict=True) if k], numbers


def _check_field_counts(
    rows: list[str], row_lines: np.ndarray, n_fields: int, name: str, allow_gaps: bool
) -> tuple[list[str], np.ndarray]:
    """The rows whose field count is the header's: others refused, or left out under ``allow_gaps``
    (a serial link's garbled rows; the time or counter column then shows the gap), said.
    """
    commas = np.fromiter((row.count(",") for row in rows), dtype=np.int64, count=len(rows))
    bad = np.flatnonzero(commas != n_fields - 1)
    if not bad.size:
        return rows, row_lines
    garbled = Garbled(name, allow_gaps)
    for i in bad:
        garbled.row(int(commas[i]) + 1, n_fields, "the header", int(row_lines[i]), int(i))
    garbled.said(True)
    keep = np.ones(len(rows), dtype=bool)
    keep[bad] = False
    return [row for row, kept in zip(rows, keep, strict=True) if kept], row_lines[keep]


def _parse_numbers(
    rows: list[str], row_lines: np.ndarray, wanted: list[int], names: list[str], name: str
) -> np.ndarray:
    """Parse the wanted columns as float64, fast; on failure find and name the bad field."""
    try:
        data = np.loadtxt(rows, delimiter=",", comments=None, dtype=np.float64, usecols=wanted, ndmin=2)
    except ValueError:
        data = None
    if data is not None and data.shape == (len(rows), len(wanted)):
        return data
    return _parse_numbers_slowly(rows, row_lines, wanted, names, name)


def _parse_numbers_slowly(
    rows: list[str], row_lines: np.ndarray, wanted: list[int], names: list[str], name: str
) -> np.ndarray:
    """Field-by-field parse: slow, but it can say exactly which field is bad."""
    data = np.empty((len(rows), len(wanted)))
    for i, row in enumerate(rows):
        fields = row.split(",")
        for j, position in enumerate(wanted):
            try:
                data[i, j] = float(fields[position])
            except ValueError:
                field = fields[position].strip()
                clockish = j == 0 and ":" in field and any(c.isdigit() for c in field)
                raise CalibError(
                    f"field {field!r} is not a number"
                    + (" nor a clock time this tool reads" if clockish else ""),
                    f"{name}, line {int(row_lines[i])}, column {names[position]} (sample {i})",
                    "write clock times as HH:MM:SS.fff or HH:MM:SS:fff (two digits each, a date as "
                    "YYYY-MM-DD before them), or seconds"
                    if clockish
                    else "write plain decimal numbers such as 1.5e-07",
                ) from None
    return data


def csv_meta(path) -> dict[str, str]:
    """The metadata of a CSV run log, from the lines above its header row only."""
    where = str(path)
    lines = []
    try:
        with open(path, encoding="utf-8") as handle:
            for line in handle:
                lines.append(line.rstrip("\r\n"))
                if line.strip() and not is_comment(line):
                    break  # the header row
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibError(f"cannot read the file ({exc})", where, f"give a UTF-8 {FORMAT} CSV") from None
    return parse_preamble(lines, where)[0]


def csv_chunks(path, rows: int):
    """Yield ``(time_s, dtheta_rad, dv_mps)`` blocks of ``rows`` samples, parsed a block at a time."""
    where = str(path)
    with open(path, encoding="utf-8") as handle:
        line = next(handle, "")
        while is_comment(line):
            line = next(handle, "")
        header = header_names(line)
        missing = [c for c in REQUIRED_COLUMNS if c not in header]
        if missing:
            raise CalibError(
                f"header lacks column(s) {', '.join(missing)}",
                where,
                f"name the columns as docs/formats.md ({FORMAT}) does",
            )
        use = [header.index(c) for c in REQUIRED_COLUMNS]
        done = 0
        while block := list(itertools.islice(handle, rows)):
            try:
                table = np.loadtxt(block, delimiter=",", usecols=use, ndmin=2)
            except ValueError as exc:
                raise CalibError(
                    f"unreadable data row among rows {done + 1}-{done + len(block)} ({exc})",
                    where,
                    "`seqdesign calibrate` names the line",
                ) from None
            done += len(block)
            yield table[:, 0], table[:, 1:4], table[:, 4:7]
