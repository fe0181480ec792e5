"""A text log without a header row: columns named by position, samples evenly spaced.

Some loggers write one row of numbers per sample and nothing else (mikoff's
imu-calib logs: ``ax ay az wx wy wz``, space separated, no time). A file whose
first row after its ``#`` lines is all numbers has no header; its columns are
then named by position, ``1`` to ``N``, in the column map
(``1=accel_x_mps2,2=accel_y_mps2,...``). Fields may be separated by commas,
semicolons or white space (spaces and tabs, any number).

When the map names no time column (``time_*``) and no ``counter``, the samples
are taken as evenly spaced at the stated rate: a counter ``0, 1, 2, ...`` is
added, so that sample ``i`` ends its interval at ``(i + 1) / sample_rate_hz``
(:mod:`calib.runlog.counter`). The rate must then be stated
(``sample_rate_hz``, the CLI's ``--sample-rate-hz``, or a
``# sample_rate_hz:`` line): a file without a time says nothing of it. A file with
a header row that names no time (an Arduino sketch's ``ax,ay,az,gx,gy,gz``) is read
the same way when the rate is stated (`with_row_counter`).
"""

from __future__ import annotations

import re
import warnings

import numpy as np

from calib.errors import CalibError

from .columns import COUNTER, TIME_NAMES, apply_column_map, known_name
from .counter import RATE_FIX
from .text import header_names, is_comment
from .wallclock import is_clock_time

EXAMPLE_MAP = "1=accel_x_mps2,2=accel_y_mps2,3=accel_z_mps2,4=gyro_x_radps,5=gyro_y_radps,6=gyro_z_radps"


# A date and its time written with white space between (2023-1-1 12:00:00.000): one field.
_DATE_TIME = re.compile(r"(\d{4}[-/.]\d{1,2}[-/.]\d{1,2})\s+(\d{1,2}:\d{2}:\d{2})")


def _fields(line: str) -> list[str]:
    """The fields of a data row, split on commas, else semicolons, else white space."""
    s = _DATE_TIME.sub(r"\1T\2", line.strip())
    for sep in (",", ";"):
        if sep in s:
            return [f.strip() for f in s.split(sep)]
    return s.split()


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def is_headerless(line: str, following: str | None = None) -> bool:
    """Whether the first non-comment row ``line`` is data (numbers, a time may be a clock's), not a header.

    A field that is no number is a tag when ``following``, the next row, has the same text
    in the same place: an Arduino sketch's ``a/g:`` before every row's numbers is no name.
    """
    fields = _fields(line)
    data = [_is_number(f) or is_clock_time(f) for f in fields]
    if fields and all(data):
        return True
    after = _fields(following) if following is not None else []
    return (
        sum(data) >= 3
        and len(after) == len(fields)
        and all(d or f == a for d, f, a in zip(data, fields, after, strict=True))
    )


def _no_header(lines: list[str], header_index: int) -> bool:
    """`is_headerless` of the first row that is no comment, judged with the row after it."""
    following = next((line for line in lines[header_index + 1 :] if line.strip()), None)
    return is_headerless(lines[header_index], following)


_SENSORS = {"gyro": "gyro", "dtheta": "gyro", "accel": "accelerometer", "dv": "accelerometer"}


def _check_sensors(mapping: dict[str, str], n: int, where: str) -> None:
    """Refuse a map of a file without header that leaves a sensor's axis unnamed, in its terms."""
    axes: dict[str, set[str]] = {"gyro": set(), "accelerometer": set()}
    for target in mapping.values():
        parts = target.split("_")
        if parts[0] in _SENSORS and len(parts) > 1:
            axes[_SENSORS[parts[0]]].add(parts[1])
    short = [f"the {s} on {len(a)} of 3 axes" for s, a in axes.items() if len(a) < 3]
    if short:
        raise CalibError(
            "the column map names " + " and ".join(short) + f"; the file has no header row, so each of "
            f"its {n} columns is named by its position",
            where,
            f"map the gyro's and the accelerometer's three axes by position, e.g. {EXAMPLE_MAP}",
        )


