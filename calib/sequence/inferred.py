"""The nominal sequence a log followed, read off its navigation: grid rests and body-axis flips.

A rank-deficient run's own trajectory is bent by the errors it cannot
estimate, and that bending turns its nearly-null directions: judged on it,
what is estimable would depend on the very errors being estimated. The
analyser judges at the nominal trajectory; the estimator does the same
with the sequence it is given, or with the one inferred here when every
rest is within :data:`SNAP_DEG` of a grid attitude and every flip turns
about one body axis by a multiple of 90 degrees.
"""

from __future__ import annotations

import math

import numpy as np

from calib.nav.transform import AXES, directions_of, rot_axis

from .definition import MIN_RATE_DPS, Sequence, Step
from .motion import runs_of

SNAP_DEG = 10.0  # a rest counts as a grid attitude within this (mounting 3 deg + alignment)


def _snap(C: np.ndarray, max_deg: float = SNAP_DEG) -> np.ndarray | None:
    """The rotation among the 24 signed permutations nearest ``C`` if within ``max_deg``."""
    S = np.zeros((3, 3))
    for j in range(3):
        i = int(np.argmax(np.abs(C[:, j])))
        S[i, j] = np.sign(C[i, j])
    if abs(np.linalg.det(S) - 1.0) > 1e-9:
        return None
    cos_angle = (np.trace(S.T @ C) - 1.0) / 2.0
    return S if cos_angle >= math.cos(math.radians(max_deg)) else None


def infer_sequence(
    C_b_n: np.ndarray, dtheta: np.ndarray, moving: np.ndarray, dt: np.ndarray, name: str = "inferred"
) -> Sequence | None:
    """A :class:`Sequence` whose rests and flips are the log's, on the grid; None if off it.

    Parameters
    ----------
    C_b_n : ndarray (n + 1, 3, 3)
        Navigated attitude at the sample boundaries.
    dtheta : ndarray (n, 3)
        Gyro increments (the flip angles are their integral about the axis).
    moving : ndarray (n,) of bool
        Where the log turns.
    dt : ndarray (n,)
        Sample intervals.
    name : str
        Name of the inferred sequence.
    """
    turns = list(zip(*runs_of(moving), strict=True))
    if not turns:
        return None
    rests = (
        [(0, turns[0][0])]
        + [(a[1], b[0]) for a, b in zip(turns[:-1], turns[1:], strict=True)]
        + [(turns[-1][1], len(moving))]
    )
    # Rests relative to the first one (the alignment's heading error cancels), snapped to the
    # grid; the first one itself to the nearest grid attitude, whatever its heading error.
    first = C_b_n[(rests[0][0] + rests[0][1]) // 2]
    relative = [_snap(first.T @ C_b_n[(a + b) // 2]) for a, b in rests]
    start = _snap(first, max_deg=180.0)
    if start is None or any(r is None for r in relative):
        return None
    grid = [start @ r for r in relative]
    steps = []
    for k, (a, b) in enumerate(turns):
        step = _flip(
            grid[k].T @ grid[k + 1],
            np.sum(dtheta[a:b], axis=0),
            float(np.sum(dt[a:b])),
            float(np.sum(dt[rests[k + 1][0] : rests[k + 1][1]])),
        )
        if step is None:
            return None
        steps.append(step)
    return Sequence(
        name=name,
        start=directions_of(grid[0]),
        steps=tuple(steps),
        initial_dwell_s=float(np.sum(dt[: rests[0][1]])),
    )


def _flip(R: np.ndarray, turned: np.ndarray, duration_s: float, dwell_s: float) -> Step | None:
    """The body-axis flip ``R`` (snapped, body frame) whose gyros turned by ``turned`` (rad)."""
    fixed = [i for i in range(3) if R[i, i] == 1.0]
    if len(fixed) == 3:  # whole turns: the gyros say about which axis
        fixed = [int(np.argmax(np.abs(turned)))]
    if len(fixed) != 1:
        return None  # not a turn about one body axis
    axis = fixed[0]
    angle = 90.0 * round(math.degrees(float(turned[axis])) / 90.0)
    if angle == 0.0 or not np.allclose(rot_axis(axis, math.radians(angle)), R, atol=1e-9):
        return None
    return Step(AXES[axis], angle, max(abs(angle) / duration_s, MIN_RATE_DPS), dwell_s)
