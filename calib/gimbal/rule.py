"""The gimbal: its limits, which gimbal plays each flip, gimbal lock, and the encoder angles.

The single source of the gimbal rule of the conventions::

    C_b_n = C_start R_Z(outer) R_X(middle) R_Y(inner)

Angles are encoder angles: continuous (cumulative, so winding counts), zero
at the start attitude, radians inside. Rotating one gimbal by ``d`` turns the
body by ``d`` about that gimbal's axis, so a flip about body axis ``a`` is
one gimbal moving whenever a gimbal axis lies along ``a``:

- the inner axis is always body Y;
- the middle axis is ``R_Y(inner)^T e_x`` in the body;
- the outer axis is ``(R_X(middle) R_Y(inner))^T e_z`` in the body.

**Gimbal lock** (``cos(middle) = 0``): the outer axis coincides with the
inner (body Y) and only ``outer + inner`` (middle = +90 deg) or
``outer - inner`` (-90 deg) matters. A flip about body X or Z that the middle
axis does not hold then needs the outer and inner gimbals to counter-rotate
first (``inner += d``, ``outer -= sin(middle) d``), which leaves the IMU
still and brings the middle axis onto the flip axis. That *unlock* is played
at the end of the rest before the flip, at the gimbal's own limits.

A middle-gimbal move through +-90 deg is one move: its encoder angle simply
grows, so encoder angles stay continuous.

Flips that no gimbal holds outside lock (after non-90-degree flips) are
*combined* moves: several gimbals turn at once, and their encoder angles
follow the continuous decomposition of the attitude along the flip (sampled
every 0.5 deg of flip, interpolated in between: approximate, unlike the
single-gimbal moves, which are exact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.nav.transform import axis_index, gimbal_from_relative, gimbal_to_relative, rot_axis, unwrap_gimbal
from calib.sequence.rate_profile import Pieces, RateProfile

from .description import DEFAULT_GIMBAL, NAMES, Gimbal, builtin_gimbal_dir

PARALLEL_TOL = 1e-9  # |cos| of a gimbal axis to the flip axis beyond 1 - this counts as along it
LIMIT_TOL = 1e-9  # relative slack on rate/acceleration limits, absolute (rad) on ranges
COMBINED_STEP_RAD = math.radians(0.5)


# ---------------------------------------------------------------------------
# One move


@dataclass(frozen=True)
class Violation:
    """A limit a move (or the sequence) breaks."""

    step: int | None  # 1-based step number, None for the whole sequence
    gimbal: str
    limit: str  # range, lock margin, rate, acceleration, jerk, rest, home
    what: str

    def __str__(self) -> str:
        where = f"step {self.step}" if self.step is not None else "sequence"
        return f"{where}: {self.gimbal} gimbal: {self.what}"


@dataclass(frozen=True)
class Move:
    """How a gimbal plays one flip (SI; encoder states are (outer, middle, inner) in rad).

    ``unlock`` is the encoder change of the lock counter-rotation played
    before the flip (zeros when none is needed), taking ``unlock_s``.
    ``direction`` is the encoder change per radian of flip (single-gimbal
    moves: one entry +-1); combined moves carry a sampled ``path`` instead.
    """

    state_start: np.ndarray
    unlock: np.ndarray
    unlock_s: float
    unlock_profile: RateProfile | None
    gimbal: int  # 0 outer, 1 middle, 2 inner, -1 combined
    direction: np.ndarray
    duration_s: float
    state_end: np.ndarray
    violations: tuple[Violation, ...] = ()
    path_theta: np.ndarray | None = field(default=None, repr=False)
    path: np.ndarray | None = field(default=None, repr=False)

    @property
    def playable(self) -> bool:
        return not self.violations

    @property
    def gimbal_name(self) -> str:
        return NAMES[self.gimbal] if self.gimbal >= 0 else "combined"


def gimbal_axes_in_body(state: np.ndarray) -> np.ndarray:
    """Rows: the outer, middle and inner axes written in the body frame at encoder ``state``."""
    _, m, i = state
    Ri = rot_axis(1, i)
    return np.array([(rot_axis(0, m) @ Ri).T @ [0.0, 0.0, 1.0], Ri.T @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def in_lock(state: np.ndarray) -> bool:
    """Whether encoder angles ``state`` (rad) put the outer and inner axes in line."""
    return abs(math.cos(state[1])) < PARALLEL_TOL


def _holding_gimbal(state: np.ndarray, ax: int) -> tuple[int, float]:
    """The gimbal whose axis lies along body axis ``ax`` (inner first) and the sign, or (-1, 0)."""
    dots = gimbal_axes_in_body(state)[:, ax]
    for g in (2, 1, 0):
        if abs(dots[g]) > 1.0 - PARALLEL_TOL:
            return g, math.copysign(1.0, dots[g])
    return -1, 0.0


def _unlock_candidates(state: np.ndarray, ax: int) -> list[np.ndarray]:
    """Counter-rotations that bring the middle axis onto body X or Z at a locked rest, shortest first."""
    target = 0.0 if ax == 0 else 0.5 * math.pi  # middle axis in body = (cos i, 0, sin i)
    d = math.remainder(target - state[2], math.pi)  # in [-pi/2, pi/2]
    out = []
    for delta in sorted({d, d - math.copysign(math.pi, d)}, key=abs):
        out.append(np.array([-math.sin(state[1]) * delta, 0.0, delta]))
    return out


def unlock_profile(gimbal: Gimbal, profile: RateProfile) -> RateProfile:
    """Outer and inner counter-rotate at the slower one's limits, else at the flip's profile."""
    o, i = gimbal.axes[0], gimbal.axes[2]

    def pick(a, b, own):
        lim = min(a, b)
        return lim if math.isfinite(lim) else own

    return RateProfile(
        rate=pick(o.max_rate, i.max_rate, profile.rate),
        accel=pick(o.max_accel, i.max_accel, profile.accel),
        jerk=pick(o.max_jerk, i.max_jerk, profile.jerk),
    )


def plan_move(
    gimbal: Gimbal,
    state: np.ndarray,
    axis: str | int,
    angle_rad: float,
    profile: RateProfile,
    step: int | None = None,
) -> Move:
    """How ``gimbal`` plays a flip about body ``axis`` by ``angle_rad`` from encoder ``state``.

    Pure: returns the new encoder state, the move's duration, any lock
    counter-rotation it needs first (and its duration), and every limit it
    breaks (``Move.violations``; empty when playable). ``step`` (1-based)
    only labels the violations.
    """
    ax = axis if isinstance(axis, int) else axis_index(axis)
    state = np.asarray(state, dtype=float)
    pieces = profile.pieces(angle_rad)
    unlock, u_prof, u_s = np.zeros(3), None, 0.0
    g, sign = _holding_gimbal(state, ax)
    if g < 0 and in_lock(state):
        u_prof = unlock_profile(gimbal, profile)
        best = None
        for cand in _unlock_candidates(state, ax):
            g2, s2 = _holding_gimbal(state + cand, ax)
            v = _unlock_violations(gimbal, state, cand, u_prof, step)
            if best is None or (not v and best[3]):
                best = (cand, g2, s2, v)
        assert best is not None  # _unlock_candidates always offers two
        unlock, g, sign, u_viol = best
        u_s = u_prof.duration_s(float(np.max(np.abs(unlock))))
    else:
        u_viol = []
    start = state + unlock
    if g >= 0:
        direction = np.zeros(3)
        direction[g] = sign
        end = start + direction * angle_rad
        viol = _single_violations(gimbal, start, end, g, pieces, step)
        return Move(state, unlock, u_s, u_prof, g, direction, pieces.duration_s, end, tuple(u_viol + viol))
    theta, path = combined_path(start, ax, angle_rad)
    viol = _combined_violations(gimbal, theta, path, pieces, step)
    return Move(
        state,
        unlock,
        u_s,
        u_prof,
        -1,
        np.zeros(3),
        pieces.duration_s,
        path[-1],
        tuple(u_viol + viol),
        theta,
        path,
    )


# ---------------------------------------------------------------------------
# Limits


def _range_violations(
    gimbal: Gimbal, lo: np.ndarray, hi: np.ndarray, step, moving=(0, 1, 2)
) -> list[Violation]:
    """Range limits of the gimbals that move.

    A gimbal left beyond its range was flagged when it got there.
    """
    out = []
    for g, a in enumerate(gimbal.axes):
        if g not in moving:
            continue
        if lo[g] < a.min_angle - LIMIT_TOL or hi[g] > a.max_angle + LIMIT_TOL:
            bad = lo[g] if lo[g] < a.min_angle - LIMIT_TOL else hi[g]
            out.append(
                Violation(
                    step,
                    a.name,
                    "range",
                    f"reaches {math.degrees(bad):.1f} deg, beyond its range "
                    f"[{math.degrees(a.min_angle):g}, {math.degrees(a.max_angle):g}] "
                    f"deg of gimbal {gimbal.name!r}",
                )
            )
    return out


def lock_distance(lo: float, hi: float) -> float:
    """Smallest distance (rad) from the middle-angle interval [lo, hi] to any 90 + k 180 deg."""
    k = math.ceil((lo - 0.5 * math.pi) / math.pi)
    if 0.5 * math.pi + k * math.pi <= hi:
        return 0.0
    return min(
        abs(math.remainder(lo - 0.5 * math.pi, math.pi)), abs(math.remainder(hi - 0.5 * math.pi, math.pi))
    )


def _lock_violations(gimbal: Gimbal, lo: float, hi: float, step) -> list[Violation]:
    if gimbal.lock_margin <= 0.0:
        return []
    d = lock_distance(lo, hi)
    if d >= gimbal.lock_margin - LIMIT_TOL:
        return []
    return [
        Violation(
            step,
            "middle",
            "lock margin",
            f"comes within {math.degrees(d):.1f} deg of gimbal lock (|middle| = 90 deg); "
            f"gimbal {gimbal.name!r} keeps {math.degrees(gimbal.lock_margin):g} deg away",
        )
    ]


def _dynamic_violations(
    gimbal: Gimbal, g: int, gain: float, curve: float, pieces: Pieces, profile_jerk: float, step
) -> list[Violation]:
    """Rate, acceleration and jerk of gimbal ``g`` turning ``gain`` rad per rad of flip."""
    a = gimbal.axes[g]
    out = []
    rate = gain * pieces.peak_rate
    if rate > a.max_rate * (1 + LIMIT_TOL):
        out.append(
            Violation(
                step,
                a.name,
                "rate",
                f"turns at {math.degrees(rate):.3g} deg/s, above its {math.degrees(a.max_rate):g} deg/s",
            )
        )
    accel = gain * pieces.peak_accel + curve * pieces.peak_rate**2
    if np.any(pieces.rate0[:1] != 0.0) and math.isfinite(a.max_accel):
        out.append(
            Violation(
                step,
                a.name,
                "acceleration",
                "starts at full rate in zero time (no accel_dps2), but it accelerates "
                f"at most {math.degrees(a.max_accel):g} deg/s^2 (give the step "
                f"accel_dps2 <= {math.degrees(a.max_accel):g})",
            )
        )
    elif accel > a.max_accel * (1 + LIMIT_TOL):
        out.append(
            Violation(
                step,
                a.name,
                "acceleration",
                f"accelerates at "
                f"{math.degrees(accel):.3g} deg/s^2, above its "
                f"{math.degrees(a.max_accel):g} deg/s^2",
            )
        )
    if math.isfinite(a.max_jerk) and (
        math.isinf(profile_jerk) or gain * profile_jerk > a.max_jerk * (1 + LIMIT_TOL)
    ):
        out.append(
            Violation(
                step,
                a.name,
                "jerk",
                f"needs jerk above its {math.degrees(a.max_jerk):g} deg/s^3 (give jerk_dps3 within it)",
            )
        )
    return out


def _jerk_of(pieces: Pieces) -> float:
    return (
        float(np.max(np.abs(pieces.jerk)))
        if np.any(pieces.jerk)
        else (math.inf if np.any(pieces.accel0) or np.any(pieces.rate0[:1]) else 0.0)
    )


def _single_violations(gimbal: Gimbal, start, end, g: int, pieces: Pieces, step) -> list:
    lo, hi = np.minimum(start, end), np.maximum(start, end)
    out = _range_violations(gimbal, lo, hi, step, (g,))
    if g == 1:  # a rest in lock is reached by a middle move and flagged there
        out += _lock_violations(gimbal, lo[1], hi[1], step)
    return out + _dynamic_violations(gimbal, g, 1.0, 0.0, pieces, _jerk_of(pieces), step)


def _unlock_violations(gimbal: Gimbal, state, unlock, prof: RateProfile, step) -> list:
    """A counter-rotation happens at a locked rest: lock margin > 0 already flags that rest."""
    end = state + unlock
    out = _range_violations(gimbal, np.minimum(state, end), np.maximum(state, end), step, (0, 2))
    pieces = prof.pieces(float(np.max(np.abs(unlock))))
    for g in (0, 2):
        out += _dynamic_violations(gimbal, g, 1.0, 0.0, pieces, _jerk_of(pieces), step)
    return out


def _combined_violations(gimbal: Gimbal, theta, path, pieces: Pieces, step) -> list:
    out = _range_violations(gimbal, path.min(axis=0), path.max(axis=0), step)
    out += _lock_violations(gimbal, float(path[:, 1].min()), float(path[:, 1].max()), step)
    d1 = np.gradient(path, theta, axis=0)  # encoder rad per rad of flip, sampled
    d2 = np.gradient(d1, theta, axis=0)
    for g in range(3):
        gain, curve = float(np.max(np.abs(d1[:, g]))), float(np.max(np.abs(d2[:, g])))
        if gain > 1e-12:
            out += _dynamic_violations(gimbal, g, gain, curve, pieces, _jerk_of(pieces), step)
    return out


def combined_path(state: np.ndarray, ax: int, angle_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Encoder angles along a flip no single gimbal holds: flip angles ``theta`` and ``(m, 3)`` angles.

    The attitude is decomposed every :data:`COMBINED_STEP_RAD` of flip,
    unwrapped, and put on the branch (and turn count) of ``state``.
    """
    n = max(2, int(math.ceil(abs(angle_rad) / COMBINED_STEP_RAD)) + 1)
    theta = np.linspace(0.0, angle_rad, n)
    C = gimbal_to_relative(state) @ rot_axis(ax, theta)
    a = unwrap_gimbal(gimbal_from_relative(C))
    if abs(math.remainder(a[0, 1] - state[1], 2 * math.pi)) > 0.5 * math.pi:  # the twin branch
        a = a + [math.pi, 0.0, math.pi]
        a[:, 1] = math.pi - a[:, 1]
    a = a + 2 * math.pi * np.round((state - a[0]) / (2 * math.pi))
    a[0] = state
    return np.abs(theta), a  # by |flip angle| turned, increasing (for np.interp)


