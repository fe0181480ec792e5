"""The hand fit's start: rest attitudes chained through the moves by the compensated gyro.

A move's gyro increments, less bias and g-sensitivity and through ``A_g^-1``
(`compensated`), turn one rest's attitude into the next's; chained from the first
rest and each levelled on its own accelerometers, they start the fit
(`chained_start`). A move that misses its next rest's gravity by more than a MEMS
gyro's errors can give (`gross_tilt_rad`) is no move of this unit and is not chained.
"""

from __future__ import annotations

import math

import numpy as np

from calib.model.error_model import ErrorModel
from calib.nav.transform import rotvec_to_dcm

from .data import HandData
from .moves import move_rotation
from .poses import tip_to

GROSS_TILT_DEG = 5.0  # gross_tilt_rad: a chained move missing its next rest's gravity by more is no move
GROSS_FRACTION = 0.1  # ... plus this fraction of the angle turned


def compensated(dtheta, dv, dt, sl: slice, model: ErrorModel, G: np.ndarray):
    """A move's gyro increments less bias and g-sensitivity, through ``A_g^-1``; its specific-force
    increments through the accelerometer errors; and the compensated sample before the move.
    """
    A_inv = np.linalg.inv(model.gyro_matrix)
    idx = np.arange(sl.start - 1, sl.stop)
    dv_true = np.linalg.solve(model.accel_matrix, (dv[idx] - model.accel_bias * dt[idx, None]).T).T
    dth = (dtheta[idx] - model.gyro_bias * dt[idx, None] - dv_true @ G.T) @ A_inv.T
    return dth[1:], dv_true[1:], dth[0], A_inv


def gross_tilt_rad(turn_rad: float) -> float:
    """The largest tilt a gyro-chained move may miss the next rest's gravity by and still be a move.

    A MEMS gyro's scale and axis errors (a few per cent, `calib.hand.setup` refuses a common
    2 %) tilt a turn's end by a few per cent of its angle; `GROSS_FRACTION` of it plus
    `GROSS_TILT_DEG` is far beyond that. A miss beyond it is no move of this unit: two
    recordings spliced, samples lost in a turn.
    """
    return math.radians(GROSS_TILT_DEG) + GROSS_FRACTION * turn_rad


def chained_start(data: HandData, dtheta, dv, dt, values, G, omega_n) -> tuple[np.ndarray, dict]:
    """Rest attitudes chained through the moves, each levelled on its accelerometers.

    A move whose chained attitude misses the next rest's gravity by more than
    :func:`gross_tilt_rad` is not chained through (the rests after it start from their
    own gravity alone). Returns the attitudes and each such move's miss, rad.
    """
    model = ErrorModel(values)
    C = np.empty((data.count, 3, 3))
    C[0] = tip_to(np.eye(3), data.rest_force[0])
    gross = {}
    for r, sl in enumerate(data.move_slices):
        prev = C[r]
        if data.move_used[r]:
            dth, _, before, _ = compensated(dtheta, dv, dt, sl, model, G)
            R, _, _ = move_rotation(dth, before)
            chained = rotvec_to_dcm(-omega_n * dt[sl].sum()) @ C[r] @ R
            up = data.rest_force[r + 1] / np.linalg.norm(data.rest_force[r + 1])
            miss = math.acos(float(np.clip((chained @ up)[2], -1.0, 1.0)))
            if miss > gross_tilt_rad(float(data.move_turn_rad[r])):
                gross[r] = miss
            else:
                prev = chained
        C[r + 1] = tip_to(prev, data.rest_force[r + 1])
    return C, gross
