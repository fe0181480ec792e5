"""Intel RealSense motion logs: one file, a block of rows per stream (the gyro's, the accelerometer's).

librealsense's tools write a camera's IMU to one CSV of blocks, each a header row
``Stream Type,...`` and the rows of one stream, keyed by its first field
(``Gyro``, ``Accel``; a camera's ``Depth``, ``Color``... blocks are passed over)::

    rs-data-collect   Stream Type,Index,F#,HW Timestamp (ms),Host Timestamp(ms),3DOF_x,3DOF_y,3DOF_z
    rs-convert -v     Stream Type,F#,HW Timestamp (ms),Backend Timestamp(ms),Host Timestamp(ms),3DOF_x,...

The values are rad/s and m/s^2 (the SDK's motion frames), and the two streams are
sampled apart (the gyro at 200 or 400 Hz, the accelerometer at 63, 100 or 250 Hz): each
is read on its own clock and the accelerometer's increments carried onto the gyro's
samples (:mod:`calib.runlog.streams`), as two files of a phone's logger are. The time is
the frame's hardware stamp: milliseconds in rs-data-collect's; in rs-convert's, the
frame's metadata, which librealsense gives in microseconds whatever the header says.
The host's arrival time is not used: it is when the USB delivered a packet of samples.
"""

from __future__ import annotations

import os

import numpy as np

from calib.errors import CalibError

from .checks import check_meta
from .clipping import sensor_clipping
from .clock import stamps_rate
from .columns import TIME_UNITS, plan_one_sensor
from .csv import _fill_meta, time_in_seconds
from .csvpair import _Place
from .paths import read_bytes
from .run import Run
from .streams import Stream, two_clocks
from .text import decode_lines

HEADER = "Stream Type,"
STREAMS = {"Gyro": "gyro", "Accel": "accel"}  # the first field of a motion stream's rows
TIME = "HW Timestamp (ms)"
AXES = ("3DOF_x", "3DOF_y", "3DOF_z")
CONVERT_MARK = "Backend Timestamp(ms)"  # only rs-convert writes it; its stamps are microseconds
UNITS = {"gyro": "radps", "accel": "mps2"}


def is_realsense(path: str | os.PathLike) -> bool:
    """Whether a CSV file is a librealsense motion log: ``Configuration:`` or a ``Stream Type,`` header
    first, past blank lines.
    """
    try:
        head = read_bytes(path)[:4096].decode("utf-8", errors="replace")
    except CalibError:
        return False
    first = next((line.strip() for line in head.splitlines() if line.strip()), "")
    return first == "Configuration:" or first.startswith(HEADER)


def _blocks(lines: list[str], name: str) -> dict[str, tuple[list[str], list[int], str]]:
    """Each motion stream's rows, their line numbers and the header they follow."""
    found: dict[str, tuple[list[str], list[int], str]] = {}
    header = None
    for number, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith(HEADER):  # rs-data-collect's configuration lists its streams under one too
            header = (line, number) if TIME in line.split(",") else None
            continue
        key = line.split(",", 1)[0]
        if key not in STREAMS or header is None:
            continue
        rows, numbers, own = found.setdefault(key, ([], [], header[0]))
        if own != header[0]:
            raise CalibError(
                f"the {key} rows follow two different headers",
                f"{name}, line {header[1]}",
                "give the file as the RealSense tool wrote it",
            )
        rows.append(line)
        numbers.append(number)
    return found


