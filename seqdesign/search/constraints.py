"""What a user may fix about a design, how long its moves last, and the sequence a walk becomes."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from calib.errors import CalibError
from calib.gimbal.description import Gimbal
from calib.model.optional_terms import OptionalTerms, parse_groups
from calib.model.requirements import Requirements, load_requirements
from calib.nav.transform import AXES
from calib.sequence.definition import FIRST_REST_MARGIN_S, MIN_ALIGN_S, Sequence, Step

from .gimbal import move_profile
from .graph import Move, Node, as_node

MAX_FLIPS = 60


@dataclass(frozen=True)
class Constraints:
    """What a user may fix about a design (SI: seconds, rad/s)."""

    start: Node = ("east", "up", "south")
    end: Node | None = None
    max_flips: int = 60  # at most; the budget ends most walks sooner
    axes: str = AXES
    max_quarters: int = 5
    rate_dps: float = 10.0
    min_dwell_s: float = 10.0  # as the CLI: short dwells are what GM profiles need
    max_dwell_s: float = 300.0
    budget_s: float = 900.0
    accel_dps2: float | None = None  # every move a trapezoid (None: constant rate)
    jerk_dps3: float | None = None  # and an S-curve
    gimbal: Gimbal | None = None  # only moves it plays (seqdesign.search.gimbal)


@dataclass(frozen=True)
class DesignOptions:
    """How a design is scored and searched: the defaults of ``seqdesign design`` and ``seqdesign.api.design``.

    Attributes
    ----------
    latitude_deg : float
        Site latitude, deg (the site's height is 0).
    objective : str
        ``worst`` (worst 3 sigma/requirement), or ``D``, ``A``, ``E``-optimal.
    tolerance_deg : float
        Mounting box half-width, deg; designs are re-scored at its worst case.
    beam_width : int
        Candidates kept per depth of the beam search (fewer: faster, perhaps worse).
    refine : bool
        Refine the winner's dwells with IPOPT.
    workers : int
        Local processes.
    scheduler : str, optional
        A dask.distributed scheduler address (or client) instead of local processes.
    requirements : Requirements or str, optional
        The objective's requirements (default: the paper's).
    extras : OptionalTerms or str, optional
        Terms fitted beside the 21 (``--with``: ``lever-arm,k2,time-offset`` or ``all``); the
        objective is then the worst ratio of the 21 with them fitted.
    """

    latitude_deg: float = 40.0
    objective: str = "worst"
    tolerance_deg: float = 3.0
    beam_width: int = 200
    refine: bool = True
    workers: int = 1
    scheduler: Any = None
    requirements: Requirements | str | None = None
    extras: OptionalTerms | str | None = None

    def judged_by(self) -> tuple[Requirements, OptionalTerms]:
        """The requirements and the extra terms as objects (names and files read)."""
        extras = (
            self.extras
            if isinstance(self.extras, OptionalTerms)
            else OptionalTerms(parse_groups(self.extras))
        )
        return load_requirements(self.requirements), extras


def turn_seconds(mv: Move, c: Constraints) -> float:
    """How long a move lasts with the design's rate profile (longer with an acceleration limit)."""
    if c.accel_dps2 is None:
        return abs(mv.angle_deg) / c.rate_dps
    return move_profile(c.rate_dps, c.accel_dps2, c.jerk_dps3).duration_s(math.radians(abs(mv.angle_deg)))


def turn_rate(mv: Move, c: Constraints) -> float:
    """Signed rate (rad/s) of the search's constant-rate segment: the mean over the real move."""
    if c.accel_dps2 is None:
        return mv.sign * math.radians(c.rate_dps)
    return mv.sign * math.radians(abs(mv.angle_deg)) / turn_seconds(mv, c)


def to_sequence(
    walk,
    c: Constraints,
    dwells: list[float],
    name: str,
    provenance: dict | None = None,
    latitude_deg: float | None = None,
    height_m: float | None = None,
) -> Sequence:
    """A sequence file's content for a walk and its dwells (initial first), with its site."""
    steps = tuple(
        Step(mv.axis, mv.angle_deg, c.rate_dps, float(d), c.accel_dps2, c.jerk_dps3)
        for mv, d in zip(walk, dwells[1:], strict=True)
    )
    return Sequence(
        name=name,
        start=as_node(c.start),
        steps=steps,
        initial_dwell_s=float(dwells[0]),
        description=f"designed: {' '.join(m.label() for m in walk)}",
        latitude_deg=latitude_deg,
        height_m=height_m,
        provenance=provenance or {},
    )


def uniform_dwell(c: Constraints, n_moves_guess: int, quarters_guess: float = 2.0) -> float:
    """A dwell that lets ``n_moves_guess`` moves fit the budget."""
    turn = n_moves_guess * quarters_guess * 90.0 / c.rate_dps
    d = (c.budget_s - turn) / (n_moves_guess + 1)
    return float(min(max(d, c.min_dwell_s), c.max_dwell_s))


def check_constraints(c: Constraints) -> None:
    """Refuse constraints no walk can meet, naming the field (and the CLI's option)."""

    def field(name: str, option: str) -> str:
        return f"{name} (the CLI's {option})"

    if c.budget_s <= 0 or not math.isfinite(c.budget_s):
        raise CalibError(f"budget {c.budget_s} s must be positive", field("budget_s", "--budget-min"))
    if not 1 <= c.max_flips <= MAX_FLIPS:
        raise CalibError(
            f"max_flips {c.max_flips} outside [1, {MAX_FLIPS}]", field("max_flips", "--max-flips")
        )
    if not 1 <= c.max_quarters <= 12:
        raise CalibError(
            f"max_quarters {c.max_quarters} outside [1, 12]", field("max_quarters", "--max-quarters")
        )
    if not c.axes or any(a not in AXES for a in c.axes):
        raise CalibError(f"axes {c.axes!r} must be letters from XYZ", field("axes", "--axes"))
    dwells = field("min_dwell_s/max_dwell_s", "--min-dwell-s/--max-dwell-s")
    if not 0 < c.min_dwell_s <= c.max_dwell_s:
        raise CalibError(f"dwell range [{c.min_dwell_s}, {c.max_dwell_s}] s is empty", dwells)
    shortest = MIN_ALIGN_S + FIRST_REST_MARGIN_S
    if c.min_dwell_s < shortest:
        raise CalibError(
            f"min_dwell_s {c.min_dwell_s:g} s is too short: the first rest of a "
            f"run must last {shortest:g} s for calibrate to align on it",
            field("min_dwell_s", "--min-dwell-s"),
            f"give {shortest:g} s or more",
        )
    if not 0.1 <= c.rate_dps <= 100:
        raise CalibError(f"rate_dps {c.rate_dps} outside [0.1, 100]", field("rate_dps", "--rate-dps"))
    if c.min_dwell_s * 2 + 90.0 / c.rate_dps > c.budget_s:
        raise CalibError(
            f"a budget of {c.budget_s:.0f} s cannot hold two dwells of {c.min_dwell_s:.0f} s and one flip",
            field("budget_s", "--budget-min"),
            "raise the budget or lower the shortest dwell",
        )
