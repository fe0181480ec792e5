"""CSV column grammar of run logs: ``quantity_axis_unit`` names as loggers write them.

A header names each column by quantity, axis and unit, in any order::

    time_{s,ms,us,ns}                       sample time (end of the sample interval)
    dtheta_{x,y,z}_{rad,deg}                gyro angle increments
    counter                                 a sample counter instead of a time (needs the rate)
    gyro_{x,y,z}_{radps,dps,mdps,counts}    gyro rates, rad/s, deg/s, milli-deg/s or raw counts
    dv_{x,y,z}_mps                          velocity increments, m/s
    accel_{x,y,z}_{mps2,g,mg,counts}        specific force, m/s^2, g (9.80665 m/s^2), milli-g or raw counts

Raw counts are turned into SI by a conversion file (:mod:`calib.runlog.conversion`), a
counter into time by the stated rate (:mod:`calib.runlog.counter`).

Each sensor (gyro, accelerometer) is given once, as increments or as rates, on all
three axes. Other columns (temperature, gimbal encoders, ...) are ignored here.
The classic header of ``docs/formats.md`` (``dtheta_x_rad``, ``dv_x_mps``) is one case
of the grammar, so every file that read before reads the same.

Rates become increments by the rectangular rule over the IMU's own period:
the increment of sample ``k`` is ``rate_k / sample_rate_hz``. A logger's rate
sample is the sensor's mean rate over its output interval (the decimation
filter averages), so this is exact for that reading; a trapezoid would mix
neighbouring samples and correlate their noise, which bends the Allan
deviation at the shortest averaging times. The time column's own steps are not
used: a host's reception stamps jitter by milliseconds around a sample period
the IMU's crystal keeps to ppm (:mod:`calib.runlog.clock`), and a sample lost
before row ``k`` is filled on its own, not folded into ``k``.

A header whose names are the logger's own (``t,gx,gy,gz,ax,ay,az``) is read
through a column map (:func:`parse_column_map`): ``t=time_ms,gx=gyro_x_dps,...``
renames the file's columns to names of this grammar.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError
from calib.model.params import DEG, STANDARD_GRAVITY

from .format import GIMBAL_COLUMNS, TIME_COLUMN

AXES = ("x", "y", "z")

# quantity: (sensor, is a rate, {unit: SI per unit})
QUANTITIES = {
    "dtheta": ("gyro", False, {"rad": 1.0, "deg": DEG}),
    "gyro": ("gyro", True, {"radps": 1.0, "dps": DEG, "mdps": DEG / 1000.0, "counts": 1.0}),
    "dv": ("accel", False, {"mps": 1.0}),
    "accel": (
        "accel",
        True,
        {"mps2": 1.0, "g": STANDARD_GRAVITY, "mg": STANDARD_GRAVITY / 1000.0, "counts": 1.0},
    ),
}
COUNTS = "counts"  # the unit of raw converter counts: SI through a conversion file, not a factor
COUNTER = "counter"  # a sample counter in place of the time column
_CLASSIC = {"gyro": "dtheta", "accel": "dv"}  # the quantity docs/formats.md names
_CLASSIC_UNIT = {"dtheta": "rad", "dv": "mps"}
EXAMPLE_HEADER = "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_g,accel_y_g,accel_z_g"
# Time units: ticks per second, exact integers (an integer stamp converts without rounding twice).
# 100us: a 10 kHz tick clock (Xsens' SampleTimeFine); last, so a unit guessed from the steps is
# one of the usual four first.
TIME_UNITS = {"s": 1, "ms": 1_000, "us": 1_000_000, "ns": 1_000_000_000, "100us": 10_000}
TIME_NAMES = tuple(f"time_{unit}" for unit in TIME_UNITS)


@dataclass(frozen=True)
class SensorColumns:
    """Where one sensor's three axes are and how to turn them into SI increments."""

    quantity: str  # a key of QUANTITIES
    names: tuple[str, str, str]  # the file's column names, x, y, z
    positions: tuple[int, int, int]
    si_per_unit: tuple[float, float, float]

    @property
    def is_rate(self) -> bool:
        return QUANTITIES[self.quantity][1]

    @property
    def is_counts(self) -> bool:
        """Raw converter counts (``gyro_x_counts``...), SI only through a conversion."""
        return self.names[0].endswith("_" + COUNTS)


