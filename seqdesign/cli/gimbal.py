"""``seqdesign export``: the command schedule a gimbal controller plays; helpers for ``show --gimbal``.

The schedule is CSV: ``# key: value`` comment lines, then
``time_s,outer_deg,middle_deg,inner_deg,outer_dps,middle_dps,inner_dps``, one
row per tick at ``--rate-hz`` (plus the last instant of the sequence). The
angles are the continuous encoder angles of :mod:`calib.gimbal`, so
replaying them through the gimbal rule gives the sequence's attitudes.
"""

from __future__ import annotations

import math
from pathlib import Path

import click
import numpy as np

from calib.errors import CalibError

from . import options
from .tools import emit_json, guarded, info, provenance

FORMAT = "gimbal-commands/1"
COLUMNS = "time_s,outer_deg,middle_deg,inner_deg,outer_dps,middle_dps,inner_dps"


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
    for u in unlocks:
        lines.append(
            f"  before step {u['step']}: counter-rotation in gimbal lock, "
            f"{u['start_s']:.1f}-{u['end_s']:.1f} s: outer {u['outer_deg']:+.1f} deg, "
            f"inner {u['inner_deg']:+.1f} deg (the IMU stays still)"
        )
    for v in plan.violations:
        lines.append(f"  VIOLATION {v}")
    return doc, lines


LOCK_NOTE = (
    "GIMBAL LOCK: the middle gimbal is at +-90 deg, so the outer and inner axes coincide; "
    "a flip about the body axis no gimbal then holds is preceded by a counter-rotation of "
    "outer and inner (listed below when needed). See docs/gimbal.md."
)


def schedule_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """Ticks ``k / rate_hz`` from 0 to the end, plus the end itself if it falls between ticks."""
    t = np.arange(int(math.floor(duration_s * rate_hz + 1e-9)) + 1) / rate_hz
    if duration_s - t[-1] > 1e-9:
        t = np.append(t, duration_s)
    return t


def schedule_csv(seq, plan, times: np.ndarray, header: dict) -> str:
    """The command schedule as CSV text."""
    from calib.encoders import encoder_track

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


@click.command(short_help="Write the time-stamped command schedule a gimbal controller plays.")
@click.argument("sequence")
@options.gimbal("Gimbal description (TOML; see docs/gimbal.md). Default: slip rings, no limits.")
@click.option("-o", "--output", required=True, help="Schedule to write (.csv).")
@click.option(
    "--rate-hz",
    type=float,
    default=100.0,
    show_default=True,
    help="Command rate of the schedule, Hz (rows per second of the CSV).",
)
@options.as_json
@guarded
def export(sequence, gimbal_file, output, rate_hz, as_json):
    """Write SEQUENCE as a schedule of continuous encoder angles and rates
    (time_s, outer/middle/inner in deg and deg/s) for the gimbal of --gimbal.
    A sequence the gimbal cannot play is refused, naming the step, the gimbal
    and the limit.
    """
    from calib.fileio import atomic_write_text
    from calib.gimbal import check_playable, plan_sequence
    from calib.gimbalfile import load_gimbal
    from calib.sequence import load_sequence, resolve_sequence_path

    if Path(output).suffix.lower() != ".csv":
        raise CalibError(
            f"unknown schedule format {Path(output).suffix!r}", "-o/--output", "name the file .csv"
        )
    if not (math.isfinite(rate_hz) and 1.0 <= rate_hz <= 10000.0):
        raise CalibError(f"--rate-hz {rate_hz} outside [1, 10000]", "--rate-hz")
    seq = load_sequence(sequence)
    gimbal = load_gimbal(gimbal_file)
    plan = plan_sequence(seq, gimbal)
    check_playable(plan, f"{resolve_sequence_path(sequence)} on gimbal {gimbal.name!r}", sequence)
    prov = provenance({"sequence": sequence, "gimbal": gimbal.path}, sequence=seq.name, gimbal=gimbal.name)
    header = {
        "format": FORMAT,
        "sequence": seq.name,
        "sequence_file": str(resolve_sequence_path(sequence)),
        "sequence_sha256": prov["sequence_sha256"],
        "gimbal": gimbal.name,
        "gimbal_file": gimbal.path or "none (default: slip rings, no limits)",
        "gimbal_sha256": prov.get("gimbal_sha256", ""),
        "rate_hz": f"{rate_hz:g}",
        "tool_version": prov["tool_version"],
        "command": prov["command"],
    }
    times = schedule_times(seq.duration_s, rate_hz)
    atomic_write_text(output, schedule_csv(seq, plan, times, header))
    doc = {
        "schedule": str(output),
        "sequence": seq.name,
        "gimbal": gimbal.name,
        "rate_hz": rate_hz,
        "rows": int(len(times)),
        "duration_s": seq.duration_s,
        "counter_rotations": len(plan.unlocks),
    }
    if as_json:
        emit_json(doc)
    else:
        info(
            f"wrote {output} ({doc['rows']} rows at {rate_hz:g} Hz, {seq.duration_s:.1f} s, "
            f"gimbal {gimbal.name}, {doc['counter_rotations']} lock counter-rotations)"
        )