def _stream(key: str, rows: list[str], numbers: list[int], header: str, name: str) -> tuple[Stream, str]:
    """One motion stream from its block: stamps in seconds, values in SI, and the stamps' unit."""
    sensor = STREAMS[key]
    names = header.split(",")
    where = f"{name}, the {key} block's header"
    missing = [c for c in (TIME, *AXES) if c not in names]
    if missing:
        raise CalibError(
            "a RealSense block without " + ", ".join(f"'{c}'" for c in missing),
            where,
            "give the file as rs-data-collect or rs-convert wrote it (with the 3DOF columns)",
        )
    at = [names.index(c) for c in (TIME, *AXES)]
    values = np.empty((len(rows), 4))
    for i, (row, number) in enumerate(zip(rows, numbers, strict=True)):
        fields = row.split(",")
        if len(fields) != len(names):
            raise CalibError(
                f"a row of {len(fields)} fields under a header of {len(names)}",
                f"{name}, line {number}",
                "give the file as the RealSense tool wrote it, whole",
            )
        try:
            values[i] = [float(fields[j]) for j in at]
        except ValueError:
            raise CalibError(
                "a field that is not a number", f"{name}, line {number}", "correct or remove the row"
            ) from None
    unit = "us" if CONVERT_MARK in names else "ms"
    stamps = time_in_seconds(
        values[:, 0],
        [row.split(",")[at[0]] for row in rows],
        0,
        TIME_UNITS[unit],
        TIME,
        lambda i: f"{name}, line {numbers[i]}",
    )
    plan = plan_one_sensor(["time_s", *(f"{sensor}_{a}_{UNITS[sensor]}" for a in "xyz")], sensor, where)[2]
    period = 1.0 / stamps_rate(stamps)
    clipped = sensor_clipping(values[:, 1:], plan, None, period)
    own = (TIME, *AXES)
    return Stream(name, stamps, np.asarray(numbers), values[:, 1:], clipped, own), unit


def read_realsense(path: str | os.PathLike, allow_gaps: bool, options: dict, columns, conversion=None) -> Run:
    """Read a librealsense motion log (module docstring) into one run on the gyro's clock.

    Parameters
    ----------
    path : str or os.PathLike
        The file, as rs-data-collect or rs-convert wrote it.
    allow_gaps : bool
        Fill samples either stream lost at rest (`calib.runlog.clock.settle`).
    options : dict
        ``latitude_deg``, ``height_m`` and ``sample_rate_hz`` (the gyro's; default: its
        stamps' rate).
    columns : str or dict, optional
        Must be empty: the file names its columns itself.
    conversion : Conversion, optional
        Must be None: the file is in SI.

    Returns
    -------
    Run
        With ``meta["streams"]`` saying how the two streams were put together.

    Raises
    ------
    CalibError
        On a column map or a conversion, a file without both motion streams, or a row that is
        not whole.
    """
    name = str(path)
    if columns:
        raise CalibError(
            "a column map renames a header, and a RealSense motion log names its columns itself "
            "(3DOF_x,3DOF_y,3DOF_z in rad/s and m/s^2)",
            name,
            "leave out the column map (the CLI's --columns) for this file",
        )
    if conversion is not None:
        raise CalibError(
            "a conversion turns raw counts into SI, and a RealSense motion log is in SI already "
            "(rad/s and m/s^2)",
            name,
            "leave out the conversion (the CLI's --conversion) for this file",
        )
    lines = decode_lines(read_bytes(path), name)
    blocks = _blocks(lines, name)
    absent = [k for k in STREAMS if k not in blocks]
    if absent:
        raise CalibError(
            "a RealSense log without the " + " and the ".join(absent) + " stream's rows",
            name,
            "record the camera's motion streams, the gyro and the accelerometer both "
            "(rs-data-collect -c with Gyro and Accel in its configuration)",
        )
    gyro, unit = _stream("Gyro", *blocks["Gyro"], name)
    accel, _ = _stream("Accel", *blocks["Accel"], name)
    meta: dict[str, str] = {}
    time_column = ("time_ms" if unit == "ms" else "time_us", TIME)
    _fill_meta(meta, options, gyro.stamps_s, name, blocks["Gyro"][1][0], time_column)
    check_meta(meta, _Place(name))
    return two_clocks(accel, gyro, meta, allow_gaps)
