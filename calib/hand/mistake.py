"""A setup mistake a hand log's data show: what they show, and how the log is put right."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Mistake:
    """A likely setup mistake: what the data show, and how the log is put right."""

    what: str
    gyro: np.ndarray  # (3, 3) applied to the gyro's increments to put it right
    accel: np.ndarray  # (3, 3) applied to the accelerometer's
    swap: bool = False  # gyro and accelerometer columns exchanged first
    rate_factor: float = 1.0  # the true rate over the given one
    cannot_fix: str | None = None  # what the user must do when no relabelling puts the log right
