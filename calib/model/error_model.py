"""The 21-parameter IMU error model of ``conventions.md``.

``apply`` turns true increments into what the IMU outputs; ``compensate``
is its exact inverse. Values are held in SI (rad/s, m/s^2, dimensionless).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from importlib import resources

import numpy as np

from . import params as P


def _matrix(values: np.ndarray, scale: slice, misalignment: slice) -> np.ndarray:
    """``I + S + M`` from the 21-vector, using the table's row/col of each term."""
    E = np.eye(3)
    for p in P.PARAMETERS[scale] + P.PARAMETERS[misalignment]:
        E[p.row, p.col] += values[p.index]
    return E


def error_matrix_jacobian(sensor: str) -> np.ndarray:
    """``d(E)/d(values)`` for ``gyro`` or ``accel``: shape ``(21, 3, 3)``, 0/1 entries."""
    J = np.zeros((P.N_PARAMS, 3, 3))
    for p in P.PARAMETERS:
        if p.sensor == sensor and p.kind != "bias":
            J[p.index, p.row, p.col] = 1.0
    return J


@dataclass(frozen=True)
class ErrorModel:
    """IMU deterministic errors.

    Attributes
    ----------
    values : ndarray, shape (21,)
        The parameters in SI, in the order of :data:`calib.model.params.PARAMETERS`.
    """

    values: np.ndarray

    def __post_init__(self):
        v = np.asarray(self.values, dtype=float).reshape(P.N_PARAMS)
        object.__setattr__(self, "values", v)

    @classmethod
    def zero(cls) -> ErrorModel:
        return cls(np.zeros(P.N_PARAMS))

    @classmethod
    def from_units(cls, values_in_units) -> ErrorModel:
        return cls(P.to_si(values_in_units))

    @classmethod
    def from_table2(cls) -> ErrorModel:
        """The paper's Table 2 standard values (the ``--table2`` injection)."""
        return cls.from_units(paper_table("table2_simulation", "standard"))

    def in_units(self) -> np.ndarray:
        return P.from_si(self.values)

    @property
    def gyro_bias(self) -> np.ndarray:
        return self.values[P.GYRO_BIAS]

    @property
    def accel_bias(self) -> np.ndarray:
        return self.values[P.ACCEL_BIAS]

    @property
    def gyro_matrix(self) -> np.ndarray:
        """``I + S_g + M_g``."""
        return _matrix(self.values, P.GYRO_SCALE, P.GYRO_MISALIGNMENT)

    @property
    def accel_matrix(self) -> np.ndarray:
        """``I + S_a + M_a``."""
        return _matrix(self.values, P.ACCEL_SCALE, P.ACCEL_MISALIGNMENT)

    def apply(self, dtheta: np.ndarray, dv: np.ndarray, dt: np.ndarray | float):
        """True increments -> sensor output (no noise).

        The model is linear with constant coefficients, so applying it to
        increments over ``dt`` is exact.
        """
        dt = np.asarray(dt, dtype=float)[..., None] if np.ndim(dt) else dt
        dtheta_m = dtheta @ self.gyro_matrix.T + self.gyro_bias * dt
        dv_m = dv @ self.accel_matrix.T + self.accel_bias * dt
        return dtheta_m, dv_m

    def compensate(self, dtheta_m: np.ndarray, dv_m: np.ndarray, dt: np.ndarray | float):
        """Sensor output -> corrected increments (exact inverse of :meth:`apply`)."""
        dt = np.asarray(dt, dtype=float)[..., None] if np.ndim(dt) else dt
        dtheta = np.linalg.solve(self.gyro_matrix, (dtheta_m - self.gyro_bias * dt).T).T
        dv = np.linalg.solve(self.accel_matrix, (dv_m - self.accel_bias * dt).T).T
        return dtheta, dv


def paper_table(table: str, column: str) -> np.ndarray:
    """A column of a copied paper table (``calib/data``) as a 21-vector in spec order."""
    text = (resources.files("calib") / "data" / f"{table}.csv").read_text("utf-8")
    rows = [r for r in csv.DictReader(line for line in text.splitlines() if not line.startswith("#"))]
    by_name = {r["name"]: float(r[column]) for r in rows}
    return np.array([by_name[name] for name in P.NAMES])
