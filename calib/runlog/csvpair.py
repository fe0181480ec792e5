"""Two CSV files, one per sensor: a logger that writes the gyro and the accelerometer apart.

A phone's sensor logger, a camera's IMU driver or a bag exported topic by topic
writes each sensor to its own file, each with its own header, rate and stamps::

    Gyroscope.csv       time_ns,gyro_x_radps,gyro_y_radps,gyro_z_radps
    Accelerometer.csv   time_ns,accel_x_mps2,accel_y_mps2,accel_z_mps2

Each header follows the column grammar (:mod:`calib.runlog.columns`; one column map
serves both files, each name found in one of them), each file holds its time and
its one sensor, and each is read on its own clock: the accelerometer's increments
are carried onto the gyro's samples (:mod:`calib.runlog.streams`). imu_tk's
headerless text files take the other road (:mod:`calib.runlog.imutk`).
"""

from __future__ import annotations

import os

import numpy as np

from calib.errors import CalibError

from .checks import check_meta
from .clipping import sensor_clipping
from .clock import stamps_rate
from .columns import (
    COUNTER,
    SENSOR_WORDS,
    TIME_UNITS,
    SensorColumns,
    apply_column_map,
    column_map_pairs,
    plan_one_sensor,
    sensor_of,
)
from .conversion import Conversion, sensor_si
from .csv import (
    _check_field_counts,
    _data_rows,
    _fill_meta,
    _parse_numbers,
    header_names,
    parse_preamble,
    time_in_seconds,
)
from .dialect import past_preamble, to_commas, unquoted, without_repeated_headers, without_units_row
from .loggers import known_sensor_map
from .paths import read_bytes
from .run import Run
from .streams import Stream, two_clocks
from .text import decode_lines, is_comment, without_cut_last_row
from .wallclock import fields_in_seconds

_SITE = ("latitude_deg", "height_m")


def has_header(path: str | os.PathLike) -> bool:
    """Whether a text file's first row that is no comment names its columns (a field not a number)."""
    lines = decode_lines(read_bytes(path), str(path))
    for line in lines:
        stripped = line.strip()
        if not stripped or is_comment(stripped) or stripped[0] == "%":
            continue
        return has_header_text(stripped)
    return False


def has_header_text(row: str) -> bool:
    """Whether a row names columns: a field of it is not a number."""
    for field in row.replace(";", ",").replace("\t", ",").replace(" ", ",").split(","):
        if not field:
            continue
        try:
            float(field)
        except ValueError:
            return True
    return False


def sensor_maps(columns: str | dict[str, str] | None, where: str) -> dict[str, dict[str, str]]:
    """One column map split into each file's: ``{"accel": {...}, "gyro": {...}}``.

    A name mapped to a sensor's column goes to that sensor's file alone, so both files may call
    their axes ``x, y, z`` (``x=gyro_x_radps,x=accel_x_mps2``, as a phone's logger writes them);
    the time and other names go to both. A name mapped twice for one file is refused.
    """
    maps: dict[str, dict[str, str]] = {"accel": {}, "gyro": {}}
    for source, target in column_map_pairs(columns, where):
        sensor = sensor_of(target)
        for name in (sensor,) if sensor else ("accel", "gyro"):
            if source in maps[name]:
                raise CalibError(
                    f"column map names the {SENSOR_WORDS[name]} file's column '{source}' twice",
                    where,
                    "map each file's column once (a name may come twice only as one gyro and one "
                    "accelerometer column)",
                )
            maps[name][source] = target
    return maps


def sensor_of_any(names: list[str], sensor: str) -> bool:
    """Whether any of a header's (mapped) names is one of ``sensor``'s columns."""
    return any(sensor_of(n) == sensor for n in names)


