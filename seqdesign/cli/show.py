"""``seqdesign show``: a sequence's rest positions, gimbal angles and times."""

from __future__ import annotations

import click

from . import options
from .tools import emit_json, guarded, info


@click.command(short_help="Print a sequence's rest positions: axes, gimbal angles, times.")
@click.argument("sequence")
@options.gimbal(
    "List the counter-rotations and flag the violations on this gimbal (default: slip rings, no limits)."
)
@options.as_json
@guarded
def show(sequence, gimbal_file, as_json):
    """Print where body X, Y, Z point at every rest position of SEQUENCE (a
    file or a shipped name such as paper-9pos), its gimbal angles (outer,
    middle, inner; continuous along the run) and its start and end times.
    """
    from calib.gimbal.description import load_gimbal
    from seqdesign.positions import show_positions

    shown = show_positions(sequence, load_gimbal(gimbal_file))
    for warning in shown.warnings():  # on the ideal default gimbal: what a real one would refuse
        info(f"warning: {warning}")
    if as_json:
        emit_json(shown.to_json())
        return
    click.echo(shown.to_text())
