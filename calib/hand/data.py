"""What a fit of a run placed by hand reads of it: its rests, their means and noise, its moves.

The rests are found from the data (:mod:`calib.hand.rests`); each rest's mean specific
force and rate are the fit's observations at rest, with the noise of that mean (the
profile's white noise, or more for a pose held in the hand: `rest_noise_factor`),
and the samples between two rests are a move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from calib.noise.profiles import NoiseProfile
from calib.runlog.coarse import reading_step

from .rests import POSE_APART_DEG, Rests, find_rests
from .rounding import rest_rounding


@dataclass(frozen=True)
class HandData:
    """What the fit reads of a run: rest means and move samples.

    Attributes
    ----------
    rests : Rests
    rest_time_s : ndarray, shape (K,)
        Length of each rest, s.
    rest_rate, rest_force : ndarray, shape (K, 3)
        Mean gyro rate (rad/s) and specific force (m/s^2) over each rest.
    move_slices : list of slice
        The samples from the end of rest ``r`` to the start of rest ``r + 1``.
    move_used : ndarray of bool, shape (K - 1,)
        False for a move with clipped samples (its rests are then not chained).
    move_turn_rad : ndarray, shape (K - 1,)
        The angle the gyro turned through over each move (the sum of its increments' norms).
    rest_noise : ndarray, shape (K, 2)
        Each rest mean's own noise over the profile's white noise (accelerometer, gyro), at
        least 1 (`rest_noise_factor`: a pose held in the hand trembles; an accelerometer
        written coarser than its noise, :mod:`calib.hand.rounding`).
    reading_steps : ndarray, shape (2, 3)
        The step each axis' readings are written in (accelerometer m/s^2, gyro rad/s; 0: none).
    rest_rate_rounding : ndarray, shape (K, 3)
        Each rest's rounding error on its mean rate, rad/s, one offset shared by every rest
        (0 where the noise dithers it; :func:`calib.hand.rounding.consider_rounding`).
    """

    rests: Rests
    rest_time_s: np.ndarray
    rest_rate: np.ndarray
    rest_force: np.ndarray
    move_slices: list
    move_used: np.ndarray
    move_turn_rad: np.ndarray
    rest_noise: np.ndarray
    reading_steps: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    rest_rate_rounding: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def count(self) -> int:
        return len(self.rest_time_s)


def rest_noise_factor(increments: np.ndarray, T: float, density: float) -> float:
    """How much a rest's mean is noisier than the profile's white noise says (at least 1).

    A pose held in the hand trembles: the unit wobbles and shakes about a mean pose, so its
    increments' running sum (the angle, or the velocity, about the rest's mean) wanders within
    a bound instead of walking. The mean over the rest then errs by the wander's change from
    start to end over ``T``: variance ``2 s^2 / T^2``, ``s^2`` the wander's variance beyond
    what white noise gives a bridge of ``T`` (``density^2 T / 6``).
    """
    if density <= 0 or len(increments) < 3:
        return 1.0
    wander = np.cumsum(increments - increments.mean(axis=0), axis=0)
    extra = max(float(np.mean(np.var(wander, axis=0))) - density**2 * T / 6.0, 0.0)
    return math.sqrt(1.0 + 2.0 * extra / T**2 / (density**2 / T))


def hand_data(
    dtheta, dv, dt, profile: NoiseProfile, clipped=None, where: str = "run", loosen: float = 1.0
) -> HandData:
    """Rests found with the profile's noise (thresholds times ``loosen``), their means, each rest's
    own noise, and the moves between them.
    """
    rests = find_rests(dtheta, dv, dt, profile.arw, profile.vrw, where, loosen)
    T = np.array([dt[a:b].sum() for a, b in zip(rests.start, rests.end, strict=True)])
    rate = np.array([dtheta[a:b].sum(0) for a, b in zip(rests.start, rests.end, strict=True)]) / T[:, None]
    force = np.array([dv[a:b].sum(0) for a, b in zip(rests.start, rests.end, strict=True)]) / T[:, None]
    slices = [slice(int(e), int(s)) for e, s in zip(rests.end[:-1], rests.start[1:], strict=True)]
    used = np.array([clipped is None or not clipped[s].any() for s in slices], dtype=bool)
    turn = np.array([np.linalg.norm(dtheta[s], axis=1).sum() for s in slices])
    noise = np.ones((len(T), 2))
    for r, (a, b) in enumerate(zip(rests.start, rests.end, strict=True)):
        for k, (x, density) in enumerate(((dv, profile.vrw), (dtheta, profile.arw))):
            noise[r, k] = rest_noise_factor(x[a:b], T[r], density)
    # Readings written coarser than their noise (:mod:`calib.hand.rounding`): an accelerometer's
    # rounding differs from pose to pose, a floor on each rest's mean; a gyro's is the same at
    # every rest (bias and Earth rate within a step), considered in the covariance instead.
    f, w = dv / dt[:, None], dtheta / dt[:, None]
    steps = np.array([[reading_step(x[:, i]) for i in range(3)] for x in (f, w)])
    floor = rest_rounding(f, rests.start, rests.end, steps[0]).max(axis=1, initial=0.0)
    noise[:, 0] = np.sqrt(noise[:, 0] ** 2 + floor**2 * T / profile.vrw**2)
    shared = rest_rounding(w, rests.start, rests.end, steps[1])
    return HandData(rests, T, rate, force, slices, used, turn, noise, steps, shared)


def distinct_poses(rest_force: np.ndarray, apart_deg: float = POSE_APART_DEG) -> int:
    """How many gravity directions the rests hold, each at least ``apart_deg`` from the others
    (greedy, in time order): what a user counts as the poses of a hand run.
    """
    up = rest_force / np.linalg.norm(rest_force, axis=1, keepdims=True)
    kept: list[np.ndarray] = []
    for u in up:
        if all(float(u @ k) < math.cos(math.radians(apart_deg)) for k in kept):
            kept.append(u)
    return len(kept)
