"""Samples a logger lost at rest, put back as the mean increment of their neighbours.

A sample lost while the IMU is still holds the Earth rate and gravity seen through the
IMU's errors, plus white noise: the mean of its neighbours stands for it up to one
sample's noise. One lost while the IMU turns cannot be known and is refused.
"""

from __future__ import annotations

import numpy as np

from calib.errors import CalibError
from calib.nav.strapdown import sample_intervals

# Samples each side of a lost one whose mean increment fills it (at rest).
FILL_NEIGHBOURS = 100
# The longest hole filled: beyond this the fill would be mostly invented, not measured.
MAX_FILL = 2 * FILL_NEIGHBOURS
# A neighbourhood is at rest when its mean rate is below this: 14x the Earth rate,
# far above any calibration-grade gyro bias, far below a flip (rad/s).
REST_RATE = 1e-3
# No single neighbour may turn faster than this: a flip (0.57 deg/s; the estimator's threshold).
TURN_RATE = 1e-2
# Around a polling loop's stall (a hand run's MEMS unit: per-sample noise to 0.03 rad/s, bias to
# 0.005 rad/s) no row may turn faster than this (5.7 deg/s).
STALL_REST_RATE = 0.1


def fill_dropped(
    index: np.ndarray,
    time_of: tuple[float, float],
    dtheta: np.ndarray,
    dv: np.ndarray,
    gimbal: np.ndarray | None = None,
):
    """Put each lost sample back, at rest, as the mean increment of its neighbours.

    At rest the increments are the Earth rate and gravity seen through the
    IMU errors plus white noise; the mean of ``FILL_NEIGHBOURS`` samples each
    side is the lost increment up to one sample's noise, so the navigation
    error a filled sample adds is that of the noise the IMU would have added.
    A sample lost while the IMU turns cannot be known and is refused, as is
    a hole longer than ``MAX_FILL`` samples.

    Parameters
    ----------
    index : numpy.ndarray
        ``(n,)`` sample count of each row present (a `SampleClock`'s, duplicates
        already removed: increasing).
    time_of : (float, float)
        The clock's offset and period, s: sample ``k`` ends at ``offset + k * period``.
    dtheta, dv : numpy.ndarray
        ``(n, 3)`` increments of the rows that are present.
    gimbal : numpy.ndarray, optional
        ``(n, 3)`` encoder angles: the lost rows repeat the previous one.

    Returns
    -------
    dtheta, dv, gimbal, index : numpy.ndarray
        Full arrays over ``index[0] .. index[-1]`` and that index.

    Raises
    ------
    CalibError
        For a hole whose neighbourhood is not at rest (``where`` is the time).
    """
    full = np.arange(index[0], index[-1] + 1)
    pos = index - index[0]
    out_th = np.full((len(full), 3), np.nan)
    out_dv = np.full((len(full), 3), np.nan)
    out_th[pos], out_dv[pos] = dtheta, dv
    for row in np.flatnonzero(np.diff(index) > 1):
        lo, hi = max(0, row + 1 - FILL_NEIGHBOURS), min(len(index), row + 1 + FILL_NEIGHBOURS)
        _check_fillable(index, time_of, row, dtheta[lo:hi])
        hole = slice(pos[row] + 1, pos[row + 1])
        out_th[hole] = dtheta[lo:hi].mean(axis=0)
        out_dv[hole] = dv[lo:hi].mean(axis=0)
    out_g = None
    if gimbal is not None:
        filled = np.zeros(len(full), dtype=np.int64)
        filled[pos] = 1
        out_g = np.asarray(gimbal)[np.cumsum(filled) - 1]
    return out_th, out_dv, out_g, full


def _check_fillable(
    index: np.ndarray, time_of: tuple[float, float], row: int | np.integer, neighbours: np.ndarray
) -> None:
    """Refuse a hole after ``row`` that is too long, or whose neighbours are not at rest."""
    offset, period = time_of
    lost = int(index[row + 1] - index[row] - 1)
    t = offset + (index[row] + 1) * period
    if lost > MAX_FILL:
        raise CalibError(
            f"{lost} samples lost at t = {t:.6g} s, more than the "
            f"{MAX_FILL} that the {FILL_NEIGHBOURS} samples each side can "
            "stand for",
            f"t = {t:.6g} s",
            "split the log at the hole and calibrate each part",
        )
    rate = np.linalg.norm(neighbours.mean(axis=0)) / period
    peak = np.max(np.linalg.norm(neighbours, axis=1)) / period
    if rate > REST_RATE or peak > TURN_RATE:
        raise CalibError(
            f"{lost} sample(s) lost at t = {t:.6g} s, while the IMU turns",
            f"t = {t:.6g} s",
            "the increments of a flip cannot be recovered; repair the log or record the run again",
        )


def check_stalls_at_rest(dtheta: np.ndarray, time_s: np.ndarray, stalls_s: list) -> None:
    """Refuse a polling loop's stall (:func:`calib.runlog.polled.stalls`) while the IMU turns.

    The row after a stall holds one reading over the whole hole: at rest that is the hole's
    increment to its noise; while turning the rate changed unseen. At rest means no row of
    the ``FILL_NEIGHBOURS`` each side turns faster than ``STALL_REST_RATE`` (a MEMS unit's
    noise and bias stay below it; a hand's turn passes it within its first rows).
    ``time_s``: the rows' own ends, s.
    """
    dt = sample_intervals(time_s)
    for start in stalls_s:
        row = int(np.searchsorted(time_s, start))
        lo, hi = max(0, row - FILL_NEIGHBOURS), min(len(time_s), row + 1 + FILL_NEIGHBOURS)
        near = np.r_[lo:row, row + 1 : hi]  # the stall's own row is the one in doubt
        peak = np.max(np.linalg.norm(dtheta[near], axis=1) / dt[near])
        if peak > STALL_REST_RATE:
            raise CalibError(
                f"the logger stalled for {1e3 * dt[row]:.3g} ms at t = {start:.6g} s, while the IMU turns",
                f"t = {start:.6g} s",
                "a turn's rate over a stall cannot be recovered; log without stalls (a polling loop "
                "that writes to a card blocks) or record the run again",
            )
