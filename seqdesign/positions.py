"""A sequence's rest positions on a gimbal: what ``seqdesign show`` prints and ``sd.show`` returns.

:func:`show_positions` plays the sequence on the gimbal (default: slip rings, no
limits) and returns a :class:`Positions` that knows its ``--json`` document and
its text table.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.gimbal.description import DEFAULT_GIMBAL, Gimbal, builtin_gimbal_dir, load_gimbal
from calib.gimbal.encoders import RestPosition, rest_positions
from calib.gimbal.rule import GimbalPlan, plan_sequence
from calib.sequence.definition import Sequence, load_sequence

LOCK_NOTE = (
    "GIMBAL LOCK: the middle gimbal is at +-90 deg, so the outer and inner axes coincide; "
    "a flip about the body axis no gimbal then holds is preceded by a counter-rotation of "
    "outer and inner (listed below when needed). See docs/gimbal.md."
)


def as_sequence(sequence: Sequence | str | Path) -> Sequence:
    """A :class:`Sequence` as given, or read from a file or a shipped name (``paper-9pos``)."""
    return sequence if isinstance(sequence, Sequence) else load_sequence(sequence)


def as_gimbal(gimbal: Gimbal | str | Path | None) -> Gimbal:
    """A :class:`Gimbal` as given, or read from a file or a shipped name; None: slip rings."""
    if isinstance(gimbal, Gimbal):
        return gimbal
    try:
        return load_gimbal(gimbal)
    except CalibError as exc:
        if exc.where != "--gimbal":  # the file's own errors name the file
            raise
        raise CalibError(exc.what, "gimbal", exc.fix) from None  # the argument, not the CLI's option


def gimbal_summary(seq, gimbal, plan) -> tuple[dict, list[str]]:
    """What ``show --gimbal`` adds: the counter-rotations and every violation (JSON and lines)."""
    unlocks = [
        {
            "step": k,
            "start_s": a,
            "end_s": b,
            "outer_deg": float(np.degrees(d[0])),
            "inner_deg": float(np.degrees(d[2])),
        }
        for k, a, b, d in plan.unlocks
    ]
    doc = {
        "gimbal": gimbal.name,
        "gimbal_file": gimbal.path,
        "playable": plan.playable,
        "counter_rotations": unlocks,
        "violations": [str(v) for v in plan.violations],
    }
    lines = [f"gimbal: {gimbal.name}" + ("" if plan.violations else " (every move playable)")]
    if gimbal is DEFAULT_GIMBAL:
        lines[0] += (
            f"; an ideal one: no angle, rate or acceleration limit and no margin from gimbal lock "
            f"(a real gimbal: --gimbal {' or '.join(_shipped_gimbals())} or your own file)"
        )
    for u in unlocks:
        lines.append(
            f"  before step {u['step']}: counter-rotation in gimbal lock, "
            f"{u['start_s']:.1f}-{u['end_s']:.1f} s: outer {u['outer_deg']:+.1f} deg, "
            f"inner {u['inner_deg']:+.1f} deg (the IMU stays still)"
        )
    for v in plan.violations:
        lines.append(f"  VIOLATION {v}")
    return doc, lines


# Beyond a turn either way an encoder's cables need slip rings (the shipped cable-wrap
# gimbal keeps every axis within +-360 deg).
WIND_LIMIT_DEG = 360.0


def _shipped_gimbals() -> list[str]:
    return sorted(p.stem for p in builtin_gimbal_dir().glob("*.toml"))


def real_gimbal_warnings(seq: Sequence, gimbal: Gimbal, positions: list[RestPosition]) -> list[str]:
    """What keeps a sequence shown on the ideal default gimbal off every real one.

    Nothing when it plays on one of the shipped gimbals, or when the user gave a gimbal
    (its violations are listed already). Else: the limits each shipped gimbal breaks
    (range, lock margin, rate, acceleration ...), then the rests in gimbal lock (a real
    gimbal keeps a margin from it) and each encoder winding beyond a turn (cables).
    """
    if gimbal is not DEFAULT_GIMBAL:
        return []
    refusals = []
    for name in _shipped_gimbals():
        plan = plan_sequence(seq, load_gimbal(name))
        if plan.playable:
            return []
        limits = sorted({v.limit for v in plan.violations})
        refusals.append(f"{name}: {len(plan.violations)} violation(s) of {', '.join(limits)}")
    out = [
        f"{seq.name} plays on none of the shipped gimbals ({'; '.join(refusals)}): `seqdesign show "
        "SEQ --gimbal NAME` lists them, `seqdesign design --gimbal NAME` designs for one"
    ]
    locked = [p.number for p in positions if p.gimbal_lock]
    if locked:
        out.append(
            f"rest(s) {_first_few(locked)} in gimbal lock (middle at +-90 deg), which a real gimbal "
            "keeps a margin from (cable-wrap: 15 deg)"
        )
    angles = np.array([p.gimbal_deg for p in positions])
    for axis, name in enumerate(("outer", "middle", "inner")):
        reach = float(np.max(np.abs(angles[:, axis])))
        if reach > WIND_LIMIT_DEG + 1e-6:
            out.append(
                f"the {name} gimbal winds to {reach:.0f} deg: only slip rings turn that far "
                f"(cable-wrap stays within +-{WIND_LIMIT_DEG:.0f} deg)"
            )
    return out


def _first_few(numbers: list[int], few: int = 6) -> str:
    """``'2, 3, 7'``, or ``'2, 3, 7, ... (20 in all)'``: a list that stays short."""
    text = ", ".join(map(str, numbers[:few]))
    return text if len(numbers) <= few else f"{text}, ... ({len(numbers)} in all)"


@dataclass(frozen=True)
class Positions:
    """A sequence's rest positions and how a gimbal plays it.

    Attributes
    ----------
    sequence : Sequence
        The sequence shown.
    gimbal : Gimbal
        The gimbal it was played on.
    plan : GimbalPlan
        Which gimbal plays each flip, the lock counter-rotations and every violation.
    positions : list of RestPosition
        One per rest: where body X, Y, Z point, the encoder angles (deg), start and end (s).
    """

    sequence: Sequence
    gimbal: Gimbal
    plan: GimbalPlan
    positions: list[RestPosition]

    @property
    def playable(self) -> bool:
        return self.plan.playable

    def warnings(self) -> list[str]:
        """What would keep the sequence off a real gimbal (:func:`real_gimbal_warnings`)."""
        return real_gimbal_warnings(self.sequence, self.gimbal, self.positions)

    def to_json(self) -> dict:
        """The ``show --json`` document."""
        seq = self.sequence
        gimbal_doc, _ = gimbal_summary(seq, self.gimbal, self.plan)
        return {
            **gimbal_doc,
            "warnings": self.warnings(),
            "sequence": seq.name,
            "duration_s": seq.duration_s,
            "positions": [
                {
                    "position": p.number,
                    "x": p.directions[0],
                    "y": p.directions[1],
                    "z": p.directions[2],
                    "outer_deg": float(p.gimbal_deg[0]),
                    "middle_deg": float(p.gimbal_deg[1]),
                    "inner_deg": float(p.gimbal_deg[2]),
                    "start_s": p.start_s,
                    "end_s": p.end_s,
                    "gimbal_lock": p.gimbal_lock,
                    "on_grid": p.on_grid,
                }
                for p in self.positions
            ],
        }

    def to_text(self) -> str:
        """The table ``seqdesign show`` prints."""
        seq, positions = self.sequence, self.positions
        lines = [f"{seq.name}: {seq.description}".rstrip(": ")]
        w = max(6, *(len(d) + 1 for p in positions for d in p.directions))  # off-grid axes are vectors
        lines.append(
            f"{'pos':>3}  {'X':<{w}}{'Y':<{w}}{'Z':<{w}} {'outer':>8}{'middle':>8}{'inner':>8}"
            f"  {'start s':>8}{'end s':>8}"
        )
        for p in positions:
            lock = "  GIMBAL LOCK" if p.gimbal_lock else ""
            lines.append(
                f"{p.number:>3}  {p.directions[0]:<{w}}{p.directions[1]:<{w}}{p.directions[2]:<{w}}"
                f" {p.gimbal_deg[0]:8.1f}{p.gimbal_deg[1]:8.1f}{p.gimbal_deg[2]:8.1f}"
                f"  {p.start_s:8.1f}{p.end_s:8.1f}{lock}"
            )
        if not all(p.on_grid for p in positions):
            lines.append("off-grid axes are shown as [east north up] components")
        if any(p.gimbal_lock for p in positions):
            lines.append(LOCK_NOTE)
        lines.extend(gimbal_summary(seq, self.gimbal, self.plan)[1])
        lines.append(
            f"{len(positions)} rest positions, {len(seq.steps)} flips, "
            f"total {seq.duration_s:.1f} s ({seq.duration_s / 60:.1f} min)"
        )
        return "\n".join(lines)


def show_positions(sequence: Sequence | str | Path, gimbal: Gimbal | str | Path | None = None) -> Positions:
    """A sequence's rest positions and its plan on a gimbal.

    Parameters
    ----------
    sequence : Sequence, str or Path
        A sequence, a sequence file or a shipped name (``paper-9pos``).
    gimbal : Gimbal, str or Path, optional
        A gimbal, a gimbal file or a shipped name (``cable-wrap``); default: slip
        rings, no limits.

    Returns
    -------
    Positions
    """
    seq, g = as_sequence(sequence), as_gimbal(gimbal)
    return Positions(seq, g, plan_sequence(seq, g), rest_positions(seq, g))
