"""``seqdesign design --by-hand``: poses, order and holds for a run placed by hand."""

from __future__ import annotations

from pathlib import Path

import click

from .tools import emit_json, info

PLACEMENT_DEG = 15.0  # how far a hand places a pose from the plan, each axis (the protocol's promise)


def design_by_hand(
    budget_min,
    move_s,
    min_hold_s,
    first_rest_s,
    pose_set,
    profile,
    latitude,
    requirements,
    with_terms,
    output,
    name,
    protocol_path,
    as_json,
) -> None:
    """Design, analyse (with a hand's placement error) and write the pose list and its protocol."""
    from calib.io.files import atomic_write_text
    from calib.model.optional_terms import as_extras
    from calib.model.requirements import load_requirements
    from calib.noise.profiles import load_profile
    from seqdesign.handanalysis import analyze_hand
    from seqdesign.handdesign import design_hand
    from seqdesign.handprotocol import pose_toml, write_protocol

    prof, req = load_profile(profile), load_requirements(requirements or "mems")
    extras = as_extras(with_terms, by_hand=True)
    out = Path(output or "hand.toml")
    info(f"designing a run placed by hand: {budget_min:g} min, profile {prof.name}, poses from {pose_set}")
    design = design_hand(
        budget_min * 60.0,
        prof,
        req,
        move_s=move_s,
        min_hold_s=min_hold_s,
        first_rest_s=first_rest_s,
        pose_set=pose_set,
        latitude_deg=latitude,
        g_sensitivity=bool(extras.groups),
        name=name or out.stem,
    )
    analysis = analyze_hand(
        design.poses, prof, req, latitude_deg=latitude, tolerance_deg=15.0, extras=extras, cure=False
    )
    worst = analysis.to_json()["worst"]
    summary = (
        f"{len(design.poses.up)} poses, {design.poses.duration_s / 60:.1f} min, profile {prof.name}, "
        f"requirements {req.name}: worst 3 sigma/requirement {design.worst_ratio:.2f} as planned, "
        f"{worst['ratio']:.2f} "
        f"({worst['name']}) with each pose placed within {PLACEMENT_DEG:g} deg; no plan of this length "
        f"does better than "
        f"{design.bias_bound_ratio:.2f} on the gyro biases."
    )
    atomic_write_text(out, pose_toml(design.poses, summary))
    written = [out]
    if protocol_path:
        written += write_protocol(design.poses, protocol_path, summary)
    doc = analysis.to_json() | {
        "worst_ratio_as_planned": design.worst_ratio,
        "bias_bound_ratio": design.bias_bound_ratio,
        "poses_up": [list(map(float, u)) for u in design.poses.up],
        "written": [str(p) for p in written],
    }
    if as_json:
        emit_json(doc)
        return
    click.echo(summary)
    click.echo(analysis.to_text())
    click.echo("wrote " + ", ".join(map(str, written)))