@dataclass(frozen=True)
class ColumnPlan:
    """The columns a run needs, found in one header row."""

    time: int
    gyro: SensorColumns
    accel: SensorColumns
    time_name: str = TIME_COLUMN  # time_s, time_ms, time_us, time_ns, time_100us or counter

    @property
    def ticks_per_second(self) -> int:
        """What one second is in the time column's unit (1 for seconds and for a counter)."""
        return TIME_UNITS.get(self.time_name.removeprefix("time_"), 1)


NEGATED = "-"  # before a sensor name: the column holds that axis with its sign reversed


def _split(name: str) -> tuple[str, str, str] | None:
    """``(quantity, axis, unit)`` of a grammar name (negated or not); unit '' when it has none."""
    parts = name.removeprefix(NEGATED).split("_")
    if parts[0] not in QUANTITIES or len(parts) < 2 or parts[1] not in AXES:
        return None
    return parts[0], parts[1], "_".join(parts[2:])


def plan_columns(names: list[str], where: str) -> ColumnPlan:
    """Find time, gyro and accelerometer columns in a header row.

    Parameters
    ----------
    names : list of str
        Header fields, stripped.
    where : str
        Place to name in messages (file and line).

    Returns
    -------
    ColumnPlan

    Raises
    ------
    CalibError
        On a column of a known quantity with a missing or unknown unit, a
        duplicate, a sensor given twice (as rates and as increments) or
        missing axes; the message names the column.
    """
    found, seen = _scan(names, where)
    return ColumnPlan(
        time=_time_position(seen, names, where),
        gyro=_sensor("gyro", found, names, where),
        accel=_sensor("accel", found, names, where),
        time_name=_time_name(seen),
    )


def plan_one_sensor(names: list[str], sensor: str, where: str) -> tuple[int, str, SensorColumns]:
    """The time column and one sensor's columns of a file that holds that sensor alone.

    For loggers that write the gyro and the accelerometer to two files
    (:mod:`calib.runlog.csvpair`). Returns the time column's position, its name
    (``time_s`` ... ``time_ns``) and the sensor's columns; refuses what
    :func:`plan_columns` refuses, and a file that holds the other sensor too.
    """
    found, seen = _scan(names, where)
    other = "accel" if sensor == "gyro" else "gyro"
    both = [q for q, (s, _, _) in QUANTITIES.items() if s == other and q in found]
    if both:
        column = next(iter(found[both[0]].values()))[0]
        raise CalibError(
            f"the {SENSOR_WORDS[sensor]} file also holds the {SENSOR_WORDS[other]} ('{column}')",
            where,
            "give one file with both sensors (no second file), or each sensor's file alone",
        )
    return _time_position(seen, names, where), _time_name(seen), _sensor(sensor, found, names, where)


SENSOR_WORDS = {"gyro": "gyro", "accel": "accelerometer"}


