"""Values written coarser than they vary: time stamps coarser than the samples come (a 200 Hz
IMU stamped to 10 ms), and readings printed in steps (a gyro in whole deg/s, `reading_step`).

Such stamps put half the samples at the time of the one before: zero steps on many
rows, and steps of two periods between. Each is no repeated sample and no lost one:
the rows are the samples, counted by the count rule (:mod:`calib.runlog.countrule`)
at the stamps' resolution. A quantised IMU at rest may give a sample equal to the one
before; such repeats are duplicates only beyond the rate at which rows the stamps
move on (new samples for certain) repeat their predecessor.
"""

from __future__ import annotations

import math

import numpy as np

# Zero steps on more than this share of rows: stamps coarser than the sample period, not a
# logger's repeated samples (a logger repeats a few).
COARSE_SHARE = 0.1
# Repeated rows as many as chance gives this often or more are samples.
CHANCE_P = 1e-3
STEP_TOLERANCE = 1e-6  # steps: how far a gap may sit off a whole number of steps (float conversion)
MIN_VALUES = 2  # a channel needs this many distinct values for a step to mean anything
SAME_VALUE = 1e-9  # of the largest reading: values closer than this are one value written twice


def coarse_stamps(step: np.ndarray) -> bool:
    """Whether stamps were written coarser than the samples come (a 200 Hz IMU stamped to 10 ms).

    Zero steps on more than `COARSE_SHARE` of the rows, and the stamps that move on do so by
    1.5 rows' time or more (the span over the rows): a logger's repeats are few, and a host
    that reads two samples at once moves on by one row's time in between.
    """
    moved = step[step > 0.0]
    if step.size < 2 or moved.size == 0 or np.mean(step == 0.0) <= COARSE_SHARE:
        return False
    return float(moved.min()) >= 1.5 * float(np.sum(step)) / step.size


def stamp_resolution(periods: np.ndarray) -> float:
    """The stamps' resolution in periods when they are coarser than the samples (`coarse_stamps`), else 1."""
    if not coarse_stamps(periods):
        return 1.0
    return max(1.0, float(np.min(periods[periods > 0.0])))


def chance_repeats(step: np.ndarray, alike: np.ndarray, close: np.ndarray) -> bool:
    """Whether the rows ``close`` marks as repeats (equal to the one before, at its time) are as
    many as chance gives under coarse stamps (`coarse_stamps`); False for other stamps.

    ``alike`` marks every row equal to the one before, whatever its stamp. The chance is the
    share of rows the stamps move on that are alike; the repeats are chance when a Poisson
    count of that mean reaches theirs with probability `CHANCE_P` or more.
    """
    if not coarse_stamps(step):
        return False
    moved = step > 0.0
    chance = (int(np.sum(alike & moved)) + 1) / max(int(moved.sum()), 1)
    return _poisson_tail(int(close.sum()), chance * float(np.sum(~moved))) >= CHANCE_P


def _poisson_tail(k: int, mean: float) -> float:
    """P(K >= k) for K Poisson with ``mean``."""
    term, below = math.exp(-mean), 0.0
    for j in range(k):
        below += term
        term *= mean / (j + 1)
    return max(0.0, 1.0 - below)


def reading_step(x: np.ndarray) -> float:
    """The step a channel's readings ``(n,)`` are written in, 0 where they keep no grid.

    The smallest gap between its distinct values, kept where every gap is a whole number
    of it (a grid with any offset: counts less a zero, times a scale).
    """
    values = np.unique(np.asarray(x, dtype=float))
    if len(values) < MIN_VALUES:
        return 0.0
    gaps = np.diff(values)
    # One written value may come back as several a few ulps apart (units converted, a rate
    # taken from an increment over its interval): gaps that small are no gaps.
    gaps = gaps[gaps > SAME_VALUE * float(np.max(np.abs(values)))]
    if not gaps.size:
        return 0.0
    q = float(gaps.min())
    if not q > 0.0:
        return 0.0
    ratio = gaps / q
    if np.max(np.abs(ratio - np.rint(ratio))) > STEP_TOLERANCE:
        return 0.0
    return q


def duplicate_rows(time_s: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, period_s: float) -> np.ndarray:
    """Rows that repeat the previous row: same increments, at most half a period later.

    Returns
    -------
    numpy.ndarray
        ``(n,)`` bool, True for each extra copy.
    """
    same = np.zeros(len(time_s), dtype=bool)
    step = np.diff(time_s)
    alike = np.ones(len(step), dtype=bool)
    # Column by column: numpy reduces a 3-wide axis one row at a time, ten times slower.
    for x in (dtheta, dv):
        for i in range(x.shape[1]):
            alike &= x[1:, i] == x[:-1, i]
    close = alike & (step >= 0.0) & (step < 0.5 * period_s)
    if close.any() and not chance_repeats(step, alike, close):
        same[1:] = close  # (stamps coarser than the period: repeats no more than chance gives are samples)
    return same
