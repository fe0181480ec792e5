"""Rate profiles of a move: constant rate, trapezoid, or S-curve (jerk-limited).

A move turns by a signed angle. Its profile is cut into *pieces* of constant
jerk, so within a piece the angle is the cubic
``theta(tau) = theta_0 + rate_0 tau + accel_0 tau^2 / 2 + jerk tau^3 / 6``
and everything downstream (the nominal attitude, the simulator's exact
increments, the encoder angles, the command schedule) evaluates that
polynomial instead of a sampled curve.

- **constant**: the rate steps from 0 to the cruise rate in zero time (every
  sequence file without ``accel_dps2``; what the tool did before profiles).
- **trapezoid** (``accel_dps2``): constant acceleration up to the cruise
  rate, cruise, constant deceleration. A move too short to reach the cruise
  rate is a triangle with peak rate ``sqrt(angle * accel)``.
- **S-curve** (``accel_dps2`` and ``jerk_dps3``): the acceleration itself
  ramps at the jerk limit (seven pieces). A move too short to reach the
  cruise rate peaks lower; that peak is found by bisection to rounding.

The cruise rate stays ``rate_dps``, so a finite acceleration makes the move
longer than ``angle / rate`` by ``rate / accel`` (trapezoid) or
``rate / accel + accel / jerk`` (S-curve reaching both limits).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Pieces:
    """Constant-jerk pieces of one move, in order (SI, signed with the move).

    ``theta0[i]`` is the angle turned before piece ``i``; the rate and
    acceleration are continuous across pieces except for the constant
    profile's (and the trapezoid's acceleration) steps.
    """

    duration: np.ndarray
    theta0: np.ndarray
    rate0: np.ndarray
    accel0: np.ndarray
    jerk: np.ndarray

    @property
    def duration_s(self) -> float:
        return float(np.sum(self.duration))

    def angle(self, i: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Angle turned at time ``tau`` into piece ``i`` (rad)."""
        return (
            self.theta0[i] + self.rate0[i] * tau + 0.5 * self.accel0[i] * tau**2 + self.jerk[i] * tau**3 / 6.0
        )

    def rate(self, i: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Angular rate at ``tau`` into piece ``i`` (rad/s)."""
        return self.rate0[i] + self.accel0[i] * tau + 0.5 * self.jerk[i] * tau**2

    @property
    def peak_rate(self) -> float:
        ends = self.rate(np.arange(len(self.duration)), self.duration)
        return float(max(np.max(np.abs(self.rate0)), np.max(np.abs(ends))))

    @property
    def peak_accel(self) -> float:
        """Largest ``|acceleration|`` (rad/s^2); the constant profile's rate steps are infinite."""
        ends = self.accel0 + self.jerk * self.duration
        return float(max(np.max(np.abs(self.accel0)), np.max(np.abs(ends))))


@dataclass(frozen=True)
class RateProfile:
    """Limits a move is played with (SI): cruise rate, acceleration, jerk.

    ``accel = inf`` is the constant-rate profile; ``jerk = inf`` with a finite
    ``accel`` the trapezoid; both finite the S-curve.
    """

    rate: float
    accel: float = math.inf
    jerk: float = math.inf

    @property
    def kind(self) -> str:
        if math.isinf(self.accel):
            return "constant"
        return "trapezoid" if math.isinf(self.jerk) else "s-curve"

    def pieces(self, angle_rad: float) -> Pieces:
        """The constant-jerk pieces of a move by ``angle_rad`` (signed)."""
        A = abs(float(angle_rad))
        if self.kind == "constant":
            rows = [(A / self.rate, 0.0, self.rate, 0.0, 0.0)]
        elif self.kind == "trapezoid":
            rows = _trapezoid(A, self.rate, self.accel)
        else:
            rows = _s_curve(A, self.rate, self.accel, self.jerk)
        # A flip too small to take any time (angles that underflow) is one empty piece.
        rows = [r for r in rows if r[0] > 0.0] or [(0.0, 0.0, 0.0, 0.0, 0.0)]
        d, th, r, a, j = (np.array(c, dtype=float) for c in zip(*rows, strict=True))
        s = 1.0 if angle_rad >= 0 else -1.0
        return Pieces(duration=d, theta0=s * th, rate0=s * r, accel0=s * a, jerk=s * j)

    def duration_s(self, angle_rad: float) -> float:
        return self.pieces(angle_rad).duration_s


def _trapezoid(A: float, v: float, a: float) -> list[tuple]:
    if A >= v * v / a:
        ta = v / a
        cruise = A / v - v / a
        return [
            (ta, 0.0, 0.0, a, 0.0),
            (cruise, 0.5 * v * ta, v, 0.0, 0.0),
            (ta, A - 0.5 * v * ta, v, -a, 0.0),
        ]
    vp = math.sqrt(A * a)  # triangle: never reaches the cruise rate
    ta = vp / a
    return [(ta, 0.0, 0.0, a, 0.0), (ta, 0.5 * A, vp, -a, 0.0)]


def _s_ramp(vp: float, a: float, j: float) -> tuple[float, float, float]:
    """Jerk time, constant-acceleration time and peak acceleration of a ramp 0 -> ``vp``."""
    if vp <= a * a / j:
        tj = math.sqrt(vp / j)
        return tj, 0.0, j * tj
    return a / j, vp / a - a / j, a


def _s_ramp_angle(vp: float, a: float, j: float) -> float:
    tj, tc, _ = _s_ramp(vp, a, j)
    return 0.5 * vp * (2.0 * tj + tc)  # the ramp is symmetric about its middle: mean rate vp/2


def _s_curve(A: float, v: float, a: float, j: float) -> list[tuple]:
    vp = v
    if 2.0 * _s_ramp_angle(v, a, j) > A:
        lo, hi = 0.0, v  # the ramp angle grows with the peak rate: bisect to rounding
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if 2.0 * _s_ramp_angle(mid, a, j) <= A:
                lo = mid
            else:
                hi = mid
            if hi - lo <= 1e-15 * v:
                break
        vp = lo
    tj, tc, ap = _s_ramp(vp, a, j)
    ramp = [(tj, 0.0, 0.0, j), (tc, 0.5 * ap * tj, ap, 0.0), (tj, vp - 0.5 * ap * tj, ap, -j)]
    ramp_angle = _s_ramp_angle(vp, a, j)
    cruise = max(0.0, (A - 2.0 * ramp_angle) / vp)
    down = [(tj, vp, 0.0, -j), (tc, vp - 0.5 * ap * tj, -ap, 0.0), (tj, 0.5 * ap * tj, -ap, j)]
    rows, theta = [], 0.0
    for d, r, acc, jk in ramp + [(cruise, vp, 0.0, 0.0)] + down:
        rows.append((d, theta, r, acc, jk))
        theta += r * d + 0.5 * acc * d * d + jk * d**3 / 6.0
    return rows