def _scan(names: list[str], where: str) -> tuple[dict, dict[str, int]]:
    """The grammar's columns in a header: ``found[quantity][axis] = (name, position, SI per unit)``
    and every name's first position; refuses a duplicate or a unit the grammar lacks.
    """
    found: dict[str, dict[str, tuple[str, int, float]]] = {}
    seen: dict[str, int] = {}
    for position, column in enumerate(names):
        if column in seen and (column in TIME_NAMES or _split(column)):
            raise CalibError(
                f"column '{column}' appears twice in the header", where, "keep one of the two columns"
            )
        seen.setdefault(column, position)
        if column.startswith("time_") and column not in TIME_NAMES:
            raise CalibError(
                f"column '{column}' has unknown time unit '{column.removeprefix('time_')}'",
                where,
                "name the time column by its unit: " + ", ".join(TIME_NAMES),
            )
        split = _split(column)
        if split is None:
            continue
        quantity, axis, unit = split
        units = QUANTITIES[quantity][2]
        if unit not in units:
            what = "has no unit" if not unit else f"has unknown unit '{unit}'"
            raise CalibError(
                f"column '{column}' {what}",
                where,
                f"name it {quantity}_{axis}_<unit> with <unit> one of "
                + ", ".join(units)
                + f", e.g. {EXAMPLE_HEADER}",
            )
        if axis in found.get(quantity, {}):
            raise CalibError(
                f"{quantity}_{axis} is given twice: columns {found[quantity][axis][1] + 1} and "
                f"{position + 1}",
                where,
                "keep one of the two columns",
            )
        sign = -1.0 if column.startswith(NEGATED) else 1.0  # iOS's accelerometer, a flipped axis
        found.setdefault(quantity, {})[axis] = (column.removeprefix(NEGATED), position, sign * units[unit])
    return found, seen


def _time_name(seen: dict[str, int]) -> str:
    return next(c for c in (*TIME_NAMES, COUNTER) if c in seen)


def _time_position(seen: dict[str, int], names: list[str], where: str) -> int:
    """The one time column's position; refuses none or two."""
    times = [c for c in (*TIME_NAMES, COUNTER) if c in seen]
    if not times:
        lower = [c for c in names if c.lower() in TIME_NAMES]
        if lower or not any(known_name(c) for c in names):  # a header of its own: name it all
            _missing([lower[0].lower() if lower else TIME_COLUMN], names, where)
        raise CalibError(
            "the header row names no time column (" + ", ".join((*TIME_NAMES, COUNTER)) + ")",
            where,
            "state the IMU's rate (the CLI's --sample-rate-hz HZ) to take the rows as evenly spaced, or "
            "map the file's time column (the CLI's --columns t=time_s,...; docs/logs-columns.md)",
        )
    if len(times) > 1:
        raise CalibError(
            f"the time is given twice, as '{times[0]}' and as '{times[1]}'", where, "keep one time column"
        )
    return seen[times[0]]


def _sensor(sensor: str, found: dict, names: list[str], where: str) -> SensorColumns:
    """The one quantity that gives ``sensor`` on all three axes."""
    given = [q for q, (s, _, _) in QUANTITIES.items() if s == sensor and q in found]
    if len(given) > 1:
        a, b = (next(iter(found[q].values()))[0] for q in given)
        raise CalibError(
            f"the {sensor} is given twice, as '{a}' and as '{b}'",
            where,
            "keep either the rates or the increments",
        )
    quantity = given[0] if given else _CLASSIC[sensor]
    axes = found.get(quantity, {})
    if len(axes) < 3:
        unit = next(iter(axes.values()))[0].split("_", 2)[2] if axes else _CLASSIC_UNIT[quantity]
        _missing([f"{quantity}_{a}_{unit}" for a in AXES if a not in axes], names, where)
    columns = [axes[a] for a in AXES]
    counts = [c[0].endswith("_" + COUNTS) for c in columns]
    if any(counts) and not all(counts):
        raise CalibError(
            f"the {sensor} mixes raw counts and SI units: " + ", ".join(c[0] for c in columns),
            where,
            "give the three axes of a sensor all in counts or all in a physical unit",
        )
    return SensorColumns(
        quantity=quantity,
        names=tuple(c[0] for c in columns),
        positions=tuple(c[1] for c in columns),
        si_per_unit=tuple(c[2] for c in columns),
    )


def _missing(missing: list[str], names: list[str], where: str) -> None:
    lower = {c.lower(): c for c in names}
    hints = [f"'{lower[c.lower()]}' should be '{c}'" for c in missing if c.lower() in lower]
    hint = f"; column names are case-sensitive: {', '.join(hints)}" if hints else ""
    shown = ", ".join(names[:5]) + (", ..." if len(names) > 5 else "")
    # The file's own names first: a logger's header is read by mapping them, said before the grammar.
    raise CalibError(
        f"header row lacks column{'s' if len(missing) > 1 else ''} "
        f"{', '.join(repr(c) for c in missing)}{hint} (it has {shown})",
        where,
        "map the file's names with a column map, e.g. columns='t=time_s,gx=gyro_x_dps,...' "
        "(the CLI's --columns): time_s, _ms, _us or _ns, and quantity_axis_unit (docs/logs-columns.md)",
    )


