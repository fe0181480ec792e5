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

Still stretches shorter than :data:`MIN_REST_S` (a pause mid-move) are part of
the move; a bump while placing splits a rest into two, the shorter of which
drops out when too short, and the rest of the pose is kept. Each rest is
trimmed so that its samples are still ones: by the window either side beyond
where the rate or the spread sees motion (their windows are centred), and by
:data:`MARGIN_S` beyond where the means before and after disagree (their
windows already reach a window and a half from the sample).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError
from calib.sequence.motion import MOTION_THRESHOLD, grow, runs_of, steady_rate

WINDOW_S = 0.25  # long enough to average a MEMS gyro's noise, short against a 3 s pose
MIN_REST_S = 0.5  # a shorter still stretch is a pause within a move
ACCEL_FLOOR = 0.02  # m/s^2: a hand's tremor is several times this, a table's vibration far less
DRIFT_FLOOR = 0.002  # m/s^2: a change of the mean a still unit on a table does not show
FASTEST_HAND_RATE_HZ = 5000.0  # an IMU's output rate above which a time column's unit is in doubt
MIN_STILL_ROWS = 20  # a still stretch this many samples long is a pose, not a pause within a move
MARGIN_S = 0.05  # trimmed from each end of a rest beyond the window: the placing's last settling


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
    """

    start: np.ndarray
    end: np.ndarray
    still: np.ndarray
    gyro_threshold_rad_s: float
    accel_threshold_mps2: float

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
    period = float(np.median(dt))
    window = max(3, int(round(WINDOW_S / period)))
    rate = dtheta / dt[:, None] - steady_rate(dtheta, dt)
    gyro_threshold = loosen * max(MOTION_THRESHOLD, 5.0 * arw / math.sqrt(window * period))
    gyro_moving = np.linalg.norm(moving_mean(rate, window), axis=1) > gyro_threshold
    force = dv / dt[:, None]
    mean = moving_mean(force, window)
    spread = np.sqrt(np.maximum(moving_mean(force**2, window) - mean**2, 0.0))
    accel_threshold = loosen * max(ACCEL_FLOOR, 4.0 * vrw / math.sqrt(period))
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
    # each end: a pose had to be held 1.85 s to give a 0.5 s rest, now 1.35 s (imu_tk's, at
    # 150 Hz), and the brief poses of a quick hand were lost.
    margin = int(round(MARGIN_S / period))
    moving = grow(gyro_moving | accel_moving, window + margin) | grow(drift > drift_threshold, margin)
    return ~moving, gyro_threshold, accel_threshold


def find_rests(
    dtheta: np.ndarray,
    dv: np.ndarray,
    dt: np.ndarray,
    arw: float,
    vrw: float,
    where: str = "run",
    loosen: float = 1.0,
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

    Returns
    -------
    Rests
    """
    still, g_thr, a_thr = still_samples(dtheta, dv, dt, arw, vrw, loosen)
    start, end = runs_of(still)
    elapsed = np.concatenate([[0.0], np.cumsum(dt)])
    lengths = elapsed[end] - elapsed[start]
    keep = lengths >= MIN_REST_S
    if keep.sum() < 2:
        raise CalibError(
            f"found {int(keep.sum())} rest(s) of at least {MIN_REST_S:g} s: a run placed by hand needs "
            "the unit still in several poses" + _time_said(lengths, end - start, elapsed),
            where,
            f"hold each pose still for a few seconds; if the unit was still, the profile's noise "
            f"(gyro threshold {math.degrees(g_thr):.3g} deg/s, accelerometer spread "
            f"{a_thr:.3g} m/s^2) is below the log's: give the unit's own profile",
        )
    return Rests(start[keep], end[keep], still, g_thr, a_thr)


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
