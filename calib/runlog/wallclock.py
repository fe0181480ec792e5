"""Time stamps written as wall-clock times: ``12:00:01.250``, ``2023-1-1 12:00:01.250`` or
``14-Nov-2023 12:00:01.250``, ``12:00:01:250``.

Some loggers (a PC tool saving what a serial IMU sends) stamp each row with the host's
clock time instead of a number. Such a column is turned into seconds from the first
stamp's midnight, before the numbers are parsed; the clock (:mod:`calib.runlog.clock`)
then reads it as any host's stamps. A date, when written, carries the run over midnight;
without one, a stamp more than 12 hours before the last is the next day.
"""

from __future__ import annotations

import dataclasses
import datetime
import re
import warnings

import numpy as np

from calib.errors import CalibError

# [date separator] hours:minutes:seconds[.fraction][zone]; the fraction's separator may be a
# comma (a locale's decimal comma). The date is year-month-day with -, / or . between. A zone
# (ISO 8601's Z or +01:00) must be the same on every row: a log's stamps share one clock. Three
# digits after a third colon are milliseconds (Physics Toolbox's 23:13:20:030; a video
# timecode's frames are two).
# Or day-month's name-year, as MATLAB's datetime writes by default (14-Nov-2023 22:13:20.030).
CLOCK_FORM = (
    r"(?:(?:(?P<y>\d{4})[-/.](?P<mo>\d{1,2})[-/.](?P<d>\d{1,2})"
    r"|(?P<d2>\d{1,2})[- ](?P<mon>[A-Za-z]{3})[- ](?P<y2>\d{4}))[ T_]+)?"
    r"(?P<h>\d{1,2}):(?P<mi>\d{2}):(?P<s>\d{2}(?:[.,]\d+|:\d{3})?)(?P<zone>Z|[+-]\d{2}:?\d{2})?"
)  # a clock time as it stands in a field (dialect finds it among a print's text)
CLOCK_TIME = re.compile(r"^\s*" + CLOCK_FORM + r"\s*$")
MONTHS = ("jan", "feb", "mar", "apr", "may", "jun", "jul", "aug", "sep", "oct", "nov", "dec")
DAY_S = 86_400.0


def is_clock_time(text: str) -> bool:
    """Whether a field is a wall-clock time (with or without a date)."""
    return CLOCK_TIME.match(text) is not None


def clock_seconds(fields: list[str], locate) -> list[float]:
    """Seconds from the first stamp's midnight of each wall-clock field.

    ``locate(i)`` names row ``i`` for a field that is no clock time.
    """
    out: list[float] = []
    first_day = None
    day_shift = 0.0
    was_dated = False
    zone = None
    for i, text in enumerate(fields):
        m = CLOCK_TIME.match(text)
        if m is None:
            raise CalibError(
                f"field {text.strip()!r} is no clock time like the first rows' (HH:MM:SS.fff)",
                locate(i),
                "write every time stamp the same way",
            )
        dated = m["y"] is not None or m["y2"] is not None
        if out and dated != was_dated:
            raise CalibError(
                f"field {text.strip()!r} is written {'with' if dated else 'without'} a date, the first rows "
                f"{'with' if was_dated else 'without'}",
                locate(i),
                "write every time stamp the same way, with its date or without",
            )
        was_dated = dated
        if i == 0:
            zone = m["zone"]
        elif m["zone"] != zone:
            raise CalibError(
                f"field {text.strip()!r} is in another time zone than the first row's ({zone or 'none'})",
                locate(i),
                "write every time stamp in one zone",
            )
        fraction = m["s"].replace(",", ".").replace(":", ".")
        seconds = int(m["h"]) * 3600.0 + int(m["mi"]) * 60.0 + float(fraction)
        if dated:
            try:
                day = _date(m).toordinal()
            except ValueError:
                raise CalibError(
                    f"field {text.strip()!r} has no such date", locate(i), "write a real date"
                ) from None
            first_day = day if first_day is None else first_day
            seconds += (day - first_day) * DAY_S
        elif out and seconds + day_shift < out[-1] - DAY_S / 2:
            day_shift += DAY_S  # past midnight, no date to say so
        out.append(seconds + day_shift)
    return out


def _date(m: re.Match) -> datetime.date:
    """The date of a matched stamp, either form (ValueError for no such date or month)."""
    if m["y"] is not None:
        return datetime.date(int(m["y"]), int(m["mo"]), int(m["d"]))
    return datetime.date(int(m["y2"]), MONTHS.index(m["mon"].lower()) + 1, int(m["d2"]))


