"""Scores of any calibration on a recording placed by hand, free of any tool's convention.

Each tool hands out its calibration in its own parametrisation (imu_tk's
``T K (raw - b)``, imucal's ``R^-1 K^-1 (raw - b)``, ours); read as a
:class:`calib.calibration.correction.Correction` (``calibrated = M (raw - b)``), each is
judged on the same static poses of the same log by what physics fixes whatever
the convention:

* **|g| spread**: at every pose, the magnitude of the calibrated specific force
  (the mean over the rest) is local gravity; its spread (std and max - min over
  the poses) is the accelerometer's error, blind to any rotation of the frame;
* **pose to pose**: the gravity direction at rest ``r`` (the calibrated mean
  specific force, normalised), carried through the calibrated gyro's rotation
  over the move to rest ``r + 1`` (the rule of :mod:`calib.hand.moves`:
  :func:`calib.hand.moves.move_rotation` on the compensated increments, from
  the end of rest ``r`` to the start of rest ``r + 1``), is the direction
  predicted at rest ``r + 1``; its angle to the measured one is the gyro's
  (and accelerometer's) error over the move. The Earth's turn over the move is
  left out: it moves the vertical by at most ``Omega cos(lat) T``, reported as
  :attr:`PoseToPose.earth_bound_deg`;
* **axes**: each raw channel's scale factor (SI per raw unit), the angles
  between the calibrated sensing axes less 90 deg, and the biases.

The sensing axis of raw channel ``i``: from ``raw - b = M^-1 c`` (``c`` the
calibrated vector), ``raw_i - b_i = s_i . c`` with ``s_i`` **row** ``i`` of
``M^-1``; channel ``i`` responds to the component of ``c`` along ``s_i``, with
``|s_i|`` raw units per SI unit. Its scale factor is ``1 / |s_i|``; a rotation
of the calibrated frame (``M -> Q M``) turns every ``s_i`` alike, leaving
both the scale factors and the angles between axes unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.calibration.correction import Correction, SensorCorrection
from calib.hand.moves import move_rotation
from calib.nav import earth
from calib.nav.strapdown import sample_intervals

ARCSEC_PER_RAD = 180.0 / math.pi * 3600.0
PAIRS = ((0, 1), (0, 2), (1, 2))


def rest_means(x: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Mean of the rows of ``(n, 3)`` ``x`` over each rest ``[start, end)``, shape ``(K, 3)``."""
    return np.array([x[a:b].mean(axis=0) for a, b in zip(start, end, strict=True)])


@dataclass(frozen=True)
class ForceSpread:
    """``|calibrated specific force|`` over the pose means, m/s^2.

    Attributes
    ----------
    magnitude : ndarray, shape (K,)
        At each rest.
    mean, std, range : float
        Over the rests (``range`` is max - min).
    """

    magnitude: np.ndarray
    mean: float
    std: float
    range: float


def force_spread(force: np.ndarray, start: np.ndarray, end: np.ndarray) -> ForceSpread:
    """The spread of ``|f|`` over the rests' means of calibrated specific force ``force`` (n, 3)."""
    mag = np.linalg.norm(rest_means(force, start, end), axis=1)
    return ForceSpread(mag, float(mag.mean()), float(mag.std()), float(mag.max() - mag.min()))


def angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle (rad) between the rows of ``u`` and ``v``, accurate at small angles."""
    u, v = np.atleast_2d(u), np.atleast_2d(v)
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))


@dataclass(frozen=True)
class PoseToPose:
    """The gyro's check from rest to rest.

    Attributes
    ----------
    angle_deg : ndarray, shape (K - 1,)
        Between the predicted and the measured gravity direction at each next
        rest; nan for a move left out (clipped).
    used : ndarray of bool, shape (K - 1,)
    turn_deg : ndarray, shape (K - 1,)
        The calibrated gyro's rotation angle over each move.
    earth_bound_deg : float
        The largest turn of the vertical by the Earth's rate over a used move, left out.
    rms_deg, max_deg : float
        Over the used moves.
    """

    angle_deg: np.ndarray
    used: np.ndarray
    turn_deg: np.ndarray
    earth_bound_deg: float
    rms_deg: float
    max_deg: float


@dataclass(frozen=True)
class RestSpans:
    """Where a recording rests, as the scores read it (the same rests for every tool).

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample ends, s (each rate times its interval is the sample's increment).
    start, end : ndarray of int, shape (K,)
        The rests, ``[start, end)`` (:func:`calib.hand.rests.find_rests`).
    clipped : ndarray of bool, shape (n,), optional
        Samples at the sensor's range: a move holding one is left out.
    latitude_deg : float
        Only for the bound on the Earth's turn that is left out.
    """

    time_s: np.ndarray
    start: np.ndarray
    end: np.ndarray
    clipped: np.ndarray | None = None
    latitude_deg: float = 0.0


def pose_to_pose(rate: np.ndarray, force: np.ndarray, rests: RestSpans) -> PoseToPose:
    """Gravity at each rest carried to the next by the calibrated gyro, against the one measured there.

    Parameters
    ----------
    rate, force : ndarray, shape (n, 3)
        Calibrated rates (rad/s) and specific force (m/s^2).
    rests : RestSpans
        The sample ends, the rests, the clipped samples and the latitude.
    """
    start, end, clipped = rests.start, rests.end, rests.clipped
    dt = sample_intervals(np.asarray(rests.time_s, dtype=float))
    dth = rate * dt[:, None]
    up = rest_means(force, start, end)
    up = up / np.linalg.norm(up, axis=1, keepdims=True)
    k = len(start) - 1
    angle, turn, used = np.full(k, np.nan), np.zeros(k), np.ones(k, dtype=bool)
    bound = 0.0
    for r in range(k):
        a, b = int(end[r]), int(start[r + 1])
        if clipped is not None and np.any(clipped[a:b]):
            used[r] = False
            continue
        R, _, _ = move_rotation(dth[a:b], dth[a - 1] if a > 0 else np.zeros(3))
        # C(end) = C(start) R in a fixed frame: the vertical in the body turns by R^T.
        angle[r] = math.degrees(angle_between(R.T @ up[r], up[r + 1])[0])
        turn[r] = math.degrees(math.acos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))
        horizontal = earth.RATE * math.cos(math.radians(rests.latitude_deg))
        bound = max(bound, math.degrees(horizontal * float(dt[a:b].sum())))
    ok = angle[used]
    rms = float(np.sqrt(np.mean(ok**2))) if ok.size else math.nan
    return PoseToPose(angle, used, turn, bound, rms, float(ok.max()) if ok.size else math.nan)


@dataclass(frozen=True)
class Axes:
    """One triad's axes, free of convention.

    Attributes
    ----------
    scale : ndarray, shape (3,)
        SI per raw unit of each channel (``1 / |row i of M^-1|``).
    nonorthogonality_arcsec : ndarray, shape (3,)
        Angle between the sensing axes x-y, x-z, y-z, less 90 deg.
    bias_raw : ndarray, shape (3,)
        ``b``, raw units.
    bias_si : ndarray, shape (3,)
        ``(b - zero) * scale``: the bias in SI against the raw zero of a nominal conversion.
    """

    scale: np.ndarray
    nonorthogonality_arcsec: np.ndarray
    bias_raw: np.ndarray
    bias_si: np.ndarray


def sensing_axes(M: np.ndarray) -> np.ndarray:
    """Row ``i``: raw channel ``i``'s sensing direction in the calibrated frame, raw per SI (``M^-1``)."""
    return np.linalg.inv(np.asarray(M, dtype=float))


def axes_of(sensor: SensorCorrection, zero: np.ndarray | None = None) -> Axes:
    """Scale factors, non-orthogonalities and biases of one triad's ``M (raw - b)``."""
    s = sensing_axes(sensor.M)
    norm = np.linalg.norm(s, axis=1)
    scale = 1.0 / norm
    u = s / norm[:, None]
    angles = np.array([math.acos(np.clip(u[i] @ u[j], -1.0, 1.0)) - math.pi / 2 for i, j in PAIRS])
    z = np.zeros(3) if zero is None else np.asarray(zero, dtype=float)
    return Axes(scale, angles * ARCSEC_PER_RAD, np.asarray(sensor.b, dtype=float), (sensor.b - z) * scale)


@dataclass(frozen=True)
class HandScore:
    """The scores of one calibration on one recording's rests."""

    spread: ForceSpread
    poses: PoseToPose
    gyro: Axes
    accel: Axes
    source: str = ""


def score(
    correction: Correction,
    raw_gyro: np.ndarray,
    raw_accel: np.ndarray,
    rests: RestSpans,
    raw_zero: tuple[np.ndarray | None, np.ndarray | None] = (None, None),
) -> HandScore:
    """Score a correction on raw samples and given rests (the same rests for every tool).

    Parameters
    ----------
    correction : Correction
        The calibration, in the raw samples' units.
    raw_gyro, raw_accel : ndarray, shape (n, 3)
        Raw rates and specific force, as logged (counts, deg/s, ...).
    rests : RestSpans
        The sample ends, the rests, the clipped samples (their moves are left out) and the
        latitude.
    raw_zero : (ndarray or None, ndarray or None), each shape (3,)
        The gyro's and the accelerometer's raw zero of a nominal conversion, for the biases in SI.

    Returns
    -------
    HandScore
    """
    rate, force = correction.apply(raw_gyro, raw_accel)
    gyro_zero, accel_zero = raw_zero
    return HandScore(
        force_spread(force, rests.start, rests.end),
        pose_to_pose(rate, force, rests),
        axes_of(correction.gyro, gyro_zero),
        axes_of(correction.accel, accel_zero),
        correction.source,
    )
