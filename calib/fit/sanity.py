"""Physical sanity checks of a run before calibrating it.

A log from the lab can carry degrees for radians, rates for increments, g
for m/s^2, clipped samples or a base that moved. Each of these would give
numbers that look valid and are not; each is refused here with what was
seen, where, and the likely cause.
"""

from __future__ import annotations

import math

import numpy as np

from calib.errors import CalibError
from calib.nav.earth import MAX_LATITUDE_DEG  # one source: calib.nav.earth
from calib.sequence.motion import MOTION_BLOCK, row_norm, runs_of

MAX_PLAUSIBLE_RATE = 5.0  # rad/s: 286 deg/s, beyond any calibration gimbal (the paper turns at 10)
MAX_REST_RATE = 1e-3  # rad/s: 14x the Earth rate, 200 deg/h of bias: beyond a navigation IMU
GRAVITY_TOLERANCE = 0.02  # relative: biases and scale errors stay far below 2 % of g
SATURATION_RUN = 10  # consecutive samples stuck at the same extreme value
STILL_RELATIVE = 1e-9  # changes below this fraction of a sensor's peak reading are float rounding
REST_NOISE_FACTOR = 20.0  # a rest whose specific force varies 20x more than the noise moved


def check_latitude(latitude_rad: float, where: str) -> None:
    """Refuse a site at the poles: the Earth rate there has no horizontal part to find north by."""
    if abs(math.degrees(latitude_rad)) > MAX_LATITUDE_DEG:
        raise CalibError(
            f"latitude {math.degrees(latitude_rad):.3f} deg is within "
            f"{90 - MAX_LATITUDE_DEG:g} deg of a pole",
            where,
            "stationary self-calibration needs the Earth rate's horizontal part "
            "(W cos L) to find the heading; check the latitude_deg metadata",
        )


class GyroUnitError(CalibError):
    """A gyro reading beyond what the unit can show: most often a unit in degrees read as radians.

    ``rate`` is what the gyros read (rad/s) and ``limit`` the most that is
    plausible there, so that :func:`explain_gyro_unit` can tell, for a log whose
    gyro came from rate columns, whether the same numbers in deg/s would fit.
    """

    def __init__(
        self,
        what: str,
        where: str | None = None,
        fix: str | None = None,
        rate: float = 0.0,
        limit: float = 0.0,
    ):  # defaults: an error pickled to another process comes back from its message alone
        super().__init__(what, where, fix)
        self.rate, self.limit = rate, limit


def explain_gyro_unit(error: GyroUnitError, gyro_columns) -> CalibError:
    """``error`` told in the terms of the file's gyro columns, when they were rates.

    ``gyro_columns`` is a run's ``gyro_columns``: ``(file's name, read as)`` of
    x, y, z, or None. A refusal about increments (``dtheta`` columns) means
    nothing to a file of rates: for rate columns read as rad/s, numbers that
    would be plausible in deg/s are named as such, with the names to give.
    """
    if not gyro_columns or not all(read.startswith("gyro_") for _, read in gyro_columns):
        return error
    files = ", ".join(name for name, _ in gyro_columns)
    radps = all(read.endswith("_radps") for _, read in gyro_columns)
    if radps and error.rate * math.radians(1.0) <= error.limit:
        renamed = [(name, read.removesuffix("_radps") + "_dps") for name, read in gyro_columns]
        if any(name != read for name, read in gyro_columns):  # a column map renamed them
            to = "map " + ",".join(f"{name}={new}" for name, new in renamed)
        else:
            to = "name them " + ", ".join(new for _, new in renamed)
        fix = f"the gyro columns {files} look like deg/s (57x rad/s): {to}"
    else:
        fix = (
            f"check the unit of the gyro columns {files} (gyro_<axis>_radps for rad/s, _dps for "
            "deg/s) and that the IMU was at rest"
        )
    return CalibError(error.what, error.where, fix)


