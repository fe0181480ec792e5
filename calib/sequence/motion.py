"""Where a run turns: the one motion rule of the estimator, the chunked path and the viewer.

A sample turns when the gyros' rate exceeds :data:`MOTION_THRESHOLD`, judged
sample by sample for a navigation-grade gyro and on windowed rates less the
steady rate for a noisy or strongly biased one (:func:`detect_motion`); the
turning stretches are grown by a few samples (:func:`grow`). A sequence file
can say instead where the run turns (:func:`sequence_motion`), checked
against the gyros (:func:`check_sequence_matches`). :func:`runs_of` is the one
"stretches of a mask" of the package, and :func:`diagnose_motion` tells a
flip from a swaying base.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError

from .definition import timeline

MOTION_THRESHOLD = 0.01  # rad/s: far above Earth rate + bias + noise, far below a flip
# A flip turns the IMU by tens of degrees; the spurious "turns" of a noisy static log (a MEMS
# gyro's noise and bias drift over the few seconds a window flags) by tenths of a degree.
MIN_TURN_DEG = 5.0
MOTION_BLOCK = 1 << 16  # samples per block of the motion diagnosis (its memory, not its result)


def runs_of(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) of each stretch of consecutive True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return edges[::2], edges[1::2]


def row_norm(a: np.ndarray) -> np.ndarray:
    """``|a_i|`` of each row of an ``(n, 3)`` array.

    Bit-identical to ``np.linalg.norm(a, axis=1)`` (the same three squares
    summed in the same order) and about ten times faster: numpy reduces a
    3-wide axis one row at a time.
    """
    x, y, z = a[:, 0], a[:, 1], a[:, 2]
    return np.sqrt(x * x + y * y + z * z)


def sample_motion(dtheta: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Per sample, whether its own rate exceeds the threshold (a navigation-grade gyro's rule)."""
    return row_norm(dtheta) / dt > MOTION_THRESHOLD


@dataclass(frozen=True)
class Segmentation:
    """Which samples are turning, and the first rest used for alignment."""

    moving: np.ndarray  # (n,) bool
    first_rest_end: int  # samples [0, first_rest_end) are the first rest


def grow(moving: np.ndarray, samples: int = 2) -> np.ndarray:
    """Widen turning stretches by ``samples`` each side: partial samples at a flip's ends turn too."""
    grown = moving.copy()
    for s in range(1, samples + 1):
        grown[s:] |= moving[:-s]
        grown[:-s] |= moving[s:]
    return grown


def motion_window(arw: float, period_s: float) -> int:
    """Samples to average a gyro of ``arw`` (rad/sqrt(s)) over: its noise 5x below the threshold."""
    return max(1, int(math.ceil((5.0 * arw / MOTION_THRESHOLD) ** 2 / period_s)))


def windowed_motion(window: int, steady: np.ndarray) -> bool:
    """Whether motion is judged on windowed rates less the ``steady`` rate (noise or a MEMS bias)."""
    return window > 1 or float(np.linalg.norm(steady)) > 0.1 * MOTION_THRESHOLD


def window_rate(
    angle: np.ndarray, clock: np.ndarray, i: np.ndarray, n: int, window: int, offset: int = 0
) -> np.ndarray:
    """Mean rate (norm) over the window about each sample ``i`` of a run of ``n`` samples.

    ``angle`` (m, 3) and ``clock`` (m,) are the running sums of the steady-free
    increments and of the intervals, ``angle[j - offset]`` being the sum of the
    first ``j`` samples: a whole run (``offset`` 0) or the part of it a stream holds.
    """
    half = window // 2
    lo = np.clip(i - half, 0, n) - offset
    hi = np.clip(i + window - half, 0, n) - offset
    return np.linalg.norm(angle[hi] - angle[lo], axis=1) / (clock[hi] - clock[lo])


