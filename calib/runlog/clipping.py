"""Clipping: samples a sensor gave at (or next to) the end of its range, named by stretch.

A hand-turned IMU can turn faster than its gyro measures. The reading then
sits at the range's end while the true rate goes on: the increments there
are wrong by an unknown amount. Three signs, each per axis:

- **the converter's limits**: a raw count at the lowest or highest count the
  converter has (0 or 65535 for unsigned 16 bits, or the conversion's
  ``range_counts``);
- **a flat top**: two or more consecutive gyro samples exactly at the axis's
  largest value (each sign apart), when that is at least ``FLAT_TOP_RAD_S`` (no gimbal
  turns that fast; a hand does); from ``LOW_RANGE_RAD_S`` up (a gyro of range 125 or
  250 deg/s clips a hand's turn), only when steep ramps enter and leave it
  (:func:`steep_sided`): a saturated converter repeats its last count exactly, while a
  smooth or constant-rate top in noise does not, or not with a ramp beside it; readings
  printed in coarse steps (:data:`COARSE_STEP`) repeat a smooth top by their rounding, so
  there too only with steep sides, judged a step deep;
- **a plateau**: ``PLATEAU_RUN`` or more consecutive gyro samples within
  ``PLATEAU_BAND`` of that largest magnitude (a sensor saturating before its
  converter does, with its noise on top), under the same condition, entered
  and left by ramps steeper than a smooth peak's (:func:`steep_sided`).

The mask (``Run.clipped``, ``(n, 6)``: gyro x, y, z, accel x, y, z) says
which samples; :func:`describe_clipping` names each stretch
("gyro x clipped from 511.08 s to 511.70 s (33 samples)").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError
from calib.sequence.motion import runs_of

from .coarse import reading_step
from .columns import QUANTITIES, SensorColumns
from .conversion import Conversion

FLAT_TOP_RAD_S = 5.0  # rad/s (286 deg/s): beyond a calibration gimbal, within a hand's turn
FLAT_TOP_RUN = 2  # consecutive samples exactly at the largest magnitude
# The smallest full scale of MEMS gyros is 125 deg/s (2.18 rad/s); a hand turning 90 deg in a
# second peaks at about 140 deg/s, a gimbal's flip at 10 deg/s (spec default).
LOW_RANGE_RAD_S = 1.5
# Readings printed in steps this coarse against the top (a gyro in whole deg/s at 361 deg/s: 0.0028)
# repeat at a smooth peak by their rounding: a flat top there is clipping only with steep sides
# too, judged a step deep. A 16-bit converter's count is 3e-5 of its range.
COARSE_STEP = 1e-3
PLATEAU_BAND = 0.01  # relative to the largest magnitude
PLATEAU_RUN = 5  # consecutive samples within the band
# A smooth peak's slope beside its band, times the band's half-width, is about 3 band depths
# (`steep_sided`; 0.7-3.5 measured on simulated turns, noise included); a clipped ramp's is
# tens (the Xsens recording's: 13-183, each stretch's gentler side).
PLATEAU_STEEPNESS = 6.0
MERGE_S = 0.5  # clipped samples this close are one stretch
CHANNELS = tuple(f"{sensor} {axis}" for sensor in ("gyro", "accel") for axis in "xyz")


@dataclass(frozen=True)
class ClipStretch:
    """One stretch of clipped samples on one channel.

    Attributes
    ----------
    channel : str
        ``"gyro x"`` ... ``"accel z"``.
    start, stop : int
        First sample and one past the last.
    start_s, end_s : float
        ``time_s`` of the first and the last clipped sample.
    samples : int
        How many samples in the stretch are clipped.
    """

    channel: str
    start: int
    stop: int
    start_s: float
    end_s: float
    samples: int

    def describe(self) -> str:
        """``"gyro x clipped from 511.08 s to 511.70 s (33 samples)"``."""
        return (
            f"{self.channel} clipped from {self.start_s:.2f} s to {self.end_s:.2f} s "
            f"({self.samples} sample{'s' if self.samples != 1 else ''})"
        )


def at_limits(counts: np.ndarray, range_counts: tuple[float, float], where: str, sensor: str) -> np.ndarray:
    """``(n, 3)`` bool: raw counts at the converter's lowest or highest count.

    A count beyond them cannot come from that converter: the range is wrong (most often a signed
    converter's negative counts under the unsigned default), and every such sample would pass
    for clipped. Refused, naming the first.
    """
    low, high = range_counts
    beyond = (counts < low) | (counts > high)
    if beyond.any():
        k, axis = (int(i) for i in np.argwhere(beyond)[0])
        signed = "; a signed converter reads below 0" if counts[k, axis] < 0 <= low else ""
        raise CalibError(
            f"{sensor} {'xyz'[axis]} reads {counts[k, axis]:g} counts at sample {k}, beyond the "
            f"conversion's range_counts [{low:g}, {high:g}] ({int(beyond.sum())} such counts){signed}",
            where,
            "give the converter's limits as range_counts at the top of a TOML conversion (imu_tk's text "
            "states none), e.g. range_counts = [-32768, 32767] for a signed 16-bit one",
        )
    return (counts <= low) | (counts >= high)


def flat_top(
    rate: np.ndarray, threshold: float = FLAT_TOP_RAD_S, low_range: float = LOW_RANGE_RAD_S
) -> np.ndarray:
    """``(n, 3)`` bool: gyro samples at a flat top or plateau of their axis (module docstring).

    Parameters
    ----------
    rate : numpy.ndarray
        ``(n, 3)`` rates, rad/s (or any values with the same zero: only
        magnitudes relative to the axis's largest and the thresholds matter).
    threshold : float
        The largest magnitude from which flat tops and plateaus are judged, rad/s.
    low_range : float
        The largest magnitude from which a flat top with steep sides is judged, rad/s.
    """
    mask = np.zeros(rate.shape, dtype=bool)
    for axis in range(rate.shape[1]):
        step = reading_step(rate[:, axis]) if len(rate) else 0.0
        for sign in (1.0, -1.0):  # each end of the range on its own: they need not be symmetric
            size = sign * rate[:, axis]
            peak = float(size.max()) if len(size) else 0.0
            if not peak >= min(threshold, low_range):
                continue
            fast = peak >= threshold and step < COARSE_STEP * peak
            depth = max(PLATEAU_BAND * peak, step)
            for a, b in zip(*runs_of(size == peak), strict=True):
                if b - a >= FLAT_TOP_RUN and (fast or steep_sided(size, a, b, depth)):
                    mask[a:b, axis] = True
            if peak < threshold:
                continue
            for a, b in zip(*runs_of(size >= (1.0 - PLATEAU_BAND) * peak), strict=True):
                if b - a >= PLATEAU_RUN and steep_sided(size, a, b, depth):
                    mask[a:b, axis] = True
    return mask


def steep_sided(size: np.ndarray, a: int, b: int, depth: float) -> bool:
    """Whether the samples ``a:b`` at the top of ``size`` are a plateau, not a smooth peak.

    A smooth peak ``P - k t^2`` stays within ``depth`` of its top for a half-width
    ``w = sqrt(depth / k)``; beside the band, over a further ``w``, it falls at a mean slope
    ``3 k w``, so slope times ``w`` is about ``3 depth`` whatever the sample rate (counted
    in samples both). A sensor that saturates flattens a ramp that went on rising: beside
    its plateau the slope is the ramp's, many band depths over the plateau's half-width.
    Both sides must be steep, as a saturation's are (the true rate rises through the band
    and later falls back through it); a side the record does not hold is not asked. Noise
    then has to steepen both sides of a smooth peak to make a plateau of it.
    A turn cut less than about two band depths below its true peak looks like a smooth
    peak this way and is not flagged: its increments lose at most that cap's area, and
    the move's residual (its weight, calib.hand.weights) is what then says so.
    """
    half = 0.5 * (b - a)
    span = max(1, round(half))
    slopes = []
    if a - span >= 0:
        slopes.append((size[a] - size[a - span]) / span)
    if b - 1 + span < len(size):
        slopes.append((size[b - 1] - size[b - 1 + span]) / span)
    if not slopes:  # the whole record at its top: nothing beside to tell a peak by
        return True
    return min(slopes) * half > PLATEAU_STEEPNESS * depth


def sensor_clipping(
    raw: np.ndarray, sensor: SensorColumns, conversion: Conversion | None, dt: float, where: str = ""
) -> np.ndarray:
    """``(n, 3)`` bool: a sensor's samples clipped, from its columns as the file gives them.

    Raw counts are judged at the converter's limits (``conversion.range_counts``);
    the gyro, in any unit, also by its flat tops and plateaus (`flat_top`) in rad/s
    (increments over the nominal period ``dt``).
    """
    kind = QUANTITIES[sensor.quantity][0]
    mask = np.zeros(raw.shape, dtype=bool)
    if sensor.is_counts and conversion is not None:
        mask |= at_limits(raw, conversion.range_counts, where, kind)
        si = conversion.to_si(raw, kind)
    else:
        with np.errstate(over="ignore"):  # a value near 1e308: inf here, refused as not finite later
            si = raw * np.asarray(sensor.si_per_unit) / (1.0 if sensor.is_rate else dt)
    if kind == "gyro":
        mask |= flat_top(si)
    return mask


def clip_mask(gyro: np.ndarray | None, accel: np.ndarray | None, n: int) -> np.ndarray | None:
    """The ``(n, 6)`` mask of a run from its sensors' ``(n, 3)`` masks; None when nothing is clipped."""
    mask = np.zeros((n, 6), dtype=bool)
    if gyro is not None:
        mask[:, :3] = gyro
    if accel is not None:
        mask[:, 3:] = accel
    return mask if mask.any() else None


def clipped_stretches(clipped: np.ndarray | None, time_s: np.ndarray) -> list[ClipStretch]:
    """Each stretch of clipped samples per channel, samples under ``MERGE_S`` apart joined."""
    if clipped is None:
        return []
    out = []
    for channel in range(clipped.shape[1]):
        rows = np.flatnonzero(clipped[:, channel])
        if not rows.size:
            continue
        cuts = np.flatnonzero(np.diff(time_s[rows]) > MERGE_S) + 1
        for group in np.split(rows, cuts):
            a, b = int(group[0]), int(group[-1])
            out.append(
                ClipStretch(CHANNELS[channel], a, b + 1, float(time_s[a]), float(time_s[b]), len(group))
            )
    return sorted(out, key=lambda s: (s.start, s.channel))


def describe_clipping(run) -> list[str]:
    """One line per clipped stretch of ``run`` (a `calib.runlog.Run`), in time order; [] for none."""
    return [s.describe() for s in clipped_stretches(run.clipped, run.time_s)]