def check_rates(
    dtheta: np.ndarray, dt: np.ndarray, where: str, max_rate_rad_s: float | None = MAX_PLAUSIBLE_RATE
) -> None:
    """Refuse gyro data in degrees, or rates for increments (from magnitudes).

    ``max_rate_rad_s`` is the fastest plausible turn: a gimbal's by default
    (``MAX_PLAUSIBLE_RATE``); a run turned by hand reaches 1000-2000 deg/s
    within its sensor's range, so its caller gives that range (e.g.
    ``run.conversion.range_si("gyro")``'s norm) or None to switch the check off.
    """
    if max_rate_rad_s is None:
        return
    rate = row_norm(dtheta) / dt
    peak = float(rate.max())
    if peak > max_rate_rad_s:
        k = int(np.argmax(rate))
        raise GyroUnitError(
            f"gyro increments imply {peak:.3g} rad/s at sample {k}, beyond any gimbal",
            where,
            "dtheta columns must be angle increments in rad: degrees (x57) or rates "
            f"instead of increments (x{1 / np.median(dt):.0f}) give this",
            peak,
            max_rate_rad_s,
        )


# A unit's biases before calibration are at most this many times what its calibration must
# reach: 100 x the requirement (navigation grade: 3 deg/h against 0.03; MEMS: 3000 deg/h and
# 100 mg against 30 deg/h and 1 mg). The checks below allow that much, and no more.
CLASS_FACTOR = 100.0


def check_rest_rate(
    dtheta: np.ndarray, dt: np.ndarray, rest: slice, where: str, gyro_bias_requirement: float = 0.0
) -> None:
    """Refuse a first rest whose mean rate is far beyond Earth rate plus any plausible bias.

    The plausible bias follows the unit's class: ``CLASS_FACTOR`` times its
    gyro bias requirement (rad/s), and at least ``MAX_REST_RATE``.
    """
    w = float(np.linalg.norm(dtheta[rest].sum(axis=0)) / dt[rest].sum())
    limit = max(MAX_REST_RATE, CLASS_FACTOR * gyro_bias_requirement)
    if w > limit:
        raise GyroUnitError(
            f"the gyros read {w:.3g} rad/s at the first rest, {w / 7.292115e-5:.0f}x the Earth rate",
            where,
            "dtheta must be in rad: degrees (x57) give this, as do rates logged "
            "as increments or a base that turns",
            w,
            limit,
        )


def check_gravity(
    dv: np.ndarray, dt: np.ndarray, rest: slice, gravity_mps2: float, where: str, accel_class: float = 0.0
) -> None:
    """Refuse dv in g, specific force for increments, or a site gravity far from the data.

    ``accel_class`` is the unit's plausible relative error of a specific force
    before calibration (bias over g plus scale factor, from its requirements
    times ``CLASS_FACTOR``); the tolerance is at least ``GRAVITY_TOLERANCE``.
    A log in g (a factor 9.8) is refused whatever the class.
    """
    f = float(np.linalg.norm(dv[rest].sum(axis=0)) / dt[rest].sum())
    ratio = f / gravity_mps2
    if abs(ratio - 1.0) > min(0.5, max(GRAVITY_TOLERANCE, accel_class)):
        fs = 1.0 / float(np.median(dt))
        if abs(f - 1.0) < 0.05:
            cause = "the dv columns look like g*s, not m/s (velocity increments must be in m/s)"
        elif abs(ratio / fs - 1.0) < 0.1:
            cause = "the dv columns look like specific force (m/s^2), not increments (m/s)"
        else:
            cause = (
                "check the units of dv, the gravity_mps2/latitude/height metadata, "
                "and that the IMU was at rest"
            )
        raise CalibError(
            f"specific force at the first rest is {f:.6g} m/s^2 but gravity at the "
            f"site is {gravity_mps2:.6g} m/s^2 ({100 * (ratio - 1):+.2f} %)",
            where,
            cause,
        )


def _still_level(data: np.ndarray, peaks: np.ndarray) -> float | None:
    """Changes of a sensor below this are float rounding; None for a sensor without noise.

    ``peaks`` are the channels' largest magnitudes. Any real quantum is at
    least 1e-6 of the sensor's largest reading, so changes below
    ``STILL_RELATIVE`` of it are rounding of an exact simulation. A
    noise-free sensor (its typical second difference at rounding level) is
    not judged: in a noise-free log a constant-rate flip is a flat top too,
    and clipping cannot be told from it.
    """
    still = STILL_RELATIVE * float(peaks.max())
    n = len(data)
    if n < 3:
        return None
    # Largest |second difference| of the three channels per sample, a block at a time.
    d2max = np.empty(n - 2)
    for a in range(0, n - 2, MOTION_BLOCK):
        d2 = np.abs(np.diff(data[a : a + MOTION_BLOCK + 2], 2, axis=0))
        d2max[a : a + len(d2)] = np.maximum(np.maximum(d2[:, 0], d2[:, 1]), d2[:, 2])
    return None if np.median(d2max) <= still else still