def detect_motion(dtheta: np.ndarray, dt: np.ndarray, where: str = "run", arw: float = 0.0) -> Segmentation:
    """Rest/rotation segments from the gyro increments alone.

    A noisy gyro (``arw``, rad/sqrt(s)) is averaged over a window long enough
    for its noise to stay five times below the motion threshold, and a large
    constant rate (a MEMS bias) is removed first; a navigation-grade gyro is
    judged sample by sample, as before.
    """
    window = motion_window(arw, float(np.median(dt)))
    # Rests dominate a calibration run. Column by column: one whole-run temporary, not four.
    steady = steady_rate(dtheta, dt)
    if windowed_motion(window, steady):
        rate_vec = dtheta / dt[:, None]
        angle = np.cumsum(np.vstack([np.zeros((1, 3)), (rate_vec - steady) * dt[:, None]]), axis=0)
        clock = np.concatenate([[0.0], np.cumsum(dt)])
        rate = window_rate(angle, clock, np.arange(len(dt)), len(dt), window)
        grown = grow(rate > MOTION_THRESHOLD, 2 + window)
    else:
        grown = grow(sample_motion(dtheta, dt))
    motion = diagnose_motion(dtheta, dt, MOTION_THRESHOLD)
    angles = turn_angles(dtheta, dt, grown, steady)
    turn = float(angles.max()) if angles.size else 0.0
    # Vibration or quantisation spikes alone are no flip, nor is a MEMS bias (a steady rate
    # beyond the threshold) with noise that a window flags here and there.
    if not motion.has_flip or turn < math.radians(MIN_TURN_DEG):
        raise never_rotates(motion, where, turn)
    # The first rest ends where the first real turn starts: a noise burst within it (a MEMS
    # gyro's, 0.1 deg over 0.3 s) cut a 10-s first rest to 0.2-7 s and the run was refused as
    # too short to align (5 runs in 50 of designed-15min under `mems`).
    starts = runs_of(grown)[0]
    first = int(starts[np.argmax(angles >= math.radians(MIN_TURN_DEG))])
    return Segmentation(moving=grown, first_rest_end=first)


def turn_angles(dtheta: np.ndarray, dt: np.ndarray, moving: np.ndarray, steady: np.ndarray) -> np.ndarray:
    """The largest angle (rad) the IMU turns through within each stretch between rests.

    The rate less the ``steady`` one (Earth rate and bias, rad/s) is integrated
    from the start of each turning stretch; the largest angle reached counts, so a
    turn there and back within one stretch counts too.
    """
    out = [
        float(np.max(row_norm(np.cumsum(dtheta[a:b] - steady * dt[a:b, None], axis=0))))
        for a, b in zip(*runs_of(moving), strict=True)
    ]
    return np.array(out)