def fields_in_seconds(rows: list[str], position: int, locate) -> list[str] | None:
    """The rows with their wall-clock field at ``position`` written in seconds (None: no clock)."""
    first = rows[0].split(",") if rows else []
    if position >= len(first) or not is_clock_time(first[position]):
        return None
    split = [row.split(",") for row in rows]
    seconds = clock_seconds([f[position] for f in split], locate)
    for fields, s in zip(split, seconds, strict=True):
        fields[position] = repr(s)
    return [",".join(f) for f in split]


def with_seconds(rows: list[str], position: int, plan, locate):
    """The rows with a wall-clock time column written in seconds, and the plan reading it so.

    Rows whose first time field is a number are returned as they are. ``plan`` is the
    header's :class:`calib.runlog.columns.ColumnPlan`; its time is then ``time_s``.
    """
    if not rows or plan.time_name == "counter":
        return rows, plan
    in_seconds = fields_in_seconds(rows, position, locate)
    if in_seconds is None:
        return rows, plan
    return in_seconds, dataclasses.replace(plan, time_name="time_s")


# A stamp in two columns: whole seconds and the part of the second in ns, us or ms (ROS 2's
# builtin_interfaces/Time, as `ros2 topic echo --csv` writes a header's stamp: sec,nanosec).
SUB_SECOND = {"time_ns": 1_000_000_000, "time_us": 1_000_000, "time_ms": 1_000}
SPLIT_FIX = (
    "where the fraction is in another column, map both (sec=time_s,nanosec=time_ns, ROS 2's); where it "
    "is not written, leave the time out of the map and state the rate (the CLI's --sample-rate-hz)"
)


def split_stamp_suspect(time_s: np.ndarray) -> str | None:
    """Why a time column looks like one half of a stamp written in two columns, or None.

    Whole seconds alone step by 0 most rows and 1 once a second; the fraction alone restarts
    every second (a step back of nearly 1 s).
    """
    if len(time_s) < 3:
        return None
    step = np.diff(time_s)
    if np.all(time_s == np.rint(time_s)) and np.median(step) == 0.0 and np.all((step == 0.0) | (step == 1.0)):
        return (
            f"the time column holds whole seconds only ({len(time_s)} rows in {time_s[-1] - time_s[0]:.0f} s)"
        )
    back = step < 0.0
    if back.sum() >= 2 and np.all(time_s >= 0.0) and np.all(time_s < 1.0) and np.all(step[back] < -0.5):
        return f"the time column stays below 1 s and restarts every second ({int(back.sum())} times)"
    return None


def with_split_stamp(lines: list[str], header_index: int, mapping: dict[str, str], name: str, added: int = 0):
    """The rows with a stamp written in two columns put into one, and the map reading it so.

    ``mapping`` maps one column to ``time_s`` (whole seconds) and another to ``time_ns``,
    ``time_us`` or ``time_ms`` (the part of the second): each row's seconds field becomes the
    whole stamp in that unit, an exact integer, and the fraction's column is left unread.
    Lines are comma-separated, the header at ``header_index``; ``added`` lines were put in above
    the rows (a header for a file without one). Returns ``(lines, mapping)``.
    """
    seconds = [k for k, v in mapping.items() if v == "time_s"]
    parts = [(k, v) for k, v in mapping.items() if v in SUB_SECOND]
    if len(seconds) != 1 or len(parts) != 1:
        return lines, mapping
    (part, unit), names = parts[0], [n.strip().strip('"') for n in lines[header_index].split(",")]
    if seconds[0] not in names or part not in names:
        return lines, mapping
    i, j, ticks = names.index(seconds[0]), names.index(part), SUB_SECOND[unit]
    out = list(lines[: header_index + 1])
    for k in range(header_index + 1, len(lines)):
        row = lines[k]
        if not row.strip() or row.lstrip().startswith(("#", "//")):
            out.append(row)
            continue
        fields = row.split(",")
        try:
            whole, sub = int(fields[i]), int(fields[j])
        except (ValueError, IndexError):
            whole, sub = None, -1
        if whole is None or not 0 <= sub < ticks:
            raise CalibError(
                f"a stamp in two columns ('{seconds[0]}' seconds, '{part}' {unit.removeprefix('time_')}) "
                f"needs whole numbers, the second below {ticks}: the row has "
                f"{fields[i] if i < len(fields) else ''!r}, {fields[j] if j < len(fields) else ''!r}",
                f"{name}, line {k + 1 - added}",
                "map the stamp's two columns as its seconds and their fraction, or one time column",
            )
        fields[i] = str(whole * ticks + sub)
        out.append(",".join(fields))
    warnings.warn(
        f"{name}: the time from two columns, '{seconds[0]}' (s) and '{part}' ({unit.removeprefix('time_')}), "
        "read as one stamp",
        stacklevel=3,
    )
    return out, {k: (unit if k == seconds[0] else v) for k, v in mapping.items() if k != part}
