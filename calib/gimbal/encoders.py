"""Where the gimbals stand: encoder angles and rates along a run, and at each rest position.

The encoder angles are continuous (cumulative, zero at the start attitude), as
:func:`calib.gimbal.rule.plan_sequence` plans them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.nav.transform import describe_axis, on_grid
from calib.sequence.definition import Sequence, timeline
from calib.sequence.rate_profile import Pieces

from .description import DEFAULT_GIMBAL
from .rule import GimbalPlan, Move, in_lock, plan_sequence


def _piece_eval(pieces: Pieces, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|angle| and |rate| of a profile ``tau`` seconds into it (clipped to the move)."""
    ends = np.cumsum(pieces.duration)
    tau = np.clip(tau, 0.0, ends[-1])
    i = np.clip(np.searchsorted(ends, tau, side="left"), 0, len(ends) - 1)
    local = tau - (ends[i] - pieces.duration[i])
    return np.abs(pieces.angle(i, local)), np.abs(pieces.rate(i, local))


def encoder_track(plan: GimbalPlan, seq, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Encoder angles (rad) and rates (rad/s) at ``time_s``: ``(n, 3)`` each.

    ``plan`` says which gimbal plays each step (and any unlock); ``seq``
    gives the angles and times actually played. They are the same sequence
    except in a simulation with flip errors, where ``plan`` is the nominal
    sequence's and each move then turns its gimbal by the real angle.
    """
    t = np.asarray(time_s, dtype=float)
    angles, rates = np.zeros((len(t), 3)), np.zeros((len(t), 3))
    track = (angles, rates)
    state, t0 = np.zeros(3), seq.initial_dwell_s
    for _k, (s, mv) in enumerate(zip(seq.steps, plan.moves, strict=True)):
        if mv.unlock_s > 0:
            assert mv.unlock_profile is not None  # plan_move sets it with any unlock time
            u = float(np.max(np.abs(mv.unlock)))
            _fill(
                track,
                t,
                t0 - mv.unlock_s,
                t0,
                state,
                mv.unlock / u,
                mv.unlock_profile.pieces(u),
                None,
            )
            state = state + mv.unlock
        pieces = s.profile.pieces(math.radians(s.angle_deg))
        sign = 1.0 if s.angle_deg > 0 else -1.0
        end = _fill(
            track,
            t,
            t0,
            t0 + s.duration_s,
            state,
            sign * mv.direction,
            pieces,
            mv if mv.gimbal < 0 else None,
        )
        state, t0 = end, t0 + s.duration_s + s.dwell_s
    return angles, rates


def _fill(
    track: tuple[np.ndarray, np.ndarray],
    t,
    t_a: float,
    t_b: float,
    state,
    direction,
    pieces: Pieces,
    combined: Move | None,
) -> np.ndarray:
    """Write one motion into the track (angles, rates) from ``t_a`` on (later motions overwrite the hold)."""
    angles, rates = track
    after = t >= t_a
    th, w = _piece_eval(pieces, t[after] - t_a)
    if combined is None:
        angles[after] = state + np.outer(th, direction)
        rates[after] = np.outer(np.where(t[after] <= t_b, w, 0.0), direction)
        return state + direction * abs(float(pieces.theta0[-1]) + _last_sweep(pieces))
    assert combined.path is not None and combined.path_theta is not None  # a combined move's path
    p, theta = combined.path - combined.path[0] + state, combined.path_theta
    slope = np.gradient(p, theta, axis=0)
    for g in range(3):
        angles[after, g] = np.interp(th, theta, p[:, g])
        rates[after, g] = np.where(t[after] <= t_b, np.interp(th, theta, slope[:, g]) * w, 0.0)
    return p[-1]


def _last_sweep(pieces: Pieces) -> float:
    d = pieces.duration[-1]
    return float(pieces.rate0[-1] * d + 0.5 * pieces.accel0[-1] * d * d + pieces.jerk[-1] * d**3 / 6)


@dataclass(frozen=True)
class RestPosition:
    """A rest position of a sequence, as ``show`` prints it."""

    number: int
    C_b_n: np.ndarray
    directions: tuple[str, ...]  # where body X, Y, Z point
    gimbal_deg: np.ndarray  # outer, middle, inner; continuous along the sequence
    start_s: float
    end_s: float
    gimbal_lock: bool
    on_grid: bool = True  # False: some axis is off the E/N/U grid (non-90-degree flips)


def rest_positions(seq: Sequence, gimbal=None) -> list[RestPosition]:
    """Rest positions with their attitudes and continuous (encoder) gimbal angles.

    The encoder angles are those of :func:`calib.gimbal.rule.plan_sequence` on
    ``gimbal`` (default: slip rings, no limits) at the start of each rest,
    before any lock counter-rotation played at the rest's end.
    """
    tl = timeline(seq)
    plan = plan_sequence(seq, gimbal or DEFAULT_GIMBAL)
    out = []
    for seg in np.flatnonzero(tl.rate == 0.0):
        k = int(tl.step[seg])
        state = np.zeros(3) if k < 0 else plan.state_after(k)
        C = tl.C0[seg]
        out.append(
            RestPosition(
                number=int(tl.position[seg]),
                C_b_n=C,
                directions=tuple(describe_axis(C[:, i]) for i in range(3)),
                gimbal_deg=np.round(np.degrees(state), 9) + 0.0,
                start_s=float(tl.t0[seg]),
                end_s=float(tl.t1[seg]),
                gimbal_lock=in_lock(state),
                on_grid=on_grid(C),
            )
        )
    return out
