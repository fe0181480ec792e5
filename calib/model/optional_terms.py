"""Errors of a real unit beyond the paper's 21: the optional terms.

Each group is off by default and switched on by name (``--with
lever-arm,k2,time-offset``). This module is the single source of truth for
their names, units and physics: the simulator applies :func:`apply`, the
estimator removes them with :func:`compensate` and linearises them with
:func:`dv_sensitivity`, and the analyser uses the same sensitivity.

All three act on the accelerometer increments (body frame, per sample of
length ``h``), on top of the 21-parameter model::

    dv_loc  = dv_shift + lever(dtheta)               # specific force where each accelerometer sits
    dv_meas = (I + S_a + M_a) dv_loc + b_a h + k2 * dv_loc**2 / h

- **lever-arm** (size effect): accelerometer ``i`` sits at ``r_i`` (body
  frame) from the gimbal's rotation centre and senses
  ``e_i . (omega x (omega x r_i) + omega_dot x r_i)``. Per sample the
  centripetal part is ``(dtheta x (dtheta x r_i)) / h`` (exact at a constant
  rate) and the tangential part ``(omega_j - omega_{j-1}) x r_i`` with the
  sample-mean rates ``omega_j = dtheta_j / h_j``: exact when the rate steps
  of a flip fall on sample boundaries (every sequence at 200 Hz with whole-
  millisecond timings); otherwise the step is split over two samples, a
  one-sample transient. Parameters ``r<i><m>``: component ``m`` of
  accelerometer ``i``'s position, in cm. With flips about body axes only,
  accelerometer ``i`` senses ``r_ii`` through the centripetal term and
  ``r_im`` (``m != i``) through the tangential one.
- **k2**: quadratic accelerometer error ``k2_i f_i^2``, per sample
  ``k2_i dv_i^2 / h`` (exact at rest, ``O((omega h)^2)`` relative while
  turning). Parameters ``k2x k2y k2z`` in ug/g^2.
- **time-offset**: the accelerometer samples lag the gyro samples by
  ``dt_ga`` (the accelerometers integrate over windows ending ``dt_ga``
  earlier). The specific force turns in the body at ``omega_nb`` (gravity is
  fixed in the Earth-fixed n frame, so at rest nothing changes), hence to
  first order ``dv_shift = dv + dt_ga (dtheta_nb x dv) / h`` with
  ``dtheta_nb = dtheta - C_b_n^T omega_ie_n h``; the
  simulator shifts the windows exactly, so the compensation leaves a
  second-order error ``~ dt_ga^2 omega^2 g T_flip / 2`` (3e-7 m/s per flip for
  0.5 ms at 10 deg/s). Parameter ``dt_ga`` in ms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calib.errors import CalibError

from .params import DEG_PER_HOUR, MICRO_G, STANDARD_GRAVITY


@dataclass(frozen=True)
class OptionalParameter:
    """One optional parameter.

    Attributes
    ----------
    name : str
        Name in files and ``--json`` output.
    group : str
        The ``--with`` name that switches it on.
    unit : str
        Unit in files and reports.
    si_per_unit : float
    scale : float
        A typical size in ``unit``: scales the normal equations, and is the
        reference of the "weak" test (sigma > 1000 x scale is refused).
    meaning : str
    limit : float
        Largest plausible magnitude in ``unit``; files and options beyond it are refused.
    row, col : int
        Accelerometer and body component (lever arms), accelerometer (k2), or -1.
    """

    name: str
    group: str
    unit: str
    si_per_unit: float
    scale: float
    meaning: str
    limit: float
    row: int = -1
    col: int = -1

    @property
    def scale_si(self) -> float:
        return self.scale * self.si_per_unit


K2_SI_PER_UG_PER_G2 = MICRO_G / STANDARD_GRAVITY**2  # 1 ug/g^2 in 1/(m/s^2)
G_SENSITIVITY_SI_PER_UNIT = DEG_PER_HOUR / STANDARD_GRAVITY  # 1 deg/h/g in (rad/s)/(m/s^2)
BIAS_DRIFT_SI_PER_UNIT = MICRO_G / 60.0  # 1 ug/min in (m/s^2)/s
ACCEL_BIAS_DRIFT = "accel-bias-drift"
GYRO_DRIFT_SI_PER_UNIT = DEG_PER_HOUR / 60.0  # 1 deg/h/min in (rad/s)/s
GYRO_BIAS_DRIFT = "gyro-bias-drift"


def _table() -> dict[str, tuple[OptionalParameter, ...]]:
    axes = "xyz"
    lever = tuple(
        OptionalParameter(
            f"r{axes[i]}{axes[m]}",
            "lever-arm",
            "cm",
            0.01,
            1.0,
            f"{axes[m]} component of the {axes[i]}-accelerometer's position from the rotation centre",
            50.0,
            i,
            m,
        )
        for i in range(3)
        for m in range(3)
    )
    k2 = tuple(
        OptionalParameter(
            f"k2{axes[i]}",
            "k2",
            "ug/g^2",
            K2_SI_PER_UG_PER_G2,
            10.0,
            f"quadratic error of the {axes[i]}-accelerometer",
            1000.0,
            i,
            -1,
        )
        for i in range(3)
    )
    offset = (
        OptionalParameter(
            "dt_ga",
            "time-offset",
            "ms",
            1e-3,
            0.1,
            "accelerometer samples lag the gyro samples by this",
            100.0,
        ),
    )
    g_sensitivity = tuple(
        OptionalParameter(
            f"gs{axes[i]}{axes[m]}",
            "g-sensitivity",
            "deg/h/g",
            G_SENSITIVITY_SI_PER_UNIT,
            10.0,
            f"rate the {axes[i]}-gyro reads per g of specific force along body {axes[m]}",
            1e4,
            i,
            m,
        )
        for i in range(3)
        for m in range(3)
    )
    drift = tuple(
        OptionalParameter(
            f"dba{axes[i]}",
            ACCEL_BIAS_DRIFT,
            "ug/min",
            BIAS_DRIFT_SI_PER_UNIT,
            100.0,
            f"change of the {axes[i]}-accelerometer's bias per minute over the run (a unit warming up)",
            1e6,
            i,
            -1,
        )
        for i in range(3)
    )
    gyro_drift = tuple(
        OptionalParameter(
            f"dbg{axes[i]}",
            GYRO_BIAS_DRIFT,
            "deg/h/min",
            GYRO_DRIFT_SI_PER_UNIT,
            10.0,
            f"change of the {axes[i]}-gyro's bias per minute over the run (a unit warming up)",
            1e5,
            i,
            -1,
        )
        for i in range(3)
    )
    return {
        "lever-arm": lever,
        "k2": k2,
        "time-offset": offset,
        "g-sensitivity": g_sensitivity,
        ACCEL_BIAS_DRIFT: drift,
        GYRO_BIAS_DRIFT: gyro_drift,
    }


GROUPS: dict[str, tuple[OptionalParameter, ...]] = _table()
# The groups of a gimbal run (simulated, analysed, designed and fitted alike; ``all``).
GROUP_NAMES: tuple[str, ...] = ("lever-arm", "k2", "time-offset")
# Fitted on runs placed by hand only: a MEMS gyro's rate per g of specific force
# (``w_meas = A_g w + b_g + G f``), which real hand-placed logs show at hundreds of deg/h; and the
# accelerometers' and the gyros' biases changing linearly over the run (``b + d (t - t_last)``, a
# unit still warming up: a RealSense T265's x accelerometer bias moves 700 ug/min, a wireless IMU's
# x gyro bias about 50 deg/h/min).
HAND_GROUP_NAMES: tuple[str, ...] = ("g-sensitivity", ACCEL_BIAS_DRIFT, GYRO_BIAS_DRIFT)


def parse_groups(
    text: str | None, where: str = "extras (the CLI's --with)", allowed: tuple[str, ...] = GROUP_NAMES
) -> tuple[str, ...]:
    """``"k2,lever-arm"`` -> the groups in canonical order; ``""``/None -> none; ``all`` -> ``allowed``."""
    if not text:
        return ()
    names = [t.strip() for t in text.split(",") if t.strip()]
    if names == ["all"]:
        return allowed
    unknown = [n for n in names if n not in allowed]
    if unknown:
        hand = [n for n in unknown if n in HAND_GROUP_NAMES]
        raise CalibError(
            f"unknown extra term(s) {', '.join(map(repr, unknown))}"
            + (f" here ({', '.join(hand)}: runs placed by hand, calibrate --by-hand)" if hand else ""),
            where,
            "choose from " + ", ".join(allowed) + " (or 'all')",
        )
    return tuple(g for g in GROUPS if g in names)


@dataclass(frozen=True)
class OptionalTerms:
    """The switched-on groups and their parameters, in canonical order."""

    groups: tuple[str, ...] = ()

    @property
    def parameters(self) -> tuple[OptionalParameter, ...]:
        return tuple(p for g in self.groups for p in GROUPS[g])

    @property
    def n(self) -> int:
        return len(self.parameters)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def si_per_unit(self) -> np.ndarray:
        return np.array([p.si_per_unit for p in self.parameters])

    @property
    def scale_si(self) -> np.ndarray:
        return np.array([p.scale_si for p in self.parameters])

    def index(self, group: str) -> slice:
        start = 0
        for g in self.groups:
            if g == group:
                return slice(start, start + len(GROUPS[g]))
            start += len(GROUPS[g])
        return slice(0, 0)

    def unpack(self, values: np.ndarray) -> OptionalTermValues:
        """SI values of the switched-on parameters -> :class:`OptionalTermValues` (others zero)."""
        v = np.asarray(values, dtype=float)
        out = OptionalTermValues()
        if "lever-arm" in self.groups:
            out = out.replace(lever_arm_m=v[self.index("lever-arm")].reshape(3, 3))
        if "k2" in self.groups:
            out = out.replace(k2=v[self.index("k2")])
        if "time-offset" in self.groups:
            out = out.replace(time_offset_s=float(v[self.index("time-offset")][0]))
        return out

    def pack(self, values: OptionalTermValues) -> np.ndarray:
        parts = {
            "lever-arm": values.lever_arm_m.reshape(9),
            "k2": values.k2,
            "time-offset": np.array([values.time_offset_s]),
        }
        # A hand run's g-sensitivity has no simulated value here: a truth holds it as zero.
        return (
            np.concatenate([parts.get(g, np.zeros(len(GROUPS[g]))) for g in self.groups])
            if self.groups
            else np.zeros(0)
        )


NONE = OptionalTerms()


@dataclass(frozen=True)
class OptionalTermValues:
    """Values of every optional term (SI); zero means off.

    Attributes
    ----------
    lever_arm_m : ndarray, shape (3, 3)
        Row ``i``: position of accelerometer ``i`` from the rotation centre (body, m).
    k2 : ndarray, shape (3,)
        Quadratic terms, 1/(m/s^2).
    time_offset_s : float
        Accelerometer lag behind the gyros, s.
    """

    lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    k2: np.ndarray = field(default_factory=lambda: np.zeros(3))
    time_offset_s: float = 0.0

    def replace(self, **kw) -> OptionalTermValues:
        d: dict[str, Any] = {
            "lever_arm_m": self.lever_arm_m,
            "k2": self.k2,
            "time_offset_s": self.time_offset_s,
        }
        d.update(kw)
        return OptionalTermValues(
            np.asarray(d["lever_arm_m"], dtype=float).reshape(3, 3),
            np.asarray(d["k2"], dtype=float).reshape(3),
            float(d["time_offset_s"]),
        )

    @property
    def groups(self) -> tuple[str, ...]:
        on = {
            "lever-arm": np.any(self.lever_arm_m != 0),
            "k2": np.any(self.k2 != 0),
            "time-offset": self.time_offset_s != 0,
        }
        return tuple(g for g in GROUP_NAMES if on[g])

    @property
    def active(self) -> bool:
        return bool(self.groups)

    def in_units(self) -> dict[str, float]:
        """Every parameter by name, in its report unit."""
        full = OptionalTerms(GROUP_NAMES)
        return {
            p.name: float(v / p.si_per_unit) for p, v in zip(full.parameters, full.pack(self), strict=True)
        }

    @classmethod
    def from_units(
        cls, by_name: dict[str, float], where: str = "extra terms (the CLI's --extra)"
    ) -> OptionalTermValues:
        full = OptionalTerms(GROUP_NAMES)
        known = {p.name: p for p in full.parameters}
        unknown = sorted(set(by_name) - set(known))
        if unknown:
            raise CalibError(
                f"unknown extra parameter(s) {', '.join(unknown)}", where, "known: " + ", ".join(known)
            )
        for name, value in by_name.items():
            if not abs(value) <= known[name].limit:
                raise CalibError(
                    f"{name} = {value:g} {known[name].unit} is beyond the plausible "
                    f"{known[name].limit:g} {known[name].unit}",
                    where,
                    f"give {name} in {known[name].unit}",
                )
        v = np.array([float(by_name.get(p.name, 0.0)) * p.si_per_unit for p in full.parameters])
        return full.unpack(v)


def parse_values(text: str | None, where: str = "extra terms (the CLI's --extra)") -> OptionalTermValues:
    """``"rxx=3,k2y=20,dt_ga=0.5"`` (report units) -> :class:`OptionalTermValues`."""
    if not text:
        return OptionalTermValues()
    values = {}
    for item in (t.strip() for t in text.split(",")):
        if not item:
            continue
        name, sep, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not sep or not math.isfinite(number):
            raise CalibError(
                f"{item!r} is not name=number", where, "e.g. rxx=3,k2y=20,dt_ga=0.5 (cm, ug/g^2, ms)"
            )
        values[name.strip()] = number
    return OptionalTermValues.from_units(values, where)


def sample_rates(dtheta: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Sample-mean angular rates ``dtheta / h`` (body, rad/s)."""
    return dtheta / h[:, None]