def with_header(
    lines: list[str],
    header_index: int,
    mapping: dict[str, str],
    meta: dict,
    options: dict,
    name: str,
    allow_gaps: bool = False,
) -> tuple[list[str], int]:
    """The file's lines with a header row of positions put in, when it has none.

    Parameters
    ----------
    lines : list of str
        The file's lines; ``lines[header_index]`` is its first row that is no ``#`` line.
    header_index : int
    mapping : dict of str to str
        The column map (:func:`calib.runlog.columns.parse_column_map`).
    meta : dict
        The metadata above the rows (a ``sample_rate_hz`` there states the rate).
    options : dict
        The reader's options (``sample_rate_hz``).
    name : str
        The file, for messages.
    allow_gaps : bool
        Leave out a row of the wrong width as lost samples (:class:`Garbled`), else refuse it.

    Returns
    -------
    lines : list of str
        Unchanged for a file with a header; else the rows rewritten with commas
        (and a counter field when the map gives no time), under a header row
        ``1,2,...,N[,counter]`` inserted at ``header_index``.
    added : int
        1 when a header row was inserted (the file's line numbers of the rows
        are one less than their index + 1), else 0.

    Raises
    ------
    CalibError
        For a file without a header: no column map, a map naming other than the
        positions ``1..N``, or no time column and no stated rate.
    """
    first = lines[header_index]
    if not _no_header(lines, header_index):
        return lines, 0
    n = len(_fields(first))
    where = f"{name}, line {header_index + 1}"
    if not mapping:
        raise CalibError(
            f"the file has no header row (its first row is {n} numbers)",
            where,
            f"name its columns by position 1..{n} in a column map (the CLI's --columns), e.g. {EXAMPLE_MAP}",
        )
    positions = [str(i) for i in range(1, n + 1)]
    wrong = [k for k in mapping if k not in positions]
    if wrong:
        later = next(
            (
                k
                for k in range(header_index + 1, min(len(lines), header_index + 50))
                if set(wrong) <= set(_fields(lines[k]))
            ),
            None,
        )
        if later is not None:  # rows of numbers above the names: samples before a header?
            raise CalibError(
                "column map names " + ", ".join(f"'{k}'" for k in wrong) + f", which line {header_index + 1} "
                f"(a row of numbers) does not have; they are on line {later + 1}",
                where,
                f"put '#' before the {later - header_index} line(s) above line {later + 1} (the header row "
                "is the first line not starting with '#' or '//')",
            )
        raise CalibError(
            "column map names " + ", ".join(f"'{k}'" for k in wrong) + f", and the file has no header row: "
            f"its columns are named by position, 1 to {n}",
            where,
            f"map positions, e.g. {EXAMPLE_MAP}",
        )
    _check_sensors(mapping, n, where)
    timed = any(v in TIME_NAMES or v == COUNTER for v in mapping.values())
    if not timed and options.get("sample_rate_hz") is None and "sample_rate_hz" not in meta:
        raise CalibError(
            "the file has no time column, so its samples are taken as evenly spaced at the IMU's rate, "
            "which is not stated",
            where,
            RATE_FIX,
        )
    body, count, garbled = [], 0, Garbled(name, allow_gaps)
    for index, line in enumerate(lines[header_index:], start=header_index):
        if not line.strip():
            body.append(line)
            continue
        fields = _fields(line)
        if len(fields) != n:
            count += garbled.row(len(fields), n, "the first row", index + 1, count)
            body.append("")  # the line kept blank: every later row keeps its line number
            continue
        if not timed:
            fields.append(str(count))
            count += 1
        body.append(",".join(fields))
    garbled.said(timed)
    header = ",".join(positions + ([] if timed else [COUNTER]))
    return lines[:header_index] + [header] + body, 1