def _positions_header(lines: list[str], header_index: int, mapping: dict[str, str]) -> tuple[list[str], int]:
    """A file without a header, mapped by position (OpenCamera's ``x,y,z,timestamp_ns`` rows),
    with a header of its positions put in: ``(lines, 1)``; else ``(lines, 0)``.
    """
    first = lines[header_index].strip() if header_index < len(lines) else ""
    if not mapping or not all(k.isdigit() for k in mapping) or not first or has_header_text(first):
        return lines, 0
    sep = next((c for c in (",", ";", "\t") if c in first), " ")
    n = len(first.split(sep)) if sep != " " else len(first.split())
    return lines[:header_index] + [sep.join(str(i) for i in range(1, n + 1))] + lines[header_index:], 1


class _SensorFile:
    """One sensor's file as read: its metadata and where its keys are, the stream, its rate."""

    def __init__(
        self,
        path,
        sensor: str,
        mapping: dict[str, str],
        conversion: Conversion | None,
        rate_hz=None,
        allow_gaps: bool = False,
    ):
        self.name = name = str(path)
        lines = without_cut_last_row(decode_lines(read_bytes(path), name), name)
        self.meta, self.key_lines, header_index = parse_preamble(lines, name)
        # A sep= line, or a logger's preamble above the header: found by this sensor's own mapped
        # names (the time's and other names may be another file's spelling).
        own_names = {k: v for k, v in mapping.items() if sensor_of(v) == sensor}
        header_index = past_preamble(lines, header_index, own_names, name)
        lines, added = _positions_header(lines, header_index, mapping)
        lines = without_units_row(lines, header_index, name)
        lines = without_repeated_headers(unquoted(lines, header_index, name), header_index, name)
        lines = to_commas(lines, header_index, name)
        self.header_line = header_index + 1
        where = f"{name}, line {self.header_line}"
        own = header_names(lines[header_index])
        mapping = mapping or known_sensor_map(own, sensor, name)  # phyphox's
        names = apply_column_map(own, {k: v for k, v in mapping.items() if k in own}, where)
        self.used = set(mapping) & set(own)
        try:
            time_at, self.time_name, columns = plan_one_sensor(names, sensor, where)
        except CalibError as exc:
            if not added or sensor_of_any(names, sensor):
                raise
            n = len(own)
            raise CalibError(  # a map by position names each file's positions: this one's are not
                f"the {SENSOR_WORDS[sensor]}'s file has no header row and the column map names none of "
                f"its {n} positions as the {SENSOR_WORDS[sensor]}'s",
                where,
                "map its positions too: one map serves both files, a position for each "
                + (
                    "(e.g. 2=gyro_x_radps,3=gyro_y_radps,4=gyro_z_radps beside 2=accel_x_mps2,...)"
                    if sensor == "gyro"
                    else "(e.g. 2=accel_x_mps2,3=accel_y_mps2,4=accel_z_mps2 beside 2=gyro_x_radps,...)"
                ),
            ) from exc
        if self.time_name == COUNTER:
            raise CalibError(
                "a sample counter gives no time, and two files are put on one time by their stamps",
                where,
                "give each file its time column (time_s, time_ms, time_us or time_ns)",
            )
        rows, self.row_lines = _data_rows(lines, header_index + 1)
        self.row_lines = self.row_lines - added  # the file's own line numbers
        if len(rows) < 2:
            raise CalibError("the file has fewer than two data rows", where, "give the sensor's samples")
        rows, self.row_lines = _check_field_counts(rows, self.row_lines, len(own), name, allow_gaps)
        at = lambda i: f"{name}, line {int(self.row_lines[i])}"  # noqa: E731
        in_seconds = fields_in_seconds(rows, time_at, at)  # a time column of clock times
        if in_seconds is not None:
            rows, self.time_name = in_seconds, "time_s"
        data = _parse_numbers(rows, self.row_lines, [time_at, *columns.positions], own, name)
        self.time_own_name = own[time_at]
        ticks = TIME_UNITS[self.time_name.removeprefix("time_")]
        self.time_s = time_in_seconds(data[:, 0], rows, time_at, ticks, own[time_at], at, allow_gaps)
        # The gyro's increments become rates over the rate the run is given (a stated one),
        # the accelerometer's over its stamps' own.
        period = 1.0 / (rate_hz or stamps_rate(self.time_s))
        raw = data[:, 1:]
        self.values = _si_rate(sensor_si(raw, columns, conversion, where), columns, period)
        self.clipped = sensor_clipping(raw, columns, conversion, period, name)
        self.counts = columns.is_counts
        x, y, z = (own[i] for i in columns.positions)
        self.own_columns = (own[time_at], x, y, z)

    def stream(self) -> Stream:
        return Stream(self.name, self.time_s, self.row_lines, self.values, self.clipped, self.own_columns)


