"""CSV column grammar of run logs: ``quantity_axis_unit`` names as loggers write them.

A header names each column by quantity, axis and unit, in any order::

    time_s                                  sample time, s (end of the sample interval)
    dtheta_{x,y,z}_{rad,deg}                gyro angle increments
    gyro_{x,y,z}_{radps,dps}                gyro rates, rad/s or deg/s
    dv_{x,y,z}_mps                          velocity increments, m/s
    accel_{x,y,z}_{mps2,g}                  specific force, m/s^2 or g (9.80665 m/s^2)

Each sensor (gyro, accelerometer) is given once, as increments or as rates, on all
three axes. Other columns (temperature, gimbal encoders, ...) are ignored here.
The classic header of ``docs/formats.md`` (``dtheta_x_rad``, ``dv_x_mps``) is one case
of the grammar, so every file that read before reads the same.

Rates become increments by the rectangular rule: the increment of the sample
ending at ``t_k`` is ``rate_k * (t_k - t_{k-1})`` (the first sample uses the
nominal period). A logger's rate sample is the sensor's mean rate over its
output interval (the decimation filter averages), so this is exact for that
reading; a trapezoid would mix neighbouring samples and correlate their noise,
which bends the Allan deviation at the shortest averaging times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError
from calib.params import DEG, STANDARD_GRAVITY
from calib.runlog.format import TIME_COLUMN

AXES = ("x", "y", "z")

# quantity: (sensor, is a rate, {unit: SI per unit})
QUANTITIES = {
    "dtheta": ("gyro", False, {"rad": 1.0, "deg": DEG}),
    "gyro": ("gyro", True, {"radps": 1.0, "dps": DEG}),
    "dv": ("accel", False, {"mps": 1.0}),
    "accel": ("accel", True, {"mps2": 1.0, "g": STANDARD_GRAVITY}),
}
_CLASSIC = {"gyro": "dtheta", "accel": "dv"}  # the quantity docs/formats.md names
_CLASSIC_UNIT = {"dtheta": "rad", "dv": "mps"}
EXAMPLE_HEADER = "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_g,accel_y_g,accel_z_g"


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


@dataclass(frozen=True)
class ColumnPlan:
    """The columns a run needs, found in one header row."""

    time: int
    gyro: SensorColumns
    accel: SensorColumns


def _split(name: str) -> tuple[str, str, str] | None:
    """``(quantity, axis, unit)`` of a grammar name; unit '' when it has none."""
    parts = name.split("_")
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
    found: dict[str, dict[str, tuple[str, int, float]]] = {}
    seen: dict[str, int] = {}
    for position, column in enumerate(names):
        if column in seen and (column == TIME_COLUMN or _split(column)):
            raise CalibError(
                f"column '{column}' appears twice in the header", where, "keep one of the two columns"
            )
        seen.setdefault(column, position)
        if column.startswith("time_") and column != TIME_COLUMN:
            raise CalibError(
                f"column '{column}': the time unit must be s",
                where,
                f"name the time column '{TIME_COLUMN}', in seconds",
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
        found.setdefault(quantity, {})[axis] = (column, position, units[unit])
    if TIME_COLUMN not in seen:
        _missing([TIME_COLUMN], names, where)
    return ColumnPlan(
        time=seen[TIME_COLUMN],
        gyro=_sensor("gyro", found, names, where),
        accel=_sensor("accel", found, names, where),
    )


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
    raise CalibError(
        f"header row lacks column{'s' if len(missing) > 1 else ''} "
        f"{', '.join(repr(c) for c in missing)}{hint}",
        where,
        "the header row (first line not starting with '#') names time_s and "
        "the gyro and accelerometer on x, y, z as quantity_axis_unit, e.g. "
        f"{EXAMPLE_HEADER} (see docs/logs-columns.md)",
    )


def to_increments(
    values: np.ndarray, sensor: SensorColumns, time_s: np.ndarray, nominal_dt: float
) -> np.ndarray:
    """A sensor's ``(n, 3)`` file values as SI increments over each sample.

    Rates use the rectangular rule of the module docstring: ``rate_k * (t_k - t_{k-1})``,
    the first sample ``rate_0 * nominal_dt``.
    """
    si = values * np.asarray(sensor.si_per_unit)
    if not sensor.is_rate:
        return si
    dt = np.empty_like(time_s)
    dt[0] = nominal_dt
    dt[1:] = np.diff(time_s)
    return si * dt[:, None]
