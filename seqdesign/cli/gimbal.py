"""``seqdesign export``: the command schedule a gimbal controller plays.

The schedule and its CSV format are :mod:`seqdesign.schedule`'s (``read_schedule``
reads one back; it is importable from here too).
"""

from __future__ import annotations

from pathlib import Path

import click

from calib.errors import CalibError

from ..schedule import COLUMNS, FORMAT, read_schedule  # noqa: F401  (their old home)
from . import options
from .tools import emit_json, guarded, info, provenance


@click.command(short_help="Write the time-stamped command schedule a gimbal controller plays.")
@click.argument("sequence")
@options.gimbal("The gimbal to schedule (default: slip rings, no limits).")
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
    from calib.gimbal.description import load_gimbal
    from seqdesign.schedule import check_rate_hz, export_schedule

    if Path(output).suffix.lower() != ".csv":
        raise CalibError(
            f"unknown schedule format {Path(output).suffix!r}", "-o/--output", "name the file .csv"
        )
    check_rate_hz(rate_hz, "--rate-hz")
    schedule = export_schedule(sequence, load_gimbal(gimbal_file), rate_hz)
    seq, gimbal = schedule.sequence, schedule.gimbal
    prov = provenance({"sequence": sequence, "gimbal": gimbal.path}, sequence=seq.name, gimbal=gimbal.name)
    schedule.save(output, prov)
    doc = schedule.to_json(output)
    if as_json:
        emit_json(doc)
    else:
        info(
            f"wrote {output} ({doc['rows']} rows at {rate_hz:g} Hz, {seq.duration_s:.1f} s, "
            f"gimbal {gimbal.name}, {doc['counter_rotations']} lock counter-rotations)"
        )