# ---------------------------------------------------------------------------
# A whole sequence


@dataclass(frozen=True)
class GimbalPlan:
    """How a gimbal plays a sequence: one :class:`Move` per step, its times, and what breaks.

    ``move_start_s[k]`` is when step ``k``'s flip starts; its unlock (if any)
    runs over ``[move_start_s[k] - moves[k].unlock_s, move_start_s[k]]``.
    """

    gimbal: Gimbal
    moves: tuple[Move, ...]
    move_start_s: np.ndarray
    violations: tuple[Violation, ...]

    @property
    def playable(self) -> bool:
        return not self.violations

    @property
    def unlocks(self) -> list[tuple[int, float, float, np.ndarray]]:
        """``(step number, start s, end s, encoder change)`` of every lock counter-rotation."""
        return [
            (k + 1, float(t - m.unlock_s), float(t), m.unlock)
            for k, (m, t) in enumerate(zip(self.moves, self.move_start_s, strict=True))
            if m.unlock_s > 0
        ]

    def state_after(self, k: int) -> np.ndarray:
        """Encoder state (rad) at the rest after step ``k`` (0-based), before any later unlock."""
        return self.moves[k].state_end


def plan_sequence(seq, gimbal: Gimbal = DEFAULT_GIMBAL) -> GimbalPlan:
    """Play every step of ``seq`` on ``gimbal`` from the start (every encoder at 0)."""
    state, t = np.zeros(3), seq.initial_dwell_s
    moves: list[Move] = []
    starts: list[float] = []
    viol: list[Violation] = []
    rest_before = seq.initial_dwell_s
    for k, s in enumerate(seq.steps):
        mv = plan_move(gimbal, state, s.axis, math.radians(s.angle_deg), s.profile, step=k + 1)
        viol.extend(mv.violations)
        if mv.unlock_s > rest_before + 1e-9:
            viol.append(
                Violation(
                    k + 1,
                    "outer and inner",
                    "rest",
                    f"the rest before this flip is in gimbal lock and lasts "
                    f"{rest_before:.1f} s, but the counter-rotation it needs first "
                    f"takes {mv.unlock_s:.1f} s (lengthen that rest's dwell_s)",
                )
            )
        moves.append(mv)
        starts.append(t)
        t += s.duration_s + s.dwell_s
        rest_before = s.dwell_s
        state = mv.state_end
    if gimbal.end_at_home and np.any(np.abs(state) > 1e-6):
        away = ", ".join(
            f"{n} {math.degrees(a):.1f}" for n, a in zip(NAMES, state, strict=True) if abs(a) > 1e-6
        )
        viol.append(
            Violation(
                None,
                "every",
                "home",
                f"ends at {away} deg, not at home (0, 0, 0); gimbal {gimbal.name!r} must end there",
            )
        )
    return GimbalPlan(gimbal, tuple(moves), np.array(starts), tuple(viol))


def check_playable(plan: GimbalPlan, where: str, sequence: str | None = None) -> None:
    """Refuse a sequence the gimbal cannot play: one line naming the first violation.

    The fix names both ways out: design a sequence for this gimbal (``design --gimbal``,
    whose moves are planned on it) or see every violation (``show --gimbal``).
    """
    if plan.violations:
        v = plan.violations[0]
        more = f" (and {len(plan.violations) - 1} more)" if len(plan.violations) > 1 else ""
        g = _gimbal_argument(plan.gimbal)
        raise CalibError(
            f"{v}{more}",
            where,
            f"design a sequence for this gimbal: 'seqdesign design --gimbal {g} -o SEQ.toml' "
            f"(its moves are planned on the gimbal), or change the gimbal; "
            f"'seqdesign show {sequence or 'SEQ'} --gimbal {g}' lists every violation",
        )


def _gimbal_argument(gimbal: Gimbal) -> str:
    """How a user names the gimbal on the command line: a shipped one by name, else its file."""
    if gimbal.path and Path(gimbal.path).parent.resolve() == builtin_gimbal_dir().resolve():
        return Path(gimbal.path).stem
    return gimbal.path or "FILE"
