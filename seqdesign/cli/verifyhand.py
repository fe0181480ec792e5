"""``seqdesign verify --by-hand``: the Monte Carlo of runs placed by hand (no sequence, no gimbal)."""

from __future__ import annotations

import math

from calib.errors import CalibError

from .tools import info


def verify_by_hand(
    sequence,
    prof,
    req,
    with_terms,
    runs,
    workers,
    scheduler,
    site,
    sample_rate_hz,
    seed,
    errors,
    shape,
    troubles=None,
    progress=None,
):
    """Simulate and calibrate ``runs`` runs placed by hand (``verify`` reports them).

    ``site`` is ``(latitude, height, gravity_mps2)`` as given, ``shape`` ``(like, poses,
    peak_rate_dps, by_hand, placement_deg)``, ``troubles`` the trouble options by name
    (:mod:`seqdesign.cli.handtroubles`); a SEQUENCE given with ``--by-hand`` is a pose list,
    whose runs are held against ``analyze --by-hand``'s prediction.
    """
    import numpy as np

    from calib.model.optional_terms import as_extras
    from calib.sequence.kinematics import SimConfig
    from seqdesign.verify import HandShape, verify as run_verify

    from .handtroubles import TROUBLE_DEFAULTS, trouble_spec

    like, poses, peak_rate_dps, by_hand, placement_deg = shape
    pose_list = None
    if sequence is not None:
        if not by_hand or not str(sequence).lower().endswith(".toml"):
            raise CalibError(
                f"{sequence} given with --by-hand",
                "--by-hand",
                "give a pose list (docs/by-hand.md) with --by-hand, or a sequence without it",
            )
        from calib.hand.poses import load_poses

        pose_list = load_poses(sequence)
    if not by_hand:
        raise CalibError(
            "no SEQUENCE given", "verify", "give a sequence, or --by-hand for runs placed by hand"
        )
    spec = trouble_spec(troubles or TROUBLE_DEFAULTS)
    extras = as_extras(with_terms, by_hand=True)
    latitude, height, gravity_mps2 = site
    lat = 45.0 if latitude is None else latitude
    config = SimConfig(
        latitude_rad=math.radians(lat),
        height_m=0.0 if height is None else height,
        sample_rate_hz=sample_rate_hz,
        gravity_mps2=gravity_mps2,
    )
    hand = HandShape(
        like=like,
        poses=poses,
        peak_rate_dps=peak_rate_dps,
        g_sensitivity=bool(extras.groups),
        pose_list=pose_list,
        placement_deg=placement_deg,
        troubles=spec,
    )
    predicted = np.full(21, np.nan)
    if pose_list is not None:  # the analyser's prediction the runs are held against
        from seqdesign.handanalysis import analyze_hand

        predicted = analyze_hand(
            pose_list, prof, req, latitude_deg=lat, tolerance_deg=placement_deg, extras=extras, cure=False
        ).worst_sigma
    info(f"verifying {hand.name}: {runs} runs, profile {prof.name}")
    return run_verify(
        None,
        prof,
        runs,
        config=config,
        predicted_sigma=predicted,
        errors=errors,
        tolerance_deg=0.0,
        flip_error_deg=0.0,
        seed=seed or 0,
        requirements=req,
        workers=workers,
        scheduler=scheduler,
        hand=hand,
        progress=progress,
    )