class Garbled:
    """Rows of the wrong width in a serial logger's file (bytes lost on the wire), left out as lost
    samples under ``allow_gaps`` and said once; refused otherwise.

    A short row is one sample lost; a long one (a line end lost, two rows run together) as many as
    its fields fill rows. Where the rows are counted (no time column), the count steps over them,
    so that the gap is one the clock's rules see: filled at rest, the move it falls in left out.
    """

    def __init__(self, name: str, allow_gaps: bool):
        self.name, self.allow_gaps = name, allow_gaps
        self.lines: list[int] = []

    def row(self, have: int, want: int, what: str, line: int, sample: int) -> int:
        """Samples the row at ``line`` stands for (it is left out); refused without ``allow_gaps``."""
        if not self.allow_gaps:
            raise CalibError(
                f"row has {have} fields, {what} has {want}",
                f"{self.name}, line {line} (sample {sample})",
                "every row needs one value per column; a logger that lost bytes mid-row: allow_gaps "
                "(the CLI's --allow-gaps) leaves such rows out as lost samples",
            )
        self.lines.append(line)
        return max(1, -(-have // want))

    def said(self, timed: bool) -> None:
        if not self.lines:
            return
        shown = ", ".join(str(k) for k in self.lines[:5]) + (", ..." if len(self.lines) > 5 else "")
        warnings.warn(
            f"{self.name}: {len(self.lines)} row(s) of the wrong width (line(s) {shown}) left out as lost "
            + ("samples (their stamps show the gap)" if timed else "samples (the count steps over them)"),
            stacklevel=3,
        )


def by_commented_names(
    lines: list[str], header_index: int, mapping: dict[str, str], name: str
) -> dict[str, str]:
    """The map by position when its names are those of a comment line right above the rows.

    ``# time ax ay az gx gy gz`` (numpy's ``savetxt`` header, MATLAB's ``% t ax ...``) names the
    columns in a comment; a map that names them is read by their positions there, said on stderr.
    """
    if not mapping or header_index == 0 or not _no_header(lines, header_index):
        return mapping
    n = len(_fields(lines[header_index]))
    if all(k in {str(i) for i in range(1, n + 1)} for k in mapping):
        return mapping
    above = lines[header_index - 1].strip()
    if not is_comment(above):
        return mapping
    text = above.lstrip("#/% \t")
    names = [f.strip() for f in re.split(r"[,;\t]" if re.search(r"[,;\t]", text) else r"\s+", text)]
    # A map may name the first column as the file writes it, mark and all ("#timestamp [ns]": EuRoC).
    mapping = {
        (k.lstrip("#/% ") if k not in names and k.lstrip("#/% ") in names else k): v
        for k, v in mapping.items()
    }
    if len(names) != n or not all(k in names for k in mapping):
        return mapping
    warnings.warn(
        f"{name}, line {header_index}: the columns are named in this comment line; read by their positions",
        stacklevel=4,
    )
    return {str(names.index(k) + 1): v for k, v in mapping.items()}


def with_row_counter(
    lines: list[str],
    header_index: int,
    names: list[str],
    rate_stated: bool,
    name: str = "<memory>",
    allow_gaps: bool = False,
    inserted: int = 0,
) -> list[str]:
    """A file whose header row names no time, with a counter field added when the rate is stated.

    ``names`` are the header's names with the column map applied. Without a stated rate the
    lines are returned as they are (the header's check then says what is missing). A column
    left out of the map that increases row by row is a time the map forgot: refused, since
    evenly spaced rows would hide the gaps its stamps show. ``inserted`` lines were put in above
    the rows (a header made for ``label:value`` rows): the file's line numbers are that many less.
    """
    if not rate_stated or any(n in TIME_NAMES or n.lower() in TIME_NAMES or n == COUNTER for n in names):
        return lines
    _refuse_an_unmapped_time(lines, header_index, names, name)
    body, count, width, garbled = [], 0, len(names), Garbled(name, allow_gaps)
    for k, line in enumerate(lines[header_index + 1 :], start=header_index + 2 - inserted):
        if line.strip():
            if line.count(",") != width - 1:  # said before the counter adds a field of its own
                count += garbled.row(line.count(",") + 1, width, "the header", k, count)
                body.append("")
                continue
            line = f"{line.rstrip()},{count}"
            count += 1
        body.append(line)
    garbled.said(False)
    return lines[:header_index] + [lines[header_index].rstrip() + "," + COUNTER] + body


ROWS_JUDGED = 1000  # rows read to tell a time column the map left out (it increases on every one)


# Names a logger gives its time column (letters only, lower case).
TIME_WORDS = {
    "t",
    "time",
    "timestamp",
    "timestamps",
    "stamp",
    "ts",
    "sec",
    "secs",
    "seconds",
    "ms",
    "millis",
    "us",
}
INCREASING = 0.5  # never down and up on this share of rows: a time (a sensor's noise goes down half the time)


def _looks_like_time(name: str, fields: list[str]) -> bool:
    """A column named like a time, written as clock times, or counting up row by row; not one
    that never changes (a sensor not fitted, all zeros: `uS1`, an ultrasonic one, reads "us").
    """
    try:
        values = np.array([float(f) for f in fields])
    except ValueError:
        values = None
    if values is not None and len(values) >= 2 and np.all(values == values[0]):
        return False
    if "".join(c for c in name.lower() if c.isalpha()) in TIME_WORDS:
        return True
    if len(fields) >= 3 and all(is_clock_time(f) for f in fields):
        return True
    if values is None:
        return False
    steps = np.diff(values)
    return len(steps) >= 2 and bool(np.all(steps >= 0.0)) and float(np.mean(steps > 0.0)) >= INCREASING


def _refuse_an_unmapped_time(lines: list[str], header_index: int, names: list[str], name: str) -> None:
    rows = [
        line.split(",") for line in lines[header_index + 1 : header_index + 1 + ROWS_JUDGED] if line.strip()
    ]
    for i in (i for i, n in enumerate(names) if not known_name(n)):
        fields = [r[i] for r in rows if i < len(r)]
        if _looks_like_time(names[i], fields):
            raise CalibError(
                f"column '{names[i]}' looks like a time (by its name or its rows), and the map names no time",
                f"{name}, line {header_index + 1}",
                f"map it as the time ({names[i]}=time_s, time_ms, time_us or time_ns) or as a sample counter "
                f"({names[i]}=counter)",
            )


def mapped_header(lines: list[str], header_index: int, mapping: dict[str, str], name: str) -> list[str]:
    """The header row's names with the map applied.

    A map that names a later line's columns is told which line holds them (a logger's own
    preamble, ``Fs,100``, above its header row).
    """
    where = f"{name}, line {header_index + 1}"
    try:
        return apply_column_map(header_names(lines[header_index]), mapping, where)
    except CalibError as exc:
        for k in range(header_index + 1, min(len(lines), header_index + 50)):
            if mapping and all(
                key in header_names(lines[k].replace(";", ",").replace("\t", ",")) for key in mapping
            ):
                raise CalibError(
                    exc.what + f"; they are on line {k + 1}",
                    where,
                    f"put '#' before the {k - header_index} line(s) above line {k + 1} (the header row "
                    "is the first line not starting with '#' or '//')",
                ) from None
        raise
