"""Samples taken at their stamps: a logger that polls the sensor when its loop comes round.

Most logs hold an IMU's samples on its own crystal: the stamps only locate them, and
their deviation from a uniform clock is jitter, bounded (a host's reception delays) or
nil (the IMU's own stamps). A logger that reads the sensor whenever its loop comes
round (an Arduino's ``loop()`` with ``micros()``) takes each sample at its stamp: the
intervals vary from row to row, independently, and the time drifts from any uniform
clock as a random walk. Counting such rows on a uniform clock puts each interval's
error into the increments (a 4-6 ms loop at 200 deg/s: 0.2 deg a sample, about
0.3 deg over a one-second turn).

The two are told apart by how the deviation from the straight line in sample count
grows: over ``m`` rows a random walk's spread grows as ``sqrt(m)``, bounded jitter's
not at all. ``walk_ratio`` is ``Var(e[k+m] - e[k]) / (m Var(e[k+1] - e[k]))``: 1 for a
walk, ``1/m`` for bounded jitter.
"""

from __future__ import annotations

import numpy as np

WALK_ROWS = 100  # m: 1/m = 0.01 for jitter, 1 for a walk
WALK_RATIO = 0.25  # above: the stamps walk, the samples were taken at them
# Steps whose spread is below this fraction of the period are a clock's own or a host's that
# follows it (the Xsens recording's steps spread by 0.29 % and walk, yet its moves fit worse
# integrated over them: move noise x1.11 against x1.06 over the nominal period); a polling
# loop's vary by tens of per cent.
MIN_STEP_SPREAD = 0.02


def walk_ratio(deviation: np.ndarray, period: float) -> float:
    """How the deviation of the stamps from a uniform clock grows with the rows, ``(n,)`` s.

    Returns 0 when the log is too short to tell (fewer than ``3 * WALK_ROWS`` rows) or its
    steps vary by less than ``MIN_STEP_SPREAD`` periods.
    """
    e = np.asarray(deviation, dtype=float)
    m = WALK_ROWS
    if len(e) < 3 * m:
        return 0.0
    one = np.diff(e)
    spread = float(np.var(one))
    if not spread > (MIN_STEP_SPREAD * period) ** 2:
        return 0.0
    far = e[m:] - e[:-m]
    return float(np.var(far) / (m * spread))


def summary(step_stats: tuple, deviation_rms: float) -> str:
    """The clock line of a log sampled at its stamps; ``step_stats`` (min, max, mean, RMS), s."""
    low, high, mean, rms = step_stats
    return (
        f"clock: samples taken at their stamps (steps {1e3 * low:.3g}-{1e3 * high:.3g} ms, "
        f"{1e3 * rms:.3g} ms RMS about {1e3 * mean:.4g} ms, the time wandering from a "
        f"uniform clock by {1e3 * deviation_rms:.3g} ms RMS as a random walk does: a polling logger); "
        "each sample covers its own stamp interval"
    )
