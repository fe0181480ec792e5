"""Where a run placed by hand rests: the still stretches between a person's moves.

A unit turned by hand has no sequence file and no gimbal rate: it rests in a
pose for a few seconds, is picked up, turned and carried, and put down again.
A sample is still when, over a short window about it, both

* the gyros' mean rate (less the run's steady rate, i.e. bias plus Earth rate)
  stays below the motion threshold, widened to five times the window's noise
  under the profile's ARW, and
* every accelerometer axis' spread stays below four times the profile's
  per-sample noise (VRW), with a floor of :data:`ACCEL_FLOOR` that a unit set
  down on a table never reaches but a hand holding it does, and
* the mean specific force over the window before and the window after agree to
  five times the noise of their difference: a carried unit's acceleration may
  rise too smoothly for the spread within one window to show it.

Still stretches shorter than :data:`MIN_REST_S` are part of the move, and so are
those shorter than :data:`FULL_REST_S` at the attitude of a rest beside them (the
pose as it is lifted, carried or set down); a bump while placing splits a rest
into two, the shorter of which drops out when too short, and the rest of the pose
is kept. A pose quiet for a window or more that gives no rest is a brief pose:
not used, but said (:func:`brief_pose_lines`), so that a log whose poses were
held too briefly is not told to add faces it holds. Each rest is trimmed so that
its samples are still ones: by the window either side beyond where the rate or
the spread sees motion (their windows are centred), and by :data:`MARGIN_S`
beyond where the means before and after disagree (their windows already reach a
window and a half from the sample).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from calib.errors import CalibError
from calib.sequence.motion import MOTION_THRESHOLD, grow, runs_of, steady_rate

WINDOW_S = 0.25  # long enough to average a MEMS gyro's noise, short against a 3 s pose
# The finder keeps REACH_S (0.425 s) clear of each move, so a pose held 1 s, the shortest static
# interval imu_tk's detector takes (100 samples at 100 Hz), leaves 0.15 s of still samples. Kept
# as a rest: the verdict is already sure they are still, and a brief pose is often the one face a
# quick hand turned up (BENCHMARKS.md: out of sample, the same or better on every log tried).
MIN_REST_S = 0.15
FULL_REST_S = 0.5  # a rest this long is kept wherever it lies; a shorter one at an attitude of its own
ACCEL_FLOOR = 0.02  # m/s^2: a hand's tremor is several times this, a table's vibration far less
DRIFT_FLOOR = 0.002  # m/s^2: a change of the mean a still unit on a table does not show
FASTEST_HAND_RATE_HZ = 5000.0  # an IMU's output rate above which a time column's unit is in doubt
SHOWN_BRIEF = 6  # brief poses named by their times; the rest counted
MIN_STILL_ROWS = 20  # a still stretch this many samples long is a pose, not a pause within a move
POSE_APART_DEG = 10.0  # gravity directions this far apart are another pose to a user
_COS_APART = math.cos(math.radians(POSE_APART_DEG))
MARGIN_S = 0.05  # trimmed from each end of a rest beyond the window: the placing's last settling
# How far each verdict keeps a rest from a move it sees (see still_samples): half a window,
# a window, and the margin (at rates above 12 Hz; below, the window is three samples, longer);
# a pose gives a rest when held this twice over and MIN_REST_S more.
REACH_S = 1.5 * WINDOW_S + MARGIN_S


@dataclass(frozen=True)
class Rests:
    """The rests of a run, as sample ranges ``[start, end)``.

    Attributes
    ----------
    start, end : ndarray of int, shape (K,)
        First and one-past-last sample of each rest, trimmed.
    still : ndarray of bool, shape (n,)
        The per-sample verdict before stretches were kept or dropped.
    gyro_threshold_rad_s, accel_threshold_mps2 : float
        The thresholds the verdict used (what a user tunes the profile against).
    brief_start, brief_end : ndarray of int
        Poses too brief for a rest: stretches whose windows see no motion for a window or more
        (a pose held about half a second or more), holding no rest.
    reach_s : float
        How far the finder kept each rest from a move it saw, at this log's rate.
    """

    start: np.ndarray
    end: np.ndarray
    still: np.ndarray
    gyro_threshold_rad_s: float
    accel_threshold_mps2: float
    brief_start: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    brief_end: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    reach_s: float = REACH_S

    @property
    def shortest_pose_s(self) -> float:
        """How long a pose must be held to give a rest."""
        return MIN_REST_S + 2.0 * self.reach_s

    @property
    def count(self) -> int:
        return len(self.start)


def moving_mean(x: np.ndarray, window: int) -> np.ndarray:
    """Centred moving mean of each column of ``(n, m)`` over ``window`` samples (shorter at the ends)."""
    n = len(x)
    c = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    i = np.arange(n)
    lo = np.clip(i - window // 2, 0, n)
    hi = np.clip(i + window - window // 2, 0, n)
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def still_samples(
    dtheta: np.ndarray, dv: np.ndarray, dt: np.ndarray, arw: float, vrw: float, loosen: float = 1.0
) -> tuple[np.ndarray, float, float]:
    """Per sample, whether the unit is still, and the gyro and accelerometer thresholds used.

    ``loosen`` multiplies every threshold (a pose held in the hand trembles beyond the
    profile's noise; :func:`calib.hand.calibrate.hand_fit_of` chooses it by the fit).
    """
    still, _, gyro_threshold, accel_threshold, _ = _verdicts(dtheta, dv, dt, arw, vrw, loosen)
    return still, gyro_threshold, accel_threshold


def _verdicts(
    dtheta: np.ndarray, dv: np.ndarray, dt: np.ndarray, arw: float, vrw: float, loosen: float
) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """The still verdict (see :func:`still_samples`), the quiet one its windows give before it is
    widened clear of the moves, the gyro and accelerometer thresholds, and the verdict's reach (s).
    """
    period = float(np.median(dt))
    window = max(3, int(round(WINDOW_S / period)))
    rate = dtheta / dt[:, None] - steady_rate(dtheta, dt)
    gyro_threshold = loosen * max(MOTION_THRESHOLD, 5.0 * arw / math.sqrt(window * period))
    gyro_moving = np.linalg.norm(moving_mean(rate, window), axis=1) > gyro_threshold
    force = dv / dt[:, None]
    mean = moving_mean(force, window)
    spread = np.sqrt(np.maximum(moving_mean(force**2, window) - mean**2, 0.0))
    accel_threshold = loosen * max(ACCEL_FLOOR, 4.0 * vrw / math.sqrt(period))
    thresholds = (gyro_threshold, accel_threshold)
    # A carried unit's acceleration can rise too smoothly for the spread within a window to
    # show it: the windows either side (not overlapping) then disagree on the mean.
    # (The windows centred a window either side of each sample: a change of the mean within
    # 1.5 windows is seen, and a slow rise of acceleration is seen early.)
    drift = np.zeros(len(force))
    drift[window:-window] = np.max(np.abs(mean[2 * window :] - mean[: -2 * window]), axis=1)
    drift_threshold = loosen * max(DRIFT_FLOOR, 5.0 * vrw / math.sqrt(period) * math.sqrt(2.0 / window))
    accel_moving = np.max(spread, axis=1) > accel_threshold
    # Each verdict is widened until a motion it sees surely lies outside the rest: a centred
    # window's (rate, spread) by a window, the drift's by nothing more, its windows already
    # reaching a window and a half either side. A window more there trimmed 0.25 s more from
    # each end, and the brief poses of a quick hand were lost.
    margin = int(round(MARGIN_S / period))
    moving = grow(gyro_moving | accel_moving, window + margin) | grow(drift > drift_threshold, margin)
    # A brief pose lies between two turns: quiet for a window or more (shorter: a hand slowing
    # within a move), the gyro turning within a window either side. A quiet stretch cut short by
    # the accelerometer's spread alone is a long pose noisier than the profile, not a brief one.
    quiet = ~(gyro_moving | accel_moving)
    turning = np.concatenate([[0], np.cumsum(gyro_moving)])
    n = len(quiet)
    q_start, q_end = runs_of(quiet)
    for a, b in zip(q_start, q_end, strict=True):
        turned_before = turning[a] > turning[max(a - window, 0)]
        turned_after = turning[min(b + window, n)] > turning[b]
        quiet[a:b] = b - a >= window and turned_before and turned_after
    return ~moving, quiet, *thresholds, (1.5 * window + margin) * period


def find_rests(
    dtheta: np.ndarray,
    dv: np.ndarray,
    dt: np.ndarray,
    arw: float,
    vrw: float,
    where: str = "run",
    loosen: float = 1.0,
    min_rest_s: float = MIN_REST_S,
) -> Rests:
    """The rests of a run placed by hand (see the module's rule).

    Parameters
    ----------
    dtheta, dv : ndarray, shape (n, 3)
        Gyro and accelerometer increments, rad and m/s.
    dt : ndarray, shape (n,)
        Sample intervals, s.
    arw, vrw : float
        The profile's white noise, rad/sqrt(s) and m/s/sqrt(s).
    where : str
        The run's name, for the refusal.
    loosen : float
        Multiplies every threshold (poses held in the hand).
    min_rest_s : float
        The shortest still stretch kept as a rest.

    Returns
    -------
    Rests
    """
    still, quiet, g_thr, a_thr, reach_s = _verdicts(dtheta, dv, dt, arw, vrw, loosen)
    start, end = runs_of(still)
    elapsed = np.concatenate([[0.0], np.cumsum(dt)])
    lengths = elapsed[end] - elapsed[start]
    force = dv / dt[:, None]
    full = lengths >= max(FULL_REST_S, min_rest_s)
    keep = full.copy()
    for i in np.flatnonzero(~full & (lengths >= min_rest_s)):
        keep[i] = _own_attitude(force, start[i], end[i], start[full], end[full])
    brief_start, brief_end = _brief_poses(quiet, force, start[keep], end[keep])
    if keep.sum() < 2:
        raise CalibError(
            f"found {int(keep.sum())} rest(s) of at least {min_rest_s:g} s: a run placed by hand needs "
            "the unit still in several poses"
            + _time_said(lengths, end - start, elapsed)
            + (f"; {len(brief_start)} pose(s) held too briefly for a rest" if len(brief_start) else ""),
            where,
            f"hold each pose still for {min_rest_s + 2.0 * reach_s:.1f} s or more (a few seconds is "
            f"better); if the unit was still, the profile's noise (gyro threshold "
            f"{math.degrees(g_thr):.3g} deg/s, accelerometer spread {a_thr:.3g} m/s^2) is below the "
            "log's: give the unit's own profile",
        )
    return Rests(start[keep], end[keep], still, g_thr, a_thr, brief_start, brief_end, reach_s)


def _brief_poses(
    quiet: np.ndarray, force: np.ndarray, start: np.ndarray, end: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The quiet stretches (a window long or more) that hold no rest and an attitude of their own:
    poses held too briefly. (A window's worth of quiet samples is a pose held about two windows:
    the windows are centred.) Two with no rest between them at one attitude are one pose, a
    tremor or bump splitting it.
    """
    q_start, q_end = runs_of(quiet)
    in_rest = np.zeros(len(quiet), bool)
    for a, b in zip(start, end, strict=True):
        in_rest[a:b] = True
    covered = np.concatenate([[0], np.cumsum(in_rest)])
    brief: list[list[int]] = []
    for a, b in zip(q_start, q_end, strict=True):
        if covered[b] > covered[a] or not _own_attitude(force, a, b, start, end):
            continue
        if brief and covered[a] == covered[brief[-1][1]]:
            p, q = brief[-1]
            if not _apart(_direction(force[a:b]), _direction(force[p:q])[None]):
                brief[-1][1] = b
                continue
        brief.append([a, b])
    return np.array([a for a, _ in brief], int), np.array([b for _, b in brief], int)


def _own_attitude(force: np.ndarray, a: int, b: int, start: np.ndarray, end: np.ndarray) -> bool:
    """Whether samples ``a:b`` hold another gravity direction than the rests either side of them.

    A brief still moment at the attitude of the pose before or after it is that pose as the unit
    is lifted, carried or set down: it adds no direction, and may carry a little acceleration.
    """
    before, after = np.flatnonzero(end <= a), np.flatnonzero(start >= b)
    beside = ([before[-1]] if before.size else []) + ([after[0]] if after.size else [])
    return _apart(_direction(force[a:b]), np.array([_direction(force[start[r] : end[r]]) for r in beside]))


def _apart(direction: np.ndarray, others: np.ndarray) -> bool:
    """Whether a unit vector lies :data:`POSE_APART_DEG` or more from each of ``others`` ``(m, 3)``."""
    return bool(np.all(others.reshape(-1, 3) @ direction < _COS_APART))


def _direction(force: np.ndarray) -> np.ndarray:
    mean = force.mean(axis=0)
    return mean / np.linalg.norm(mean)


def _time_said(lengths: np.ndarray, rows: np.ndarray, elapsed_s: np.ndarray) -> str:
    """The samples and rate the time column gives (a time in another unit shows there first) and,
    where still stretches of many samples all come out shorter than a rest, that poses held for
    seconds so shortened say the time is off, not that the hand never held still.
    """
    rate = (len(elapsed_s) - 1) / elapsed_s[-1]
    fast = ", faster than IMUs output: check the time column's unit" if rate > FASTEST_HAND_RATE_HZ else ""
    n, span = len(elapsed_s) - 1, float(elapsed_s[-1])
    said = f" ({n} samples in {span:.4g} s: {rate:.5g} Hz as the time reads{fast})"
    many = rows >= MIN_STILL_ROWS
    if many.sum() < 3:
        return said
    return said + (
        f"; it holds {int(many.sum())} still stretches of {MIN_STILL_ROWS} samples or more, the longest "
        f"{float(lengths[many].max()):.3g} s: if the poses were held for seconds, the time is off (check "
        "the time column's unit, or the sample rate)"
    )


def brief_pose_lines(rests: Rests, time_s: np.ndarray) -> list[str]:
    """What a user is told of poses held too briefly for a rest (none: nothing).

    ``time_s`` is each sample's time from the log's start.
    """
    if len(rests.brief_start) == 0:
        return []
    at = ", ".join(f"{time_s[a]:.1f}" for a in rests.brief_start[:SHOWN_BRIEF])
    more = f" and {len(rests.brief_start) - SHOWN_BRIEF} more" if len(rests.brief_start) > SHOWN_BRIEF else ""
    return [
        f"{len(rests.brief_start)} pose(s) held too briefly for a rest, not used (from {at} s{more}): "
        f"a pose gives a rest when held {rests.shortest_pose_s:.1f} s or more, the rest finder keeping "
        f"{rests.reach_s:.3g} s clear of each move; hold each pose longer"
    ]


def brief_new_faces(rests: Rests, force: np.ndarray) -> int:
    """How many brief poses hold a gravity direction no rest holds (10 deg or more from each):
    the poses that, held longer, would add what a fit lacks. ``force`` ``(n, 3)`` per sample.
    """
    held = np.array([_direction(force[a:b]) for a, b in zip(rests.start, rests.end, strict=True)])
    brief = [_direction(force[a:b]) for a, b in zip(rests.brief_start, rests.brief_end, strict=True)]
    return sum(_apart(d, held) for d in brief)
