"""What the design search needs from a real gimbal (``design --gimbal FILE``).

The search walks moves of whole quarter turns; with a gimbal each child is
played by :func:`calib.gimbal.rule.plan_move` from its parent's encoder state
(continuous angles, so winding counts) and dropped when the move breaks a
limit (range, lock margin, rate, acceleration, or a lock counter-rotation
longer than the shortest rest). A gimbal that must end at home only accepts
complete walks whose encoders are back at 0, and partial walks that can no
longer get there within the flips and time left are dropped early.

The move profile is one for the whole design: the slowest axis's rate,
acceleration and jerk limits (every move is then playable on whichever
gimbal plays it). The search's segment algebra keeps a constant-rate turn
with the real (trapezoid) duration; the exact re-scoring analyses the
written sequence, whose steps carry ``accel_dps2``.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from calib.errors import CalibError
from calib.gimbal.description import Gimbal, load_gimbal
from calib.gimbal.rule import plan_move, plan_sequence
from calib.sequence.rate_profile import RateProfile

HOME_TOL_RAD = 1e-6  # encoder "at 0": grid moves land on multiples of pi/2 to rounding
MAX_DESIGN_RATE_DPS = 100.0  # check_constraints' upper bound on --rate-dps


def _slowest(gimbal: Gimbal, attr: str) -> float:
    return min(getattr(a, attr) for a in gimbal.axes)


def gimbal_limits(gimbal: Gimbal, rate_dps: float | None, default_rate_dps: float = 10.0) -> dict:
    """``rate_dps``, ``accel_dps2`` and ``jerk_dps3`` of every designed move on ``gimbal``.

    ``rate_dps=None`` takes the slowest axis's rate limit (``default_rate_dps``
    when the gimbal sets none); an explicit rate above it is refused.
    """
    top = math.degrees(_slowest(gimbal, "max_rate"))
    where = f"gimbal {gimbal.path or gimbal.name}"
    if rate_dps is None:
        rate_dps = min(top, MAX_DESIGN_RATE_DPS) if math.isfinite(top) else default_rate_dps
    elif rate_dps > top * (1 + 1e-9):
        raise CalibError(
            f"rate_dps {rate_dps:g} is above the {top:g} deg/s gimbal {gimbal.name!r} turns at most",
            where,
            f"give a rate <= {top:g} deg/s (the CLI's --rate-dps), or none to use the gimbal's rate",
        )
    accel = math.degrees(_slowest(gimbal, "max_accel"))
    jerk = math.degrees(_slowest(gimbal, "max_jerk"))
    if math.isfinite(jerk) and not math.isfinite(accel):
        raise CalibError(
            f"gimbal {gimbal.name!r} limits jerk but not acceleration",
            where,
            "give max_accel_dps2 on the axes too (a move needs both to be an S-curve)",
        )
    return {
        "rate_dps": float(rate_dps),
        "accel_dps2": accel if math.isfinite(accel) else None,
        "jerk_dps3": jerk if math.isfinite(jerk) else None,
    }


def gimbal_constraints(gimbal, constraints: dict) -> tuple[Gimbal | None, dict]:
    """The gimbal (path, shipped name or :class:`Gimbal`) and the constraints with its limits.

    ``constraints['rate_dps'] = None`` means "the gimbal's own rate".
    """
    if gimbal is None:
        out = dict(constraints)
        if out.get("rate_dps", 0) is None:
            out["rate_dps"] = 10.0
        return None, out
    g = load_gimbal(gimbal)
    return g, dict(constraints) | gimbal_limits(g, constraints.get("rate_dps")) | {"gimbal": g}


def move_profile(rate_dps: float, accel_dps2: float | None, jerk_dps3: float | None) -> RateProfile:
    """The rate profile of a designed move (SI)."""
    return RateProfile(
        rate=math.radians(rate_dps),
        accel=math.inf if accel_dps2 is None else math.radians(accel_dps2),
        jerk=math.inf if jerk_dps3 is None else math.radians(jerk_dps3),
    )


@functools.lru_cache(maxsize=65536)
def _planned(
    gimbal: Gimbal, enc: tuple, axis: str, angle_deg: float, profile: RateProfile, longest_unlock_s: float
):
    mv = plan_move(gimbal, np.array(enc), axis, math.radians(angle_deg), profile)
    if not mv.playable or mv.unlock_s > longest_unlock_s + 1e-9:
        return None
    return tuple(float(a) for a in mv.state_end)


def next_encoders(c, enc: tuple, mv) -> tuple | None:
    """Encoder state after ``mv`` from ``enc`` on ``c.gimbal``, or None when it refuses.

    A lock counter-rotation is played in the rest before the flip, so it must
    fit the shortest rest the design may give (``c.min_dwell_s``).
    """
    prof = move_profile(c.rate_dps, c.accel_dps2, c.jerk_dps3)
    return _planned(c.gimbal, enc, mv.axis, float(mv.angle_deg), prof, c.min_dwell_s)


def at_home(enc) -> bool:
    """Whether every encoder is back at 0 (no gimbal: always)."""
    return enc is None or all(abs(a) <= HOME_TOL_RAD for a in enc)


def home_reachable(c, enc: tuple, n_moves: int, time_s: float, min_turn_s: float) -> bool:
    """Whether a walk at encoders ``enc`` can still end at home (a necessary condition).

    Every encoder away from 0 must move once more. Off lock a grid move turns
    one gimbal; in lock a counter-rotation plus the flip turn three.
    """
    if c.gimbal is None or not c.gimbal.end_at_home:
        return True
    away = sum(abs(a) > HOME_TOL_RAD for a in enc)
    per_move = 1 if c.gimbal.lock_margin > 0 else 3
    need = math.ceil(away / per_move)
    return n_moves + need <= c.max_flips and time_s + need * (min_turn_s + c.min_dwell_s) <= c.budget_s + 1e-9


def check_sequence_plays(seq, gimbal: Gimbal | None, where: str = "design") -> None:
    """Refuse (a bug guard) a designed sequence the gimbal cannot play."""
    if gimbal is None:
        return
    plan = plan_sequence(seq, gimbal)
    if not plan.playable:
        raise CalibError(
            f"the designed sequence breaks a limit: {plan.violations[0]}",
            where,
            "report this: the search should only propose playable moves",
        )
