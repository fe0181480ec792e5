"""``seqdesign design --by-hand``: poses, order and holds for a run placed by hand."""

from __future__ import annotations

from pathlib import Path

from .tools import info

PLACEMENT_DEG = 15.0  # how far a hand places a pose from the plan, each axis (the protocol's promise)


def design_by_hand(
    budget_min, options, profile, requirements, with_terms, output, name, protocol_path
) -> tuple[dict, str]:
    """Design, analyse (with a hand's placement error) and write the pose list and its protocol.

    ``options`` is a :class:`seqdesign.hand.pose_search.HandDesignOptions`; returns the ``--json``
    document and the text.
    """
    from calib.hand.fit_options import HAND_REQUIREMENTS
    from calib.io.files import atomic_write_text
    from calib.model.optional_terms import load_optional_terms
    from calib.model.requirements import load_requirements
    from calib.noise.profiles import load_profile
    from seqdesign.hand.pose_search import design_hand
    from seqdesign.hand.prediction import Placement, analyze_hand
    from seqdesign.hand.protocol import pose_toml, write_protocol

    prof, req = load_profile(profile), load_requirements(requirements or HAND_REQUIREMENTS)
    extras = load_optional_terms(with_terms, by_hand=True)
    out = Path(output or "hand.toml")
    poses_from = options.pose_set
    info(f"designing a run placed by hand: {budget_min:g} min, profile {prof.name}, poses from {poses_from}")
    design = design_hand(
        budget_min * 60.0, prof, req, options, g_sensitivity=bool(extras.groups), name=name or out.stem
    )
    analysis = analyze_hand(
        design.poses,
        prof,
        req,
        latitude_deg=options.latitude_deg,
        placement=Placement(15.0),
        extras=extras,
        cure=False,
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
    return doc, "\n".join([summary, analysis.to_text(), "wrote " + ", ".join(map(str, written))])
