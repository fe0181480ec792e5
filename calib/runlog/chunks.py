"""Reading a run log a chunk at a time: its metadata, then blocks of samples.

For the streamed calibration (:mod:`calib.fit.chunked`), which never holds a run
whole: an NPZ's members are read as streams (stored or deflated, never loaded
whole), a CSV's rows parsed a block at a time. The metadata is decoded as the
whole-run readers decode it.
"""

from __future__ import annotations

import math
from pathlib import Path

from calib.errors import CalibError

from .csv import csv_chunks, csv_meta
from .npz import npz_chunks, npz_meta

READ_ROWS = 1 << 16


def read_meta(path) -> dict[str, str]:
    """The metadata of a run log, without reading its samples."""
    return npz_meta(path) if Path(path).suffix.lower() == ".npz" else csv_meta(path)


def nominal_period(meta: dict[str, str], where: str) -> float:
    """``1 / sample_rate_hz`` of the metadata, refusing a missing or impossible rate."""
    try:
        rate = float(meta["sample_rate_hz"])
    except (KeyError, ValueError):
        rate = math.nan
    if not (math.isfinite(rate) and rate > 0):
        raise CalibError(
            f"sample_rate_hz is {meta.get('sample_rate_hz')!r}",
            where,
            "the log's metadata must give the IMU's output rate in Hz",
        )
    return 1.0 / rate


def read_chunks(path, rows: int = READ_ROWS):
    """Yield ``(time_s, dtheta_rad, dv_mps)`` blocks of ``rows`` samples of an NPZ or CSV run log."""
    kind = Path(path).suffix.lower()
    if kind not in (".npz", ".csv"):
        raise CalibError(
            f"unknown run format {Path(path).suffix!r}", str(path), "give a .csv or .npz run log"
        )
    return (npz_chunks if kind == ".npz" else csv_chunks)(path, rows)
