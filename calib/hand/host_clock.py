"""The time stamps a host writes: reception times of samples the IMU spaced evenly on its own clock.

An IMU samples on its crystal; a host (a PC over USB or a serial port) stamps each sample
when it receives it: the sample's true end time plus a delay (transmission, buffering, the
host's scheduler). A sample cannot overtake the one before it (one link, first in first
out), so a late sample holds back the next ones: they arrive, and are stamped, together.
Here each delay is drawn uniformly in ``[0, jitter_s]`` and the stamps are the running
maximum of ``t_k + d_k``: non-decreasing, every sample kept, each stamp within
``[t_k, t_k + jitter_s]``. When ``jitter_s`` is below the sample period no sample is held
back: the delays are independent, the steps between stamps have mean ``T``, variance
``jitter_s^2 / 6`` and lag-one correlation ``-1/2``. Longer delays bunch samples (steps of 0
s) the way the loggers of real hand recordings do (8-20 ms steps around a 10 ms period).

A logger may write its host's UNIX time in integer milliseconds: :func:`epoch_ms` rounds
the stamps to whole milliseconds from an epoch (rounding keeps them non-decreasing) and
:func:`write_epoch_ms_csv` writes such a log (a ``time_ms`` column, docs/formats.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.io.files import atomic_write_text
from calib.runlog import Run
from calib.runlog.format import DTHETA_COLUMNS, DV_COLUMNS, FORMAT

# 2023-11-14 22:13:20 UTC in ms: where the epoch-ms stamps of a simulated log start from.
EPOCH_MS = 1_700_000_000_000
STAMP_MODES = ("seconds", "epoch-ms")


def host_stamps(time_s: np.ndarray, jitter_s: float, rng: np.random.Generator) -> np.ndarray:
    """Reception times of samples that end at ``time_s``: each delayed by up to ``jitter_s``, in order.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        True end of each sample (increasing), s.
    jitter_s : float
        Largest delay, s (>= 0); delays are uniform in ``[0, jitter_s]``.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (n,)
        ``max(t_j + d_j, j <= k)``: non-decreasing, within ``[t_k, t_k + jitter_s]``.
    """
    if not jitter_s >= 0.0:
        raise ValueError("the stamps' jitter must be >= 0")
    t = np.asarray(time_s, dtype=float)
    return np.maximum.accumulate(t + rng.uniform(0.0, jitter_s, t.shape))


def epoch_ms(time_s: np.ndarray, origin_ms: int = EPOCH_MS) -> np.ndarray:
    """Stamps as a logger writes its host's UNIX time: whole milliseconds from ``origin_ms``, int64."""
    return origin_ms + np.rint(np.asarray(time_s, dtype=float) * 1000.0).astype(np.int64)


def epoch_seconds(stamps_ms: np.ndarray) -> np.ndarray:
    """Integer epoch-ms stamps as float seconds, split as the reader splits them (whole s + rest)."""
    whole, rest = np.divmod(np.asarray(stamps_ms, dtype=np.int64), 1000)
    return whole.astype(np.float64) + rest / 1000.0


def write_epoch_ms_csv(run: Run, path: str | Path) -> None:
    """Write a run whose ``time_s`` holds epoch seconds in whole ms as a CSV with a ``time_ms`` column.

    The metadata and increments are written as :func:`calib.runlog.write_run` writes them
    (shortest reprs); the time column as integers, ``rint(time_s * 1000)``.
    """
    stamps = np.rint(np.asarray(run.time_s, dtype=float) * 1000.0).astype(np.int64)
    lines = [f"# format: {FORMAT}"] + [f"# {k}: {v}" for k, v in run.meta.items() if k != "format"]
    lines.append(",".join(("time_ms", *DTHETA_COLUMNS, *DV_COLUMNS)))
    columns = [list(map(str, stamps.tolist()))]
    columns += [list(map(repr, c)) for c in np.hstack([run.dtheta_rad, run.dv_mps]).T.tolist()]
    lines += map(",".join, zip(*columns, strict=True))
    atomic_write_text(path, "\n".join(lines) + "\n")
