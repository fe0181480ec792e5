"""``seqdesign verify --by-hand``: the Monte Carlo of runs placed by hand (no sequence, no gimbal)."""

from __future__ import annotations

import math
from dataclasses import replace

from calib.errors import CalibError

from .tools import info


def verify_by_hand(sequence, prof, options, with_terms, where, errors, shape, progress=None):
    """Simulate and calibrate ``options.runs`` runs placed by hand (``verify`` reports them).

    ``options`` is a :class:`seqdesign.verify.VerifyOptions` (its runs, seed, requirements,
    workers and scheduler; a hand run has no mounting box nor flip error, and reads ``with_terms``
    as a hand fit's), ``where`` ``(latitude, height, gravity_mps2, sample_rate_hz)`` as given,
    ``shape`` ``(drawn, by_hand, troubles)``: ``drawn`` the :class:`seqdesign.verify.HandShape`
    fields given (``like``, ``poses``, ``peak_rate_dps``, ``placement_deg``), ``troubles`` the
    trouble options by name (:mod:`seqdesign.cli.handtroubles`; None: their defaults); a
    SEQUENCE given with ``--by-hand`` is a pose list, whose runs are held against
    ``analyze --by-hand``'s prediction.
    """
    import numpy as np

    from calib.model.optional_terms import NONE as NO_EXTRAS, load_optional_terms
    from calib.sequence.kinematics import SimConfig
    from seqdesign.verify import HandShape, verify as run_verify

    from .handtroubles import TROUBLE_DEFAULTS, trouble_spec

    drawn, by_hand, troubles = shape
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
    extras = load_optional_terms(with_terms, by_hand=True)
    latitude, height, gravity_mps2, sample_rate_hz = where
    lat = 45.0 if latitude is None else latitude
    config = SimConfig(
        latitude_rad=math.radians(lat),
        height_m=0.0 if height is None else height,
        sample_rate_hz=sample_rate_hz,
        gravity_mps2=gravity_mps2,
    )
    hand = HandShape(**drawn, g_sensitivity=bool(extras.groups), pose_list=pose_list, troubles=spec)
    predicted = np.full(21, np.nan)
    if pose_list is not None:  # the analyser's prediction the runs are held against
        from seqdesign.hand.prediction import Placement, analyze_hand

        predicted = analyze_hand(
            pose_list,
            prof,
            options.requirements,
            latitude_deg=lat,
            placement=Placement(hand.placement_deg),
            extras=extras,
            cure=False,
        ).worst_sigma
    info(f"verifying {hand.name}: {options.runs} runs, profile {prof.name}")
    return run_verify(
        None,
        prof,
        replace(options, tolerance_deg=0.0, flip_error_deg=0.0, extras=NO_EXTRAS),
        config=config,
        predicted_sigma=predicted,
        errors=errors,
        hand=hand,
        progress=progress,
    )
