"""The 21 IMU error parameters: order, names, units, requirements.

This module is the single source of truth for the parameter table of
``docs/conventions.md``. Every other module takes names, units, SI factors and
requirements from :data:`PARAMETERS`; none repeats them.

Sensor model (body frame defined by the accelerometers)::

    w_meas = (I + S_g + M_g) w_true + b_g
    f_meas = (I + S_a + M_a) f_true + b_a

``M_g`` is full off-diagonal (6 terms), ``M_a`` strictly lower-triangular
(3 terms), ``M[i, j]`` = what sensor ``i`` senses of body axis ``j``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEG = np.pi / 180.0
ARCSEC = DEG / 3600.0
DEG_PER_HOUR = DEG / 3600.0
PPM = 1e-6
STANDARD_GRAVITY = 9.80665
MICRO_G = 1e-6 * STANDARD_GRAVITY


@dataclass(frozen=True)
class Parameter:
    """One row of the parameter table.

    Attributes
    ----------
    index : int
        Position in the 21-vector.
    name : str
        Spec name used in files and ``--json`` output.
    group : str
        Requirement group (``gyro_bias``, ``gyro_scale``, ...).
    unit : str
        Unit in files and reports.
    si_per_unit : float
        Multiply a value in ``unit`` by this to get SI (rad/s, m/s^2, or
        dimensionless for scale factors and misalignments).
    requirement : float
        Accuracy requirement on the calibration error, in ``unit``.
    paper_name : str
        The reference paper's symbol.
    sensor : str
        ``gyro`` or ``accel``.
    kind : str
        ``bias``, ``scale`` or ``misalignment``.
    row, col : int
        Sensor axis and body axis (for scale factors ``row == col``; for
        biases ``col`` is -1).
    """

    index: int
    name: str
    group: str
    unit: str
    si_per_unit: float
    requirement: float
    paper_name: str
    sensor: str
    kind: str
    row: int
    col: int


def _table() -> tuple[Parameter, ...]:
    rows: list[Parameter] = []
    axes = "xyz"

    # over 8 parameters: one registry row, a Parameter's fields in its order
    def add(name, group, unit, si, req, paper, sensor, kind, row, col):
        rows.append(Parameter(len(rows), name, group, unit, si, req, paper, sensor, kind, row, col))

    for i in range(3):
        add(f"bg{axes[i]}", "gyro_bias", "deg/h", DEG_PER_HOUR, 0.03, f"D0{axes[i]}", "gyro", "bias", i, -1)
    for i in range(3):
        add(f"sg{axes[i]}", "gyro_scale", "ppm", PPM, 1.0, f"Wg{axes[i] * 2}", "gyro", "scale", i, i)
    for i, j in [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]:
        add(
            f"mg{axes[i]}{axes[j]}",
            "gyro_misalignment",
            "arcsec",
            ARCSEC,
            15.0,
            f"Wg{axes[i]}{axes[j]}",
            "gyro",
            "misalignment",
            i,
            j,
        )
    for i in range(3):
        add(f"ba{axes[i]}", "accel_bias", "ug", MICRO_G, 50.0, f"E0{axes[i]}", "accel", "bias", i, -1)
    for i in range(3):
        add(f"sa{axes[i]}", "accel_scale", "ppm", PPM, 1.0, f"Ka{axes[i] * 2}", "accel", "scale", i, i)
    for i, j in [(1, 0), (2, 0), (2, 1)]:
        add(
            f"ma{axes[i]}{axes[j]}",
            "accel_misalignment",
            "arcsec",
            ARCSEC,
            10.0,
            f"Ka{axes[i]}{axes[j]}",
            "accel",
            "misalignment",
            i,
            j,
        )
    return tuple(rows)


PARAMETERS: tuple[Parameter, ...] = _table()
N_PARAMS = len(PARAMETERS)
NAMES: tuple[str, ...] = tuple(p.name for p in PARAMETERS)
INDEX: dict[str, int] = {p.name: p.index for p in PARAMETERS}
SI_PER_UNIT = np.array([p.si_per_unit for p in PARAMETERS])
REQUIREMENTS = np.array([p.requirement for p in PARAMETERS])
REQUIREMENTS_SI = REQUIREMENTS * SI_PER_UNIT

GYRO_BIAS = slice(0, 3)
GYRO_SCALE = slice(3, 6)
GYRO_MISALIGNMENT = slice(6, 12)
ACCEL_BIAS = slice(12, 15)
ACCEL_SCALE = slice(15, 18)
ACCEL_MISALIGNMENT = slice(18, 21)


def to_si(values_in_units: np.ndarray) -> np.ndarray:
    """Convert a 21-vector (or ``(..., 21)`` array) from report units to SI."""
    return np.asarray(values_in_units, dtype=float) * SI_PER_UNIT


def from_si(values_si: np.ndarray) -> np.ndarray:
    """Convert a 21-vector (or ``(..., 21)`` array) from SI to report units."""
    return np.asarray(values_si, dtype=float) / SI_PER_UNIT


def ratio(sigma_si: np.ndarray) -> np.ndarray:
    """The spec's figure of merit ``3 sigma / requirement`` per parameter."""
    return 3.0 * np.asarray(sigma_si) / REQUIREMENTS_SI
