"""``seqdesign show``: a sequence's rest positions, gimbal angles and times."""

from __future__ import annotations

import click

from . import options
from .tools import emit_json, guarded


@click.command(short_help="Print a sequence's rest positions: axes, gimbal angles, times.")
@click.argument("sequence")
@options.gimbal("Gimbal description (TOML): list its counter-rotations and flag violations.")
@options.as_json
@guarded
def show(sequence, gimbal_file, as_json):
    """Print where body X, Y, Z point at every rest position of SEQUENCE (a
    file or a shipped name such as paper-9pos), its gimbal angles (outer,
    middle, inner; continuous along the run) and its start and end times.
    """
    from calib.encoders import rest_positions
    from calib.gimbal import plan_sequence
    from calib.gimbalfile import load_gimbal
    from calib.sequence import load_sequence

    from .gimbal import LOCK_NOTE, gimbal_summary

    seq = load_sequence(sequence)
    gimbal = load_gimbal(gimbal_file)
    positions = rest_positions(seq, gimbal)
    gimbal_doc, gimbal_lines = gimbal_summary(seq, gimbal, plan_sequence(seq, gimbal))
    if as_json:
        emit_json(
            {
                **gimbal_doc,
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
                    for p in positions
                ],
            }
        )
        return
    click.echo(f"{seq.name}: {seq.description}".rstrip(": "))
    w = max(6, *(len(d) + 1 for p in positions for d in p.directions))  # off-grid axes are vectors
    click.echo(
        f"{'pos':>3}  {'X':<{w}}{'Y':<{w}}{'Z':<{w}} {'outer':>8}{'middle':>8}{'inner':>8}"
        f"  {'start s':>8}{'end s':>8}"
    )
    for p in positions:
        lock = "  GIMBAL LOCK" if p.gimbal_lock else ""
        click.echo(
            f"{p.number:>3}  {p.directions[0]:<{w}}{p.directions[1]:<{w}}{p.directions[2]:<{w}}"
            f" {p.gimbal_deg[0]:8.1f}{p.gimbal_deg[1]:8.1f}{p.gimbal_deg[2]:8.1f}"
            f"  {p.start_s:8.1f}{p.end_s:8.1f}{lock}"
        )
    if not all(p.on_grid for p in positions):
        click.echo("off-grid axes are shown as [east north up] components")
    if any(p.gimbal_lock for p in positions):
        click.echo(LOCK_NOTE)
    click.echo("\n".join(gimbal_lines))
    click.echo(
        f"{len(positions)} rest positions, {len(seq.steps)} flips, "
        f"total {seq.duration_s:.1f} s ({seq.duration_s / 60:.1f} min)"
    )
