"""Time stamps written coarser than the samples come: a 200 Hz IMU stamped to 10 ms.

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
