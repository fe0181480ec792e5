"""The plan of a calibration run placed by hand: rest attitudes, rests, moves.

A unit placed by hand (no gimbal) rests on a table in a pose, is picked up,
turned about arbitrary axes and carried, and put down in the next pose. A
:class:`HandPlan` holds what decides that trajectory exactly: the rest
attitudes, how long each rest and each move lasts, how long the turn inside a
move takes, where the unit is carried and how much its turning axis wobbles.
:mod:`calib.hand.simulate` turns a plan into the continuous trajectory and the IMU
increments; ``docs/by-hand-sim.md`` describes the physics.

Shapes of a move, as functions of its normalised time ``s`` in ``[0, 1]``:

* :func:`min_jerk` ``10 s^3 - 15 s^4 + 6 s^5``, from 0 to 1 with zero rate and
  acceleration at both ends: the fraction of the geodesic turn done;
* :func:`bump` ``64 s^3 (1 - s)^3``, from 0 up to 1 at ``s = 1/2`` and back to 0,
  with zero first and second derivatives at both ends: the wobble angle and the
  carried distance (out and back).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from calib.nav.transform import dcm_to_rotvec, quat_to_dcm

DEG = np.pi / 180.0


def min_jerk(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The minimum-jerk ramp and its first two derivatives in ``s``.

    Parameters
    ----------
    s : ndarray
        Normalised time, clipped to ``[0, 1]`` (0 before, 1 after).

    Returns
    -------
    value, d1, d2 : ndarray
    """
    s = np.clip(s, 0.0, 1.0)
    u = 1.0 - s
    return s**3 * (10.0 - 15.0 * s + 6.0 * s * s), 30.0 * s * s * u * u, 60.0 * s * u * (1.0 - 2.0 * s)


