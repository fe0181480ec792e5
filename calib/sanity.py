"""Physical sanity checks of a run before calibrating it.

A log from the lab can carry degrees for radians, rates for increments, g
for m/s^2, clipped samples or a base that moved. Each of these would give
numbers that look valid and are not; each is refused here with what was
seen, where, and the likely cause.
"""
from __future__ import annotations

import math

import numpy as np

from .errors import CalibError

MAX_PLAUSIBLE_RATE = 5.0  # rad/s: 286 deg/s, beyond any calibration gimbal (the paper turns at 10)
MAX_REST_RATE = 1e-3  # rad/s: 14x the Earth rate, 200 deg/h of bias: beyond a navigation IMU
GRAVITY_TOLERANCE = 0.02  # relative: biases and scale errors stay far below 2 % of g
SATURATION_RUN = 10  # consecutive samples stuck at the same extreme value
REST_NOISE_FACTOR = 20.0  # a rest whose specific force varies 20x more than the noise moved


from .earth import MAX_LATITUDE_DEG  # noqa: F401  (one source: calib.earth)


def check_latitude(latitude_rad: float, where: str) -> None:
    """Refuse a site at the poles: the Earth rate there has no horizontal part to find north by."""
    if abs(math.degrees(latitude_rad)) > MAX_LATITUDE_DEG:
        raise CalibError(f"latitude {math.degrees(latitude_rad):.3f} deg is within "
                         f"{90 - MAX_LATITUDE_DEG:g} deg of a pole", where,
                         "stationary self-calibration needs the Earth rate's horizontal part "
                         "(W cos L) to find the heading; check the latitude_deg metadata")


def check_rates(dtheta: np.ndarray, dt: np.ndarray, where: str) -> None:
    """Refuse gyro data in degrees, or rates for increments (from magnitudes)."""
    rate = np.linalg.norm(dtheta, axis=1) / dt
    peak = float(rate.max())
    if peak > MAX_PLAUSIBLE_RATE:
        k = int(np.argmax(rate))
        raise CalibError(
            f"gyro increments imply {peak:.3g} rad/s at sample {k}, beyond any gimbal", where,
            "dtheta columns must be angle increments in rad: degrees (x57) or rates "
            f"instead of increments (x{1 / np.median(dt):.0f}) give this")


def check_rest_rate(dtheta: np.ndarray, dt: np.ndarray, rest: slice, where: str) -> None:
    """Refuse a first rest whose mean rate is far beyond Earth rate plus any plausible bias."""
    w = float(np.linalg.norm(dtheta[rest].sum(axis=0)) / dt[rest].sum())
    if w > MAX_REST_RATE:
        raise CalibError(f"the gyros read {w:.3g} rad/s at the first rest, {w / 7.292115e-5:.0f}x "
                         "the Earth rate", where,
                         "dtheta must be in rad: degrees (x57) give this, as do rates logged "
                         "as increments or a base that turns")


def check_gravity(dv: np.ndarray, dt: np.ndarray, rest: slice, gravity_mps2: float,
                  where: str) -> None:
    """Refuse dv in g, specific force for increments, or a site gravity far from the data."""
    f = float(np.linalg.norm(dv[rest].sum(axis=0)) / dt[rest].sum())
    ratio = f / gravity_mps2
    if abs(ratio - 1.0) > GRAVITY_TOLERANCE:
        fs = 1.0 / float(np.median(dt))
        if abs(f - 1.0) < 0.05:
            cause = "the dv columns look like g*s, not m/s (velocity increments must be in m/s)"
        elif abs(ratio / fs - 1.0) < 0.1:
            cause = "the dv columns look like specific force (m/s^2), not increments (m/s)"
        else:
            cause = ("check the units of dv, the gravity_mps2/latitude/height metadata, "
                     "and that the IMU was at rest")
        raise CalibError(f"specific force at the first rest is {f:.6g} m/s^2 but gravity at the "
                         f"site is {gravity_mps2:.6g} m/s^2 ({100 * (ratio - 1):+.2f} %)", where,
                         cause)


def check_saturation(dtheta: np.ndarray, dv: np.ndarray, where: str) -> None:
    """Refuse runs with channels stuck at their extreme value (clipping)."""
    for name, data in (("dtheta", dtheta), ("dv", dv)):
        for axis in range(3):
            x = data[:, axis]
            peak = np.max(np.abs(x))
            if peak == 0.0:
                continue
            at_peak = np.abs(x) == peak
            # Longest run of consecutive samples at the extreme value.
            edges = np.flatnonzero(np.diff(np.concatenate([[0], at_peak.astype(np.int8), [0]])))
            runs = edges[1::2] - edges[::2]
            if runs.size and runs.max() >= SATURATION_RUN:
                k = int(edges[::2][np.argmax(runs)])
                raise CalibError(f"{name}_{'xyz'[axis]} is stuck at {x[k]:.6g} for {int(runs.max())} "
                                 f"consecutive samples from sample {k}", where,
                                 "the sensor saturated or the logger repeated samples")


def check_rests(dv: np.ndarray, dt: np.ndarray, moving: np.ndarray, vrw: float, where: str,
                window: int = 50) -> None:
    """Refuse a rest whose specific force varies far more than the noise allows.

    Each rest is cut into windows of ``window`` samples; in each, the spread of
    sample-to-sample differences (robust: median absolute deviation) sees
    noise and vibration but not slow drifts or the Earth's turn.
    """
    edges = np.flatnonzero(np.diff(np.concatenate([[1], moving.astype(np.int8), [1]])))
    starts, ends = edges[::2], edges[1::2]
    t = np.cumsum(dt)
    for number, (a, b) in enumerate(zip(starts, ends), start=1):
        n = (b - a) // window
        if n == 0:
            continue
        f = (dv[a:a + n * window] / dt[a:a + n * window, None]).reshape(n, window, 3)
        d = np.diff(f, axis=1)
        spread = np.median(np.abs(d - np.median(d, axis=1, keepdims=True)), axis=1) / 0.6745
        spread = spread.max(axis=1) / math.sqrt(2.0)
        expected = vrw / math.sqrt(float(np.median(dt[a:b])))
        k = int(np.argmax(spread))
        if spread[k] > REST_NOISE_FACTOR * expected:
            t0 = t[a + k * window] - dt[a + k * window]
            raise CalibError(
                f"rest {number} ({t[a] - dt[a]:.1f}-{t[b - 1]:.1f} s) is not at rest: from "
                f"{t0:.1f} s the specific force varies by {spread[k]:.3g} m/s^2 per sample "
                f"against {expected:.3g} from the noise profile", where,
                "the base moved or vibrated; or the noise profile is far too optimistic")