def accepted_names() -> str:
    """The names a column map may give, for messages."""
    sensors = "; ".join(
        f"{quantity}_{{x,y,z}}_{{{','.join(u for u in units if u != COUNTS)}}}"
        for quantity, (_, _, units) in QUANTITIES.items()
    )
    return (
        ", ".join(TIME_NAMES)
        + "; "
        + sensors
        + "; "
        + ", ".join(GIMBAL_COLUMNS)
        + f"; a sample counter: {COUNTER}; raw counts: gyro_{{x,y,z}}_{COUNTS}, accel_{{x,y,z}}_{COUNTS}; "
        f"a sensor axis negated: {NEGATED}accel_x_g"
    )


def known_name(name: str) -> bool:
    """Whether ``name`` is a column this grammar reads (time, a sensor axis with its unit, an encoder)."""
    if name in TIME_NAMES or name in GIMBAL_COLUMNS or name == COUNTER:
        return True
    split = _split(name)
    return split is not None and split[2] in QUANTITIES[split[0]][2]


def parse_column_map(columns: str | dict[str, str] | None, where: str) -> dict[str, str]:
    """A column map, ``{file's name: our name}``, from ``'t=time_ms,gx=gyro_x_dps,...'`` or a dict.

    Parameters
    ----------
    columns : str or dict or None
        Comma-separated ``FILE_NAME=OUR_NAME`` pairs, or the same pairs as a dict;
        None or empty maps nothing.
    where : str
        Place to name in messages.

    Raises
    ------
    CalibError
        On a pair without ``=``, a file name given twice, or an unknown name to map to
        (the message lists the accepted ones).
    """
    mapping: dict[str, str] = {}
    for source, target in column_map_pairs(columns, where):
        if source in mapping:
            raise CalibError(
                f"column map names the file's column '{source}' twice", where, "map each column once"
            )
        mapping[source] = target
    return mapping


def sensor_of(target: str) -> str | None:
    """``"gyro"`` or ``"accel"`` for a grammar name of that sensor's columns, else None."""
    split = _split(target)
    return QUANTITIES[split[0]][0] if split else None


def column_map_pairs(columns: str | dict[str, str] | None, where: str) -> list[tuple[str, str]]:
    """The ``(file's name, our name)`` pairs of a column map, each our name checked to be known.

    A name may come twice here; :func:`parse_column_map` refuses that for one file, and
    :mod:`calib.runlog.csvpair` allows it once per sensor (each file's ``x`` its own).
    """
    if not columns:
        return []
    if isinstance(columns, str):
        pairs = []
        for item in columns.split(","):
            if not item.strip():
                continue
            source, equals, target = item.partition("=")
            if not equals or not source.strip() or not target.strip():
                raise CalibError(
                    f"column map item {item.strip()!r} is not FILE_NAME=OUR_NAME",
                    where,
                    "write pairs like t=time_ms,gx=gyro_x_dps,gy=gyro_y_dps,gz=gyro_z_dps,"
                    "ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2",
                )
            pairs.append((source.strip(), target.strip()))
    else:
        pairs = [(str(k).strip(), str(v).strip()) for k, v in columns.items()]
    for source, target in pairs:
        if not known_name(target):
            raise CalibError(
                f"column map: '{source}={target}' maps to an unknown name '{target}'",
                where,
                "map to one of " + accepted_names() + " (docs/logs-columns.md)",
            )
    return pairs