def steady_rate(dtheta: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Per axis, the median rate (rad/s): at rest, where a calibration run spends most of its time."""
    return np.array([np.median(dtheta[:, i] / dt) for i in range(3)])


def log_turns(dtheta: np.ndarray, dt: np.ndarray, arw: float, where: str) -> np.ndarray:
    """Where the log turns, judged as the fit judges it (the profile's ``arw``), without the
    stretches that turn by less than :data:`MIN_TURN_DEG` (a noise burst within a rest):
    what a sequence's flips are held against.
    """
    moving = detect_motion(dtheta, dt, where, arw=arw).moving
    angles = turn_angles(dtheta, dt, moving, steady_rate(dtheta, dt))
    for (a, b), angle in zip(zip(*runs_of(moving), strict=True), angles, strict=True):
        if angle < math.radians(MIN_TURN_DEG):
            moving[a:b] = False
    return moving


def sequence_mask(timeline, time_s: np.ndarray, dt: np.ndarray, t_start: float) -> np.ndarray:
    """Per sample, whether a sequence's ``timeline`` says the IMU turns (not grown).

    ``time_s`` and ``dt`` are samples of a run that began at ``t_start``: the
    whole run, or one chunk of it.
    """
    start = time_s - dt - t_start
    end = time_s - t_start
    moving = np.zeros(len(time_s), dtype=bool)
    for a, b in zip(timeline.t0[~timeline.rest], timeline.t1[~timeline.rest], strict=True):
        moving |= (end > a) & (start < b)
    return moving


def sequence_motion(seq, time_s: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Per sample, whether a sequence says the IMU turns (grown by two samples as detected motion is)."""
    return grow(sequence_mask(timeline(seq), time_s, dt, time_s[0] - dt[0]))


def check_sequence_matches(
    seq, detected: np.ndarray, from_sequence: np.ndarray, dt: np.ndarray | None, where: str, elapsed=None
) -> None:
    """Refuse a sequence file whose flips are not where the log turns.

    ``elapsed(i)`` is the time from the run's start to the end of samples
    ``i``; by default ``np.cumsum(dt)[i]`` (a chunked run gives its own and no ``dt``).
    """
    d0, _ = runs_of(detected)
    s0, _ = runs_of(from_sequence)
    if len(d0) != len(s0):
        raise CalibError(
            f"the sequence {seq.name!r} has {len(s0)} flips where the log turns {len(d0)} times",
            where,
            "give the sequence the run was made with, or none (then the flips are found in the gyros)",
        )
    if elapsed is None:
        assert dt is not None  # only a chunked run, which gives elapsed(), has no dt
        t = np.cumsum(dt)
        t_d, t_s = t[d0], t[s0]
    else:
        t_d, t_s = elapsed(d0), elapsed(s0)
    offsets = np.abs(t_d - t_s)
    if offsets.max() > 2.0:
        k = int(np.argmax(offsets))
        raise CalibError(
            f"flip {k + 1} of sequence {seq.name!r} starts at {t_s[k]:.2f} s but the "
            f"log turns at {t_d[k]:.2f} s",
            where,
            "give the sequence the run was made with, or none (then the flips are found in the gyros)",
        )


@dataclass(frozen=True)
class MotionDiagnosis:
    """How a log moves, from the gyro increments alone (SI unless named).

    Attributes
    ----------
    has_flip : bool
        Some ``window_s`` stretch turns faster on average than the flip threshold.
    max_rate_rad_s : float
        Largest single-sample rate (vibration and quantisation included).
    max_mean_rate_rad_s : float
        Largest rate averaged over ``window_s``: what a flip would show.
    window_s : float
        Averaging time of the mean rates.
    mean_rate_rad_s : numpy.ndarray
        ``(3,)`` mean rate over the whole log: the Earth rate plus bias at rest.
    sway_arcsec : numpy.ndarray
        ``(3,)`` half peak-to-peak of each axis's angle about its mean-rate line.
    sway_rate_arcsec_s : numpy.ndarray
        ``(3,)`` RMS of each axis's ``window_s`` mean rate about the whole-log mean.
    """

    has_flip: bool
    max_rate_rad_s: float
    max_mean_rate_rad_s: float
    window_s: float
    mean_rate_rad_s: np.ndarray
    sway_arcsec: np.ndarray
    sway_rate_arcsec_s: np.ndarray


def diagnose_motion(
    dtheta: np.ndarray, dt: np.ndarray, flip_rate: float, window_s: float = 1.0
) -> MotionDiagnosis:
    """Whether a log flips, and how much its base sways.

    A flip turns the IMU by tens of degrees at degrees per second; a swaying
    or vibrating base turns it back and forth by arcseconds, and a single
    sample of a coarse gyro can exceed a flip's rate. Averaging the rate over
    ``window_s`` keeps the flip and removes the rest.

    Parameters
    ----------
    dtheta : numpy.ndarray
        ``(n, 3)`` gyro increments, rad.
    dt : numpy.ndarray
        ``(n,)`` sample intervals, s.
    flip_rate : float
        Mean rate over ``window_s`` above which the IMU turns, rad/s.
    window_s : float
        Averaging time, s.

    Returns
    -------
    MotionDiagnosis
    """
    n = len(dt)
    w = max(1, min(n, int(round(window_s / float(np.median(dt))))))
    # The run's mean rate first (the sway is measured about it), then the window means and
    # the sway block by block: memory stays at one block, whatever the length of the log.
    angle_end, clock_end = np.zeros(3), 0.0
    for a in range(0, n, MOTION_BLOCK):
        angle_end = carried_cumsum(dtheta[a : a + MOTION_BLOCK].T, angle_end)[:, -1]
        clock_end = float(carried_cumsum(dt[a : a + MOTION_BLOCK], clock_end)[-1])
    mean = angle_end / clock_end
    max_mean, square_sum = 0.0, np.zeros(3)
    low, high = np.zeros(3), np.zeros(3)  # sway is 0 at the start
    tail_angle, tail_clock = np.zeros((3, 1)), np.zeros(1)  # the w samples before a block
    for a in range(0, n, MOTION_BLOCK):
        angle = np.hstack([tail_angle, carried_cumsum(dtheta[a : a + MOTION_BLOCK].T, tail_angle[:, -1])])
        clock = np.concatenate([tail_clock, carried_cumsum(dt[a : a + MOTION_BLOCK], tail_clock[-1])])
        new = slice(len(tail_clock), None)
        sway = angle[:, new] - mean[:, None] * clock[new]
        low, high = np.minimum(low, sway.min(axis=1)), np.maximum(high, sway.max(axis=1))
        if len(clock) > w:
            rates = (angle[:, w:] - angle[:, :-w]) / (clock[w:] - clock[:-w])
            max_mean = max(max_mean, float(np.max(row_norm(rates.T))))
            square_sum += np.sum((rates - mean[:, None]) ** 2, axis=1)
        tail_angle, tail_clock = angle[:, -w:], clock[-w:]
    arcsec = math.degrees(1.0) * 3600.0
    return MotionDiagnosis(
        has_flip=max_mean > flip_rate,
        max_rate_rad_s=max(
            float(np.max(row_norm(dtheta[a : a + MOTION_BLOCK]) / dt[a : a + MOTION_BLOCK]))
            for a in range(0, n, MOTION_BLOCK)
        ),
        max_mean_rate_rad_s=max_mean,
        window_s=_window_s(dt, w),
        mean_rate_rad_s=mean,
        sway_arcsec=0.5 * (high - low) * arcsec,
        sway_rate_arcsec_s=np.sqrt(square_sum / max(1, n + 1 - w)) * arcsec,
    )


def carried_cumsum(x: np.ndarray, start) -> np.ndarray:
    """``start + x[0], start + x[0] + x[1], ...`` along the last axis, summed in that order.

    Prepending ``start`` keeps the sums bit-identical to one cumulative sum over the whole run.
    """
    start = np.asarray(start, dtype=float)
    return np.cumsum(np.concatenate([start[..., None], x], axis=-1), axis=-1)[..., 1:]


def _window_s(dt: np.ndarray, w: int) -> float:
    """The averaging time of ``w`` samples from the run's start, as the whole-run clock sums it."""
    return float(carried_cumsum(dt[:w], 0.0)[-1])


SWAY_NAMED_ARCSEC = 3600.0  # beyond a degree the "sway" of a static log is its gyro's integrated noise


def never_rotates(motion: MotionDiagnosis, where: str, turn_rad: float = 0.0) -> CalibError:
    """The refusal of a log without a flip: how far it turns at most, and its measured sway.

    ``turn_rad`` is the largest rotation between rests (the largest of :func:`turn_angles`).
    """
    k = int(np.argmax(motion.sway_rate_arcsec_s))
    fix = "a calibration run flips the IMU by tens of degrees between rests"
    # A base that sways (a vehicle, a soft table) is worth naming; a MEMS gyro's integrated bias
    # noise "sways" by degrees and says nothing a user can act on.
    if motion.sway_arcsec[k] <= SWAY_NAMED_ARCSEC:
        fix += (
            f"; about its mean rate, this one sways by +-{motion.sway_arcsec[k]:.3g} arcsec about "
            f"{'xyz'[k]} ({motion.sway_rate_arcsec_s[k]:.3g} arcsec/s RMS over {motion.window_s:.3g} s)"
        )
    return CalibError(
        f"the log never rotates (largest rotation between rests {math.degrees(turn_rad):.2g} deg, "
        f"a flip turns by tens): it is a static log; use it with `seqdesign profile fit` "
        f"for a noise profile",
        where,
        fix,
    )