def bump(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``64 s^3 (1 - s)^3`` and its first two derivatives in ``s`` (0 outside ``[0, 1]``)."""
    s = np.clip(s, 0.0, 1.0)
    u = 1.0 - s
    return (
        64.0 * s**3 * u**3,
        192.0 * s * s * u * u * (1.0 - 2.0 * s),
        384.0 * s * u * ((1.0 - 2.0 * s) ** 2 - s * u),
    )


_S_GRID = np.linspace(0.0, 1.0, 20001)


def peak_factor(angle_rad: np.ndarray, wobble_rad: np.ndarray) -> np.ndarray:
    """Peak of ``|omega_nb| * turn_s`` of turns of ``angle_rad`` with wobble ``wobble_rad``.

    The turn's rate is ``(min_jerk'(s) R_w^T phi + a bump'(s) e) / turn_s`` with the
    wobble axis ``e`` perpendicular to the rotation vector ``phi`` (and so to
    ``R_w^T phi``, ``R_w`` being a rotation about ``e``): its norm is
    ``sqrt((theta min_jerk')^2 + (a bump')^2) / turn_s``, maximised here over
    ``s`` on a grid of 20001 points (relative error below 1e-8).
    """
    th = np.atleast_1d(np.asarray(angle_rad, dtype=float))[:, None]
    a = np.atleast_1d(np.asarray(wobble_rad, dtype=float))[:, None]
    d_turn, d_wob = min_jerk(_S_GRID)[1], bump(_S_GRID)[1]
    return np.max(np.hypot(th * d_turn, a * d_wob), axis=1)


@dataclass(frozen=True)
class HandPlan:
    """Everything that fixes the trajectory of a run placed by hand.

    Rest ``k`` holds attitude ``C_b_n[k]``; move ``k`` takes the unit from rest
    ``k`` to rest ``k + 1``. Times in s, angles in rad, lengths in m.

    Attributes
    ----------
    C_b_n : ndarray, shape (K, 3, 3)
        Rest attitudes, body to ENU.
    rest_s : ndarray, shape (K,)
        Duration of each rest.
    move_s : ndarray, shape (K - 1,)
        Duration of each move (lift, turn, carry, put down).
    turn_s : ndarray, shape (K - 1,)
        Duration of the turn, centred in its move (``0 < turn_s <= move_s``).
    translation_m : ndarray, shape (K - 1, 3)
        ENU displacement at the middle of each move; the unit is carried there
        and back (zero: no translation).
    wobble_rad : ndarray, shape (K - 1,)
        Peak angle of the wobble about ``wobble_axis`` (0: a fixed-axis turn).
    wobble_axis : ndarray, shape (K - 1, 3)
        Body-frame unit vector of each wobble, perpendicular to the move's
        rotation vector :attr:`rotvec`.
    """

    C_b_n: np.ndarray
    rest_s: np.ndarray
    move_s: np.ndarray
    turn_s: np.ndarray
    translation_m: np.ndarray
    wobble_rad: np.ndarray
    wobble_axis: np.ndarray

    def __post_init__(self):
        C = np.asarray(self.C_b_n, dtype=float).reshape(-1, 3, 3)
        k = len(C)
        arrays = {
            "rest_s": (k,),
            "move_s": (k - 1,),
            "turn_s": (k - 1,),
            "translation_m": (k - 1, 3),
            "wobble_rad": (k - 1,),
            "wobble_axis": (k - 1, 3),
        }
        object.__setattr__(self, "C_b_n", C)
        for name, shape in arrays.items():
            value = np.asarray(getattr(self, name), dtype=float).reshape(shape)
            object.__setattr__(self, name, value)
        if k < 1:
            raise ValueError("a plan needs at least one rest")
        if not np.allclose(C @ C.transpose(0, 2, 1), np.eye(3), atol=1e-12) or np.any(np.linalg.det(C) < 0):
            raise ValueError("C_b_n must be rotation matrices")
        if np.any(self.rest_s <= 0) or np.any(self.move_s <= 0) or np.any(self.turn_s <= 0):
            raise ValueError("rest, move and turn durations must be positive")
        if np.any(self.turn_s > self.move_s * (1.0 + 1e-12)):
            raise ValueError("a turn cannot last longer than its move")
        if not np.all(np.isfinite(self.translation_m)) or not np.all(np.isfinite(self.wobble_rad)):
            raise ValueError("translations and wobble angles must be finite")
        wobbling = self.wobble_rad != 0.0
        axis = self.wobble_axis[wobbling]
        if not np.allclose(np.linalg.norm(axis, axis=1), 1.0, atol=1e-9):
            raise ValueError("wobble axes must be unit vectors")
        phi = self.rotvec[wobbling]
        theta = np.linalg.norm(phi, axis=1)
        if np.any(np.abs(np.einsum("ij,ij->i", axis, phi)) > 1e-9 * np.maximum(theta, 1.0)):
            raise ValueError("a wobble axis must be perpendicular to its move's rotation vector")

    @property
    def n_poses(self) -> int:
        """Number of rests ``K``."""
        return len(self.C_b_n)

    @property
    def rotvec(self) -> np.ndarray:
        """Body-frame rotation vector ``log(C_k^T C_{k+1})`` of each move, shape (K - 1, 3)."""
        if self.n_poses < 2:
            return np.zeros((0, 3))
        return dcm_to_rotvec(self.C_b_n[:-1].transpose(0, 2, 1) @ self.C_b_n[1:])

    @property
    def rest_start_s(self) -> np.ndarray:
        """When each rest begins (the run begins at 0 with rest 0)."""
        lengths = np.concatenate([[0.0], self.rest_s[:-1] + self.move_s])
        return np.cumsum(lengths)

    @property
    def rest_end_s(self) -> np.ndarray:
        """When each rest ends (and the next move begins)."""
        return self.rest_start_s + self.rest_s

    @property
    def turn_start_s(self) -> np.ndarray:
        """When the turn of each move begins."""
        return self.rest_end_s[:-1] + 0.5 * (self.move_s - self.turn_s)

    @property
    def duration_s(self) -> float:
        """Length of the run: all rests and moves."""
        return float(self.rest_s.sum() + self.move_s.sum())

    @property
    def breakpoints_s(self) -> np.ndarray:
        """Instants where the motion is not infinitely smooth: rest and turn ends, sorted."""
        turn0 = self.turn_start_s
        t = np.concatenate([self.rest_start_s, self.rest_end_s, turn0, turn0 + self.turn_s])
        return np.unique(t)

    @property
    def peak_rate_rad_s(self) -> np.ndarray:
        """Peak of ``|omega_nb|`` in each move (Earth rate aside), rad/s."""
        theta = np.linalg.norm(self.rotvec, axis=1)
        return peak_factor(theta, self.wobble_rad) / self.turn_s


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation matrix uniform on SO(3) (a normalised Gaussian quaternion)."""
    q = rng.standard_normal(4)
    return quat_to_dcm(q / np.linalg.norm(q))


def random_poses(n_poses: int, rng: np.random.Generator, min_step_deg: float = 30.0) -> np.ndarray:
    """``n_poses`` attitudes uniform on SO(3), each at least ``min_step_deg`` from the one before."""
    poses = [random_rotation(rng)]
    while len(poses) < n_poses:
        C = random_rotation(rng)
        angle = np.linalg.norm(dcm_to_rotvec(poses[-1].T @ C))
        if angle >= np.radians(min_step_deg):
            poses.append(C)
    return np.array(poses)


def perpendicular_axes(rotvec: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random unit vector perpendicular to each row of ``rotvec`` (any unit vector for a zero row)."""
    out = np.empty_like(rotvec)
    for i, phi in enumerate(rotvec):
        theta = np.linalg.norm(phi)
        while True:
            e = rng.standard_normal(3)
            if theta > 0:
                u = phi / theta
                e = e - (e @ u) * u
            if np.linalg.norm(e) > 1e-3:
                out[i] = e / np.linalg.norm(e)
                break
    return out


@dataclass(frozen=True)
class PlanShape:
    """How a random plan placed by hand is shaped: its rests, moves, turns, carries and wobbles.

    Parameters
    ----------
    rest_s : (float, float)
        Range of the rests after the first, uniform.
    move_s : (float, float)
        Range of the moves, uniform.
    first_rest_s : float
        The first rest (a long static start).
    min_step_deg : float
        Each pose is at least this far (rotation angle) from the one before.
    translation_m : float
        Each move carries the unit out and back by a distance drawn uniformly in
        ``[0.5, 1] * translation_m``, in a random direction (0: no translation).
    wobble_deg : float
        Each move's wobble peaks at an angle drawn uniformly in ``[0.5, 1] * wobble_deg``.
    peak_rate_dps : float, optional
        None: each turn lasts its whole move. Given: the largest turn of the
        plan peaks at exactly ``peak_rate_dps``, and a turn of angle ``theta``
        at ``u theta / theta_max`` of it, ``u`` uniform in ``[0.5, 1]`` (a hand
        turns small and large angles in about the same time, 1 to 2 times the
        largest turn's); each turn lasts what its angle and wobble need at its
        rate, and a move is lengthened to hold a turn longer than it.
    """

    rest_s: tuple[float, float] = (5.0, 12.0)
    move_s: tuple[float, float] = (1.0, 3.0)
    first_rest_s: float = 50.0
    min_step_deg: float = 30.0
    translation_m: float = 0.3
    wobble_deg: float = 10.0
    peak_rate_dps: float | None = None


HAND_PLAN = PlanShape()  # the defaults
HAND_POSES = 20  # the rests of a random plan when not told (the CLI's --poses too)


def random_hand_plan(n_poses: int, rng: np.random.Generator, shape: PlanShape = HAND_PLAN) -> HandPlan:
    """A random plan: poses uniform on SO(3), rests and moves of random length.

    Parameters
    ----------
    n_poses : int
        Number of rests ``K`` (the first one included).
    rng : numpy.random.Generator
    shape : PlanShape
        The rests', moves', turns', carries' and wobbles' sizes.

    Returns
    -------
    HandPlan
    """
    rest_s, move_s, first_rest_s = shape.rest_s, shape.move_s, shape.first_rest_s
    translation_m, wobble_deg, peak_rate_dps = shape.translation_m, shape.wobble_deg, shape.peak_rate_dps
    if n_poses < 1:
        raise ValueError("n_poses must be at least 1")
    C = random_poses(n_poses, rng, shape.min_step_deg)
    m = n_poses - 1
    rests = np.concatenate([[first_rest_s], rng.uniform(*rest_s, m)])
    moves = rng.uniform(*move_s, m)
    phi = dcm_to_rotvec(C[:-1].transpose(0, 2, 1) @ C[1:]) if m else np.zeros((0, 3))
    wobble = np.radians(wobble_deg) * rng.uniform(0.5, 1.0, m)
    axes = perpendicular_axes(phi, rng)
    direction = rng.standard_normal((m, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    translation = direction * (translation_m * rng.uniform(0.5, 1.0, m))[:, None]
    turns = moves.copy()
    if peak_rate_dps is not None and m:
        theta = np.linalg.norm(phi, axis=1)
        u = rng.uniform(0.5, 1.0, m)
        u[np.argmax(theta)] = 1.0
        rate = np.radians(peak_rate_dps) * u * theta / theta.max()
        turns = peak_factor(theta, wobble) / rate
        moves = np.maximum(moves, turns)
    return HandPlan(C, rests, moves, turns, translation, wobble, axes)


XSENS_POSES = 38  # the long static start and 37 hand-placed poses
XSENS_DURATION_S = 512.0


def xsens_like_plan(rng: np.random.Generator, shape: PlanShape = HAND_PLAN) -> HandPlan:
    """A plan shaped like imu_tk's Xsens recording (see ``docs/by-hand-sim.md``).

    A 52 s static start, then 37 poses held 5-12 s, moves of 2.5-5 s between them,
    512 s in all: the rests after the first are scaled by one common factor (a few
    per cent) so that the run lasts exactly 512 s. ``shape`` gives the turns, carries
    and wobbles; the rests and moves are the recording's.
    """
    recording = replace(shape, rest_s=(5.0, 12.0), move_s=(2.5, 5.0), first_rest_s=52.0)
    plan = random_hand_plan(XSENS_POSES, rng, recording)
    rests = plan.rest_s.copy()
    rests[1:] *= (XSENS_DURATION_S - rests[0] - plan.move_s.sum()) / rests[1:].sum()
    return HandPlan(
        plan.C_b_n, rests, plan.move_s, plan.turn_s, plan.translation_m, plan.wobble_rad, plan.wobble_axis
    )