def apply_column_map(names: list[str], mapping: dict[str, str], where: str) -> list[str]:
    """The header's names with the map applied; refuse a mapped name the header lacks."""
    absent = [source for source in mapping if source not in names]
    if absent:
        raise CalibError(
            "column map names "
            + ", ".join(f"'{a}'" for a in absent)
            + f", which the header row does not have (it has {', '.join(names)})",
            where,
            "map the names the header row gives (column names are case-sensitive)",
        )
    return [mapping.get(name, name) for name in names]


def to_increments(
    values: np.ndarray, sensor: SensorColumns, time_s: np.ndarray, nominal_dt: float | np.ndarray
) -> np.ndarray:
    """A sensor's ``(n, 3)`` file values as SI increments over each sample.

    Rates use the rectangular rule of the module docstring: ``rate_k * nominal_dt``
    (``time_s`` only locates the samples). ``nominal_dt`` may be ``(n, 1)``: each
    sample's own interval, for a log sampled at its stamps (:mod:`calib.runlog.polled`).
    """
    si = values * np.asarray(sensor.si_per_unit)
    if not sensor.is_rate:
        return si
    return si * nominal_dt


# The output rates of IMUs, Hz: a factor 1000 wide, so at most one time unit puts a log in it.
IMU_RATES_HZ = (5.0, 5000.0)
# Without a stated rate, a log this slow or this fast in its stated unit is no IMU's ...
IMPLAUSIBLE_RATES_HZ = (1.0, 20000.0)
# ... when it has at least this many samples (a handful of rows says nothing).
IMU_LIKE_COUNT = 1000
_UNIT_WORDS = {
    "s": "seconds",
    "ms": "milliseconds",
    "us": "microseconds",
    "ns": "nanoseconds",
    "100us": "100-microsecond ticks",
}


def time_unit_suspect(
    step_s: float,
    column: str | None,
    n_samples: int,
    sample_rate_hz: float | None = None,
    file_name: str | None = None,
) -> CalibError | None:
    """The refusal of a time column whose steps say it is in another unit than its name's, or None.

    With a stated rate, the typical step must be one period: a step 1000 (or
    1e6, 1e9, 1/1000...) periods long says the unit. Without one, a log of
    IMU-like length whose steps give a rate no IMU has is judged by the unit
    that gives an IMU's rate.

    Parameters
    ----------
    step_s : float
        Typical time step (median), s as the column's name converts it.
    column : str or None
        The time column's name (``time_ms``...); None for a time stored in s
        without a name to change (an NPZ's ``time_s``).
    n_samples : int
    sample_rate_hz : float, optional
        The stated rate.
    file_name : str, optional
        The file's own name of the column, when a column map renamed it.
    """
    unit = (column or TIME_COLUMN).removeprefix("time_")
    written = step_s * TIME_UNITS[unit]  # the step as the file writes it
    if not step_s > 0.0:
        return None
    if sample_rate_hz is not None:
        fits = [u for u, k in TIME_UNITS.items() if u != unit and abs(written / k * sample_rate_hz - 1) < 0.1]
        said = f"at {sample_rate_hz:g} Hz"
    else:
        low, high = IMPLAUSIBLE_RATES_HZ
        if n_samples < IMU_LIKE_COUNT or low <= 1.0 / step_s <= high:
            return None
        fits = [u for u, k in TIME_UNITS.items() if IMU_RATES_HZ[0] <= k / written < IMU_RATES_HZ[1]]
        said = f"over {n_samples} samples ({1.0 / step_s:.3g} Hz: no IMU samples at that rate)"
    if not fits:
        return None
    if column is None:
        fix = f"store the time in seconds (x{1 / TIME_UNITS[fits[0]]:g})"
    elif file_name and file_name != column:
        fix = f"map {file_name}=time_{fits[0]} in the column map"
    else:
        fix = f"name it time_{fits[0]}"
    return CalibError(
        f"time steps of {written:.6g} '{_UNIT_WORDS[unit]}' {said}: the column "
        f"'{file_name or column or TIME_COLUMN}' looks like {_UNIT_WORDS[fits[0]]}",
        None,
        fix + ", or correct sample_rate_hz" if sample_rate_hz is not None else fix,
    )
