"""The command schedule a gimbal controller plays: what ``seqdesign export`` writes and ``sd.export`` returns.

The schedule is CSV: ``# key: value`` comment lines, then
``time_s,outer_deg,middle_deg,inner_deg,outer_dps,middle_dps,inner_dps``, one
row per tick at ``rate_hz`` (plus the last instant of the sequence). The
angles are the continuous encoder angles of :mod:`calib.gimbal.rule`, so
replaying them through the gimbal rule gives the sequence's attitudes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.gimbal.description import Gimbal
from calib.gimbal.encoders import encoder_track
from calib.gimbal.rule import GimbalPlan, check_playable, plan_sequence
from calib.io.files import atomic_write_text
from calib.sequence.definition import Sequence, resolve_sequence_path

from .positions import as_gimbal, as_sequence
from .provenance import call_provenance

FORMAT = "gimbal-commands/1"
COLUMNS = "time_s,outer_deg,middle_deg,inner_deg,outer_dps,middle_dps,inner_dps"
RATE_HZ = (1.0, 10000.0)  # the command rates a schedule may have


def check_rate_hz(rate_hz: float, where: str = "rate_hz") -> None:
    """Refuse a command rate outside :data:`RATE_HZ` (``where`` names the caller's knob)."""
    if not (math.isfinite(rate_hz) and RATE_HZ[0] <= rate_hz <= RATE_HZ[1]):
        raise CalibError(f"{where} {rate_hz} outside [{RATE_HZ[0]:g}, {RATE_HZ[1]:g}]", where)


def schedule_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """Ticks ``k / rate_hz`` from 0 to the end, plus the end itself if it falls between ticks."""
    t = np.arange(int(math.floor(duration_s * rate_hz + 1e-9)) + 1) / rate_hz
    if duration_s - t[-1] > 1e-9:
        t = np.append(t, duration_s)
    return t


def schedule_csv(seq, plan, times: np.ndarray, header: dict) -> str:
    """The command schedule as CSV text."""
    angles, rates = encoder_track(plan, seq, times)
    lines = [f"# {k}: {v}" for k, v in header.items()]
    for k, a, b, d in plan.unlocks:
        lines.append(
            f"# counter_rotation: before step {k}, {a:.6f}-{b:.6f} s, outer "
            f"{math.degrees(d[0]):+.6f} deg, inner {math.degrees(d[2]):+.6f} deg"
        )
    lines.append(COLUMNS)
    A, W = np.degrees(angles) + 0.0, np.degrees(rates) + 0.0
    for t, a, w in zip(times, A, W, strict=True):
        lines.append(f"{t:.6f},{a[0]:.10f},{a[1]:.10f},{a[2]:.10f},{w[0]:.9f},{w[1]:.9f},{w[2]:.9f}")
    return "\n".join(lines) + "\n"


def read_schedule(path: str | Path) -> tuple[dict, np.ndarray]:
    """Read a schedule back: its header and an ``(n, 7)`` array of the columns."""
    header: dict[str, str] = {}
    rows = []
    for line in Path(path).read_text().splitlines():
        if line.startswith("# "):
            key, _, value = line[2:].partition(": ")
            header.setdefault(key, value)
        elif line and line != COLUMNS:
            rows.append([float(x) for x in line.split(",")])
    return header, np.array(rows)


@dataclass(frozen=True)
class Schedule:
    """A sequence as the time-stamped encoder commands of a gimbal.

    Attributes
    ----------
    sequence : Sequence
        The sequence played.
    gimbal : Gimbal
        The gimbal that plays it (every move playable).
    plan : GimbalPlan
        Which gimbal plays each flip, and the lock counter-rotations.
    rate_hz : float
        Command rate.
    sequence_file : str or None
        The sequence's file (None for a sequence made in memory).
    """

    sequence: Sequence
    gimbal: Gimbal
    plan: GimbalPlan
    rate_hz: float
    sequence_file: str | None = None

    @property
    def times_s(self) -> np.ndarray:
        """The command instants, s: ticks of ``1 / rate_hz`` and the sequence's last instant."""
        return schedule_times(self.sequence.duration_s, self.rate_hz)

    def encoders(self) -> tuple[np.ndarray, np.ndarray]:
        """Encoder angles (deg) and rates (deg/s) of outer, middle, inner at :attr:`times_s`: ``(n, 3)``."""
        angles, rates = encoder_track(self.plan, self.sequence, self.times_s)
        return np.degrees(angles) + 0.0, np.degrees(rates) + 0.0

    def to_json(self, path: str | Path | None = None) -> dict:
        """The ``export --json`` document (``schedule``: the file written, if any)."""
        return {
            "schedule": None if path is None else str(path),
            "sequence": self.sequence.name,
            "gimbal": self.gimbal.name,
            "rate_hz": self.rate_hz,
            "rows": int(len(self.times_s)),
            "duration_s": self.sequence.duration_s,
            "counter_rotations": len(self.plan.unlocks),
        }

    def header(self, provenance: dict) -> dict:
        """The ``# key: value`` lines of the file; ``provenance`` gives the version, command and hashes."""
        return {
            "format": FORMAT,
            "sequence": self.sequence.name,
            "sequence_file": self.sequence_file or "none (made in memory)",
            "sequence_sha256": provenance.get("sequence_sha256", ""),
            "gimbal": self.gimbal.name,
            "gimbal_file": self.gimbal.path or "none (default: slip rings, no limits)",
            "gimbal_sha256": provenance.get("gimbal_sha256", ""),
            "rate_hz": f"{self.rate_hz:g}",
            "tool_version": provenance.get("tool_version", ""),
            "command": provenance.get("command", ""),
        }

    def save(self, path: str | Path, provenance: dict | None = None) -> None:
        """Write the schedule as CSV, atomically (a ``.csv`` name only).

        ``provenance`` (version, command, inputs' SHA-256) defaults to this call's.
        """
        if Path(path).suffix.lower() != ".csv":
            raise CalibError(
                f"unknown schedule format {Path(path).suffix!r}", str(path), "name the file .csv"
            )
        if provenance is None:
            call = f"Schedule.save({str(path)!r}) of {self.sequence.name!r} on {self.gimbal.name!r}"
            provenance = call_provenance(call, {"sequence": self.sequence_file, "gimbal": self.gimbal.path})
        atomic_write_text(path, schedule_csv(self.sequence, self.plan, self.times_s, self.header(provenance)))


def export_schedule(
    sequence: Sequence | str | Path, gimbal: Gimbal | str | Path | None = None, rate_hz: float = 100.0
) -> Schedule:
    """The command schedule of a sequence on a gimbal, refused if the gimbal cannot play it.

    Parameters
    ----------
    sequence : Sequence, str or Path
        A sequence, a sequence file or a shipped name (``paper-9pos``).
    gimbal : Gimbal, str or Path, optional
        A gimbal, a gimbal file or a shipped name (``cable-wrap``); default: slip rings, no limits.
    rate_hz : float
        Command rate, within [1, 10000] Hz.

    Returns
    -------
    Schedule

    Raises
    ------
    CalibError
        The rate is out of range, or a move breaks a limit of the gimbal (naming the step,
        the gimbal and the limit).
    """
    check_rate_hz(rate_hz)
    seq, g = as_sequence(sequence), as_gimbal(gimbal)
    path = None if isinstance(sequence, Sequence) else str(resolve_sequence_path(sequence))
    plan = plan_sequence(seq, g)
    check_playable(plan, f"{path or seq.name} on gimbal {g.name!r}")
    return Schedule(seq, g, plan, float(rate_hz), path)