def _saturated_stretch(data: np.ndarray, axis: int, peak: float, still: float) -> tuple[int, int] | None:
    """The first stretch where channel ``axis`` is pinned at its extreme while the sensor moves.

    A clipped channel sits at its range limit while the true signal goes on:
    its noise vanishes while the sensor's other channels keep changing. A
    noise-free or quantised channel at rest also repeats one value (often its
    extreme, gravity being the largest specific force a static run sees), but
    then either the whole sensor is still or the value is the channel's
    ordinary reading (its median).
    """
    if peak == 0.0:
        return None
    x = data[:, axis]
    others = [i for i in range(data.shape[1]) if i != axis]
    typical = None  # the median costs a sort of the channel: only when a stretch is found
    for a, b in zip(*runs_of((x == peak) | (x == -peak)), strict=True):
        if b - a < SATURATION_RUN:
            continue
        typical = float(np.median(x)) if typical is None else typical
        if x[a] == typical:
            continue
        if np.max(np.ptp(data[a:b][:, others], axis=0)) > still:
            return int(a), int(b)
    return None


def check_saturation(dtheta: np.ndarray, dv: np.ndarray, where: str) -> None:
    """Refuse runs with a channel clipped: pinned at its extreme while the sensor moves."""
    for name, data in (("dtheta", dtheta), ("dv", dv)):
        # |x| at its largest, without a copy of |data|.
        peaks = np.array([np.maximum(data[:, i].max(), -data[:, i].min()) for i in range(3)])
        still = _still_level(data, peaks)  # once per sensor, not once per channel
        if still is None:
            continue
        for axis in range(3):
            found = _saturated_stretch(data, axis, float(peaks[axis]), still)
            if found is None:
                continue
            a, b = found
            raise CalibError(
                f"{name}_{'xyz'[axis]} is stuck at {data[a, axis]:.6g}, its extreme, "
                f"for {b - a} consecutive samples from sample {a} while the other "
                f"{name} channels change",
                where,
                "the sensor saturated (clipped at its range) or the logger repeated one channel",
            )


def _row_median(x: np.ndarray) -> np.ndarray:
    """``np.median(x, axis=-1)``, the same values; an odd count by one partition.

    np.median costs six times more on short rows (it also checks for NaN,
    which this one does only when there is one).
    """
    k = x.shape[-1] // 2
    if x.shape[-1] % 2 == 0 or np.isnan(x).any():
        return np.median(x, axis=-1)
    return np.partition(x, k, axis=-1)[..., k]


def check_rests(
    dv: np.ndarray, dt: np.ndarray, moving: np.ndarray, vrw: float, where: str, window: int = 50
) -> None:
    """Refuse a rest whose specific force varies far more than the noise allows.

    Each rest is cut into windows of ``window`` samples; in each, the spread of
    sample-to-sample differences (robust: median absolute deviation) sees
    noise and vibration but not slow drifts or the Earth's turn.
    """
    starts, ends = runs_of(~moving)
    t = np.cumsum(dt)
    for number, (a, b) in enumerate(zip(starts, ends, strict=True), start=1):
        n = (b - a) // window
        if n == 0:
            continue
        # (window, axis, sample) with the samples contiguous: the medians run along rows.
        f = np.ascontiguousarray(
            (dv[a : a + n * window] / dt[a : a + n * window, None]).reshape(n, window, 3).transpose(0, 2, 1)
        )
        d = np.diff(f, axis=2)
        spread = _row_median(np.abs(d - _row_median(d)[..., None])) / 0.6745
        spread = spread.max(axis=1) / math.sqrt(2.0)
        expected = vrw / math.sqrt(float(np.median(dt[a:b])))
        k = int(np.argmax(spread))
        if spread[k] > REST_NOISE_FACTOR * expected:
            t0 = t[a + k * window] - dt[a + k * window]
            raise CalibError(
                f"rest {number} ({t[a] - dt[a]:.1f}-{t[b - 1]:.1f} s) is not at rest: from "
                f"{t0:.1f} s the specific force varies by {spread[k]:.3g} m/s^2 per sample "
                f"against {expected:.3g} from the noise profile",
                where,
                "the base moved or vibrated; or the noise profile is far too optimistic",
            )