def _si_rate(values: np.ndarray, columns: SensorColumns, period: float) -> np.ndarray:
    """Rates (rad/s, m/s^2) from a sensor's columns (counts already in SI), rates or increments
    over its period.
    """
    si = values * np.asarray(columns.si_per_unit)
    return si if columns.is_rate else si / period


def read_csv_pair(
    acc_path: str | os.PathLike,
    gyro_path: str | os.PathLike,
    allow_gaps: bool,
    options: dict,
    columns: str | dict[str, str] | None,
    conversion: Conversion | None,
) -> Run:
    """Read a logger's accelerometer and gyro CSV files into one run on the gyro's clock.

    Parameters
    ----------
    acc_path, gyro_path : str or os.PathLike
        The two files (gzip-compressed or not), each a header row, then its time and
        its sensor's three axes (module docstring).
    allow_gaps : bool
        Fill samples either file lost at rest (`calib.runlog.clock.settle`).
    options : dict
        ``latitude_deg``, ``height_m`` and ``sample_rate_hz`` (the gyro's; default: its
        stamps' rate) for files that do not state them.
    columns : str or dict, optional
        One column map for both files; each name must be in one of them.
    conversion : Conversion, optional
        For columns in raw counts.

    Returns
    -------
    Run
        With ``meta["streams"]`` saying how the two were put together.

    Raises
    ------
    CalibError
        On a file that does not hold its sensor alone with a time, site keys the two
        files state differently, or files with no common time.
    """
    maps = sensor_maps(columns, f"{acc_path}; {gyro_path}")
    acc = _SensorFile(acc_path, "accel", maps["accel"], conversion, allow_gaps=allow_gaps)
    gyro = _SensorFile(gyro_path, "gyro", maps["gyro"], conversion, options.get("sample_rate_hz"), allow_gaps)
    unused = sorted({*maps["accel"], *maps["gyro"]} - acc.used - gyro.used)
    if unused:
        raise CalibError(
            "column map names " + ", ".join(f"'{k}'" for k in unused) + ", which neither file's header has",
            f"{acc.name}; {gyro.name}",
            "map the names the two header rows give (column names are case-sensitive)",
        )
    if conversion is not None and not (acc.counts or gyro.counts):
        raise CalibError(
            "a conversion file is given, and no column is in raw counts",
            f"{acc.name}; {gyro.name}",
            "leave out the conversion, or name the columns in counts (gyro_x_counts, accel_x_counts, ...)",
        )
    meta = dict(gyro.meta)
    for key in _SITE:
        if key in acc.meta and key in meta and acc.meta[key] != meta[key]:
            raise CalibError(
                f"the accelerometer's file says {key} = {acc.meta[key]} and the gyro's {meta[key]}",
                f"{acc.name}, line {acc.key_lines[key]}; {gyro.name}, line {gyro.key_lines[key]}",
                "correct the one that is wrong",
            )
        if key in acc.meta:
            meta.setdefault(key, acc.meta[key])
    _fill_meta(meta, options, gyro.time_s, gyro.name, gyro.header_line, (gyro.time_name, gyro.time_own_name))
    check_meta(meta, _Place(gyro.name))
    if conversion is not None:
        meta.update(conversion.meta())
    run = two_clocks(acc.stream(), gyro.stream(), meta, allow_gaps)
    run.conversion = conversion
    return run


class _Place:
    """Names a metadata key's place for :func:`calib.runlog.checks.check_meta`."""

    def __init__(self, name: str):
        self.name = name

    def key(self, key: str) -> str:
        return f"{self.name} (metadata '{key}')"

    def sample(self, array: str, index: int, component: int | None = None) -> str:
        return f"{self.name} (sample {index})"
