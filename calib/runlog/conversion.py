"""The nominal conversion of raw converter counts to SI: a zero and a scale per sensor and axis.

A hand-held IMU's log is often the converter's raw output (unsigned 16-bit
counts, zero near 32768). Its data sheet gives, per sensor and axis, the zero
(counts) and the scale (counts per SI unit: rad/s for the gyro, m/s^2 for the
accelerometer)::

    si = (counts - zero_counts) / counts_per_unit

Two files say so (:func:`read_conversion`):

- imu_tk's nominal-values text (``offset_acc (counts) = 33123 33276 32360``,
  ``DS_a_scale (counts per m/s^2) = diag(415, 413, 415)``, ``DS_a_misal = [...]``,
  ``offset_gyro``, ``DS_g_scale (counts per rad/s)``, ``DS_g_misal``; ``#``
  comments, of which one may state the local gravity), read as it is;
- a TOML of ours::

      range_counts = [0, 65535]          # optional: the converter's limits
      gravity_mps2 = 9.81744             # optional: local gravity
      [gyro]
      zero_counts = [32768, 32466, 32485]
      counts_per_unit = [4778, 4758, 4766]
      unit = "rad/s"                     # or "deg/s"
      [accel]
      zero_counts = [33123, 33276, 32360]
      counts_per_unit = [415, 413, 415]
      unit = "m/s^2"                     # or "g" (9.80665 m/s^2)

The misalignment matrices, when given, are kept (``misalignment``) but not
applied: the conversion is per-axis scale and zero only, the calibration
finds the rest.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from dataclasses import dataclass, field

import numpy as np

from calib.errors import CalibError
from calib.io.fields import Fields, check_format_version
from calib.model.params import DEG, STANDARD_GRAVITY

from .columns import QUANTITIES, SensorColumns
from .paths import read_bytes

SENSORS = ("gyro", "accel")
SI_UNITS = {"gyro": "rad/s", "accel": "m/s^2"}
# Units a TOML may state its scale in: SI per unit.
UNITS = {"gyro": {"rad/s": 1.0, "deg/s": DEG}, "accel": {"m/s^2": 1.0, "g": STANDARD_GRAVITY}}
UNSIGNED_16 = (0.0, 65535.0)  # the range of an unsigned 16-bit converter, counts
_KEYS = ("format_version", "range_counts", "gravity_mps2", "gyro", "accel")
_SENSOR_KEYS = ("zero_counts", "counts_per_unit", "unit", "misalignment")
EXAMPLE = (
    "[gyro] zero_counts = [32768, 32768, 32768], counts_per_unit = [4778, 4758, 4766], "
    'unit = "rad/s"; [accel] zero_counts = [...], counts_per_unit = [...], unit = "m/s^2"'
)


@dataclass(frozen=True)
class Conversion:
    """Per sensor and axis: the zero (counts) and the scale (counts per SI unit).

    Attributes
    ----------
    zero_counts : dict of str to numpy.ndarray
        ``{"gyro": (3,), "accel": (3,)}`` counts at zero rate and zero specific force.
    counts_per_unit : dict of str to numpy.ndarray
        ``{"gyro": (3,), "accel": (3,)}`` counts per rad/s and per m/s^2.
    range_counts : tuple of float
        The converter's lowest and highest count (a sample there is clipped).
    gravity_mps2 : float or None
        The local gravity the file states, m/s^2.
    misalignment : dict of str to numpy.ndarray
        The ``(3, 3)`` misalignment matrices the file gives, kept as given, not applied.
    source : str
        The file read, for messages and the run's metadata.
    """

    zero_counts: dict[str, np.ndarray]
    counts_per_unit: dict[str, np.ndarray]
    range_counts: tuple[float, float] = UNSIGNED_16
    gravity_mps2: float | None = None
    misalignment: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = "<memory>"

    def to_si(self, counts: np.ndarray, sensor: str) -> np.ndarray:
        """``(n, 3)`` counts of ``sensor`` as rad/s (gyro) or m/s^2 (accel)."""
        return (np.asarray(counts, dtype=np.float64) - self.zero_counts[sensor]) / self.counts_per_unit[
            sensor
        ]

    def to_counts(self, si: np.ndarray, sensor: str) -> np.ndarray:
        """The inverse of `to_si`: SI values of ``sensor`` back in counts."""
        return np.asarray(si, dtype=np.float64) * self.counts_per_unit[sensor] + self.zero_counts[sensor]

    def range_si(self, sensor: str) -> np.ndarray:
        """``(3,)`` the largest magnitude each axis of ``sensor`` can show, SI (rad/s, m/s^2)."""
        low, high = self.range_counts
        zero, scale = self.zero_counts[sensor], np.abs(self.counts_per_unit[sensor])
        return np.minimum(high - zero, zero - low) / scale

    @property
    def max_rate_rad_s(self) -> float:
        """The fastest turn the gyro can show (all axes at the end of their range), rad/s."""
        return float(np.linalg.norm(self.range_si("gyro")))

    def meta(self) -> dict[str, str]:
        """Metadata keys recording the conversion in a run (so results can go back to counts)."""
        out = {"conversion": self.source}
        for sensor in SENSORS:
            out[f"conversion_{sensor}_zero_counts"] = " ".join(map(repr, self.zero_counts[sensor].tolist()))
            out[f"conversion_{sensor}_counts_per_unit"] = (
                " ".join(map(repr, self.counts_per_unit[sensor].tolist())) + f" per {SI_UNITS[sensor]}"
            )
        out["conversion_range_counts"] = f"{self.range_counts[0]!r} {self.range_counts[1]!r}"
        return out


def sensor_si(
    values: np.ndarray, sensor: SensorColumns, conversion: Conversion | None, where: str
) -> np.ndarray:
    """A sensor's ``(n, 3)`` columns with raw counts converted to SI rates; other units unchanged.

    Raises
    ------
    CalibError
        For columns in counts without a conversion.
    """
    if not sensor.is_counts:
        return values
    if conversion is None:
        raise CalibError(
            f"the columns {', '.join(sensor.names)} are raw counts, and counts say no rate or force "
            "without the sensor's zero and scale",
            where,
            "give the conversion file: conversion=FILE (the CLI's --conversion FILE), a TOML with "
            "[gyro] and [accel] zero_counts and counts_per_unit, or imu_tk's nominal-values text "
            "(docs/logs-columns.md)",
        )
    return conversion.to_si(values, QUANTITIES[sensor.quantity][0])


def read_conversion(path: str | os.PathLike) -> Conversion:
    """Read a conversion file: our TOML (``.toml``) or imu_tk's nominal-values text (anything else).

    Parameters
    ----------
    path : str or os.PathLike
        The file; a text file may be gzip-compressed.

    Returns
    -------
    Conversion

    Raises
    ------
    CalibError
        On a missing or unreadable file, a missing sensor or key, a count that
        is not a number, or a zero scale; the message names the file and line or key.
    """
    name = str(path)
    data = read_bytes(path)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise CalibError("the conversion file is not UTF-8 text", name, "save it as UTF-8") from None
    if name.lower().endswith(".toml"):
        return _from_toml(text, name)
    return _from_text(text, name)


# The word a user gives instead of a file when imu_tk's two files already hold m/s^2 and rad/s
# (imu_tk reads any unit; its users' files are often SI): zero 0 and one count per SI unit.
SI_WORD = "si"
SI_ALREADY = Conversion(
    {s: np.zeros(3) for s in SENSORS},
    {s: np.ones(3) for s in SENSORS},
    range_counts=(-math.inf, math.inf),
    source=SI_WORD,
)


def as_conversion(conversion: Conversion | str | os.PathLike | None) -> Conversion | None:
    """A `Conversion` as given, or read from its file; the word ``si`` is `SI_ALREADY`; None stays None."""
    if conversion is None or isinstance(conversion, Conversion):
        return conversion
    if isinstance(conversion, str) and conversion.lower() == SI_WORD:
        return SI_ALREADY
    return read_conversion(conversion)


def _from_toml(text: str, name: str) -> Conversion:
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CalibError(f"not valid TOML ({exc})", name, "fix the TOML syntax") from None
    check_format_version(doc, "conversion", name)
    top = Fields(doc, name)
    _misplaced(doc, name)
    top.check_keys(_KEYS, "conversion")  # near misses refused; other extra keys allowed (ignored)
    zero, scale, misal = {}, {}, {}
    for sensor in SENSORS:
        table = top.sub(sensor)
        if table is None:
            raise CalibError(f"missing table [{sensor}]", name, f"write it, e.g. {EXAMPLE}")
        table.check_keys(_SENSOR_KEYS, f"conversion [{sensor}]")
        unit = table.string("unit", SI_UNITS[sensor], choices=tuple(UNITS[sensor]))
        zero[sensor] = np.array(table.numbers("zero_counts", length=3, fix="the counts at zero, x y z"))
        per_unit = table.numbers("counts_per_unit", length=3, fix=f"counts per {unit}, not zero")
        if not all(v != 0.0 for v in per_unit):
            raise CalibError(
                f"counts_per_unit has a zero: {per_unit}", table.here("counts_per_unit"), "give the scale"
            )
        scale[sensor] = np.array(per_unit) / UNITS[sensor][unit]  # counts per SI unit
        if "misalignment" in table.table:
            misal[sensor] = _matrix(table.table["misalignment"], table.here("misalignment"))
    low, high = top.numbers("range_counts", list(UNSIGNED_16), length=2)
    if not low < high:
        raise CalibError(
            f"range_counts = [{low:g}, {high:g}] is empty", top.here("range_counts"), "give [low, high]"
        )
    gravity = top.number("gravity_mps2", None, low=9.7, high=9.9, unit=" m/s^2")
    return Conversion(zero, scale, (low, high), gravity, misal, name)


def _misplaced(doc: dict, name: str) -> None:
    """Refuse a key written in the other level: a file-wide key inside [gyro] or [accel] (where it
    would be ignored and its default taken: an unsigned range for a signed converter's counts), or
    a sensor's key above the tables.
    """
    for sensor in SENSORS:
        table = doc.get(sensor)
        for key in table if isinstance(table, dict) else ():
            if key in _KEYS:
                raise CalibError(
                    f"{key} is written inside [{sensor}]: it is the whole file's, read only above the tables",
                    f"{name}: [{sensor}]",
                    f"move {key} to the top of the file, above [gyro]",
                )
    for key in doc:
        if key in _SENSOR_KEYS:
            raise CalibError(
                f"{key} is written above the tables: it is each sensor's, read only in [gyro] and [accel]",
                name,
                f"write {key} inside [gyro] and inside [accel]",
            )


def _matrix(raw, where: str) -> np.ndarray:
    try:
        matrix = np.array(raw, dtype=np.float64)
    except (TypeError, ValueError):
        matrix = np.zeros(0)
    if matrix.shape != (3, 3) or not np.isfinite(matrix).all():
        raise CalibError("misalignment must be a 3x3 matrix of numbers", where, "write [[..], [..], [..]]")
    return matrix


# imu_tk's nominal-values text: NAME (UNIT) = VALUES, one per line.
_LINE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(\([^)]*\))?\s*=\s*(.+?)\s*$")
_TEXT_KEYS = {  # name: (sensor, what)
    "offset_acc": ("accel", "zero"),
    "offset_gyro": ("gyro", "zero"),
    "DS_a_scale": ("accel", "scale"),
    "DS_g_scale": ("gyro", "scale"),
    "DS_a_misal": ("accel", "misal"),
    "DS_g_misal": ("gyro", "misal"),
}
_GRAVITY = re.compile(r"gravity[^0-9=]*(?:=\s*)?(9\.\d+)\s*(?:m/s\^?2|m/s²)?", re.IGNORECASE)


def _from_text(text: str, name: str) -> Conversion:
    found: dict[tuple[str, str], np.ndarray] = {}
    gravity = None
    lines_of: dict[tuple[str, str], int] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        where = f"{name}, line {number}"
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            match = _GRAVITY.search(stripped)
            if match and gravity is None:
                gravity = float(match.group(1))
            continue
        match = _LINE.match(stripped)
        if match is None:
            raise CalibError(
                f"line {stripped!r} is not NAME (UNIT) = VALUES",
                where,
                "write e.g. 'offset_acc (counts) = 33123 33276 32360' or start comments with '#'",
            )
        key, unit, values = match.group(1), (match.group(2) or "").strip("() "), match.group(3)
        if key.lower() == "gravity":
            gravity = _numbers(values, 1, where)[0]
            continue
        if key not in _TEXT_KEYS:
            continue  # other reference values (the authors' estimates) are not the conversion
        sensor, what = _TEXT_KEYS[key]
        if what == "misal":
            found[(sensor, what)] = _numbers(values, 9, where).reshape(3, 3)
        elif what == "zero":
            found[(sensor, what)] = _numbers(values, 3, where)
        else:
            _check_scale_unit(unit, sensor, where)
            found[(sensor, what)] = _numbers(values, 3, where)
            if not np.all(found[(sensor, what)] != 0.0):
                raise CalibError(f"{key} has a zero scale", where, "give the counts per unit of each axis")
        lines_of[(sensor, what)] = number
    missing = [k for k, (s, w) in _TEXT_KEYS.items() if w != "misal" and (s, w) not in found]
    if missing:
        raise CalibError(
            "the conversion file lacks " + ", ".join(missing),
            name,
            "give offset_acc, offset_gyro (counts), DS_a_scale (counts per m/s^2) and DS_g_scale "
            "(counts per rad/s), one per line, e.g. 'DS_g_scale (counts per rad/s) = diag(4778, 4758, 4766)'",
        )
    if gravity is not None and not 9.7 < gravity < 9.9:
        raise CalibError(f"local gravity {gravity:g} m/s^2 is not Earth's", name, "give it in m/s^2")
    return Conversion(
        zero_counts={s: found[(s, "zero")] for s in SENSORS},
        counts_per_unit={s: found[(s, "scale")] for s in SENSORS},
        gravity_mps2=gravity,
        misalignment={s: found[(s, "misal")] for s in SENSORS if (s, "misal") in found},
        source=name,
    )


def _check_scale_unit(unit: str, sensor: str, where: str) -> None:
    """A scale's stated unit must be counts per the sensor's SI unit."""
    said = unit.replace(" ", "").lower().replace("²", "^2")
    wanted = {"gyro": "countsperrad/s", "accel": "countsperm/s^2"}[sensor]
    if said and said not in (wanted, wanted.replace("^", "")):
        raise CalibError(
            f"the {sensor} scale is given in ({unit}), not in (counts per {SI_UNITS[sensor]})",
            where,
            f"convert it to counts per {SI_UNITS[sensor]}",
        )


def _numbers(text: str, count: int, where: str) -> np.ndarray:
    """``count`` numbers from ``33123 33276 32360``, ``diag(415, 413, 415)`` or ``[1 0 0; ...]``."""
    body = text.strip()
    if body.lower().startswith("diag(") and body.endswith(")"):
        body = body[5:-1]
    tokens = [t for t in re.split(r"[\s,;\[\]]+", body) if t]
    try:
        values = np.array([float(t) for t in tokens])
    except ValueError:
        values = np.zeros(0)
    if values.size != count or not all(math.isfinite(v) for v in values):
        raise CalibError(
            f"{text!r} is not {count} number{'s' if count > 1 else ''}",
            where,
            "write plain numbers, e.g. 33123 33276 32360 or diag(415, 413, 415)",
        )
    return values