def _rate_steps(dtheta: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``omega_j - omega_{j-1}`` per sample (the first sample's predecessor is itself)."""
    w = sample_rates(dtheta, h)
    return np.diff(w, axis=0, prepend=w[:1])


def lever_matrix(dtheta: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Per sample ``A_j`` with ``lever(dtheta)_i = e_i . A_j r_i``: shape (n, 3, 3).

    ``A_j r = (dtheta x (dtheta x r)) / h + (omega_j - omega_{j-1}) x r``.
    """
    t = dtheta
    # [t x]^2 = t t^T - |t|^2 I
    A = np.einsum("ni,nm->nim", t, t) - np.einsum("n,im->nim", np.sum(t * t, 1), np.eye(3))
    A /= h[:, None, None]
    d = _rate_steps(dtheta, h)
    A[:, 0, 1] -= d[:, 2]
    A[:, 0, 2] += d[:, 1]
    A[:, 1, 0] += d[:, 2]
    A[:, 1, 2] -= d[:, 0]
    A[:, 2, 0] -= d[:, 1]
    A[:, 2, 1] += d[:, 0]
    return A


def lever(lever_arm_m: np.ndarray, dtheta: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Velocity increment each accelerometer senses from its lever arm: (n, 3)."""
    A = lever_matrix(dtheta, h)
    return np.einsum("nim,im->ni", A, lever_arm_m)


def apply(
    values: OptionalTermValues, dtheta_true: np.ndarray, dv_shift: np.ndarray, h: np.ndarray, accel_apply
) -> np.ndarray:
    """Accelerometer output from true gyro increments and (time-shifted) true velocity increments.

    ``accel_apply(dv)`` applies the 21-parameter model (scale, misalignment,
    bias) to velocity increments.
    """
    dv_loc = dv_shift + lever(values.lever_arm_m, dtheta_true, h)
    return accel_apply(dv_loc) + values.k2 * dv_loc**2 / h[:, None]


def compensate(
    values: OptionalTermValues,
    dtheta: np.ndarray,
    dv_m: np.ndarray,
    h: np.ndarray,
    accel_compensate,
    earth_dtheta: np.ndarray | float = 0.0,
) -> np.ndarray:
    """Inverse of :func:`apply` (exact but for the first-order time shift).

    ``dtheta`` are the already compensated gyro increments;
    ``accel_compensate(dv)`` inverts the 21-parameter accelerometer model;
    ``earth_dtheta`` (n, 3) is the Earth's turn in the body over each sample,
    ``C_b_n^T omega_ie_n h`` (see :func:`earth_turn`).
    """
    dv_loc = accel_compensate(dv_m)
    if np.any(values.k2 != 0):
        # k2 f^2 is ~1e-4 of f: each pass gains four orders of magnitude.
        for _ in range(3):
            dv_loc = accel_compensate(dv_m - values.k2 * dv_loc**2 / h[:, None])
    dv = dv_loc - lever(values.lever_arm_m, dtheta, h)
    if values.time_offset_s != 0:
        dv = dv - values.time_offset_s * np.cross(dtheta - earth_dtheta, dv) / h[:, None]
    return dv


def earth_turn(C_b_n_mid: np.ndarray, omega_ie_n: np.ndarray, h: np.ndarray) -> np.ndarray:
    """The Earth's turn seen in the body over each sample, ``C_b_n^T omega_ie_n h``: (n, 3)."""
    return np.einsum("nab,a->nb", C_b_n_mid, omega_ie_n) * h[:, None]


def dv_sensitivity(
    extras: OptionalTerms,
    dtheta: np.ndarray,
    dv: np.ndarray,
    h: np.ndarray,
    earth_dtheta: np.ndarray | float = 0.0,
) -> np.ndarray:
    """``d dv_meas / d(extra parameters, SI)`` per sample: shape (n, 3, extras.n)."""
    n = len(h)
    D = np.zeros((n, 3, extras.n))
    if "lever-arm" in extras.groups:
        A = lever_matrix(dtheta, h)
        s = extras.index("lever-arm").start
        for i in range(3):
            D[:, i, s + 3 * i : s + 3 * i + 3] = A[:, i, :]
    if "k2" in extras.groups:
        s = extras.index("k2").start
        for i in range(3):
            D[:, i, s + i] = dv[:, i] ** 2 / h
    if "time-offset" in extras.groups:
        D[:, :, extras.index("time-offset").start] = np.cross(dtheta - earth_dtheta, dv) / h[:, None]
    return D


def load_optional_terms(extras: OptionalTerms | str | None, by_hand: bool = False) -> OptionalTerms:
    """Optional terms from an :class:`OptionalTerms`, a ``--with`` string or None.

    ``by_hand``: only the groups a run placed by hand may ask for.
    """
    allowed = HAND_GROUP_NAMES if by_hand else GROUP_NAMES
    if isinstance(extras, OptionalTerms):
        parse_groups(",".join(extras.groups), allowed=allowed)  # refuses a group this run cannot fit
        return extras
    return OptionalTerms(parse_groups(extras, allowed=allowed)) if extras else NONE
