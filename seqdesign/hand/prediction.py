"""Predicted sigma of a run placed by hand, from its pose list, before anyone records it.

The prediction is the fit's own covariance (:mod:`calib.hand.joint_fit`) on the noise-free run the
simulator makes of the poses (:mod:`calib.hand.simulate`): the same rests, moves, weights and unknowns
the fit of the recording will have, so ``analyze`` and ``calibrate`` cannot disagree by
construction, only by the recording differing from the plan. A hand places a pose within tens
of degrees of where it was meant: the placement tolerance draws that many perturbed runs and
keeps each parameter's worst sigma (a sampled worst case, not a bound). The weakest parameter's
cure is the face which, added as one more pose, lowers the worst ratio most.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.hand.calibrate import hand_fit_of
from calib.hand.fit_options import HandFitOptions, HandSamples
from calib.hand.joint_fit import fit_by_hand
from calib.hand.poses import AXES, PoseList, tipping_plan
from calib.hand.simulate import simulate_by_hand
from calib.model import params as P
from calib.model.optional_terms import OptionalTerms
from calib.model.report import format_table, parameter_entries, worst
from calib.model.requirements import Requirements
from calib.nav.site import Site
from calib.nav.strapdown import sample_intervals
from calib.nav.transform import rotvec_to_dcm
from calib.noise.profiles import NoiseProfile, white_part
from calib.sequence.kinematics import SimConfig

ANALYSIS_RATE_HZ = 50.0  # noise-free: the information does not depend on it beyond rounding
OVERSAMPLE = 2


@dataclass(frozen=True)
class HandPrediction:
    """One plan's predicted sigma (SI) and what it leaves unobserved."""

    sigma: np.ndarray  # (21,)
    correlation: np.ndarray  # (21, 21)
    estimable: np.ndarray  # (21,)
    null_directions: tuple


def predict(plan, profile: NoiseProfile, requirements: Requirements, site: Site, g_sensitivity: bool):
    """The fit's covariance on the noise-free run of ``plan`` at ``site``."""
    config = SimConfig(
        latitude_rad=site.latitude_rad, sample_rate_hz=ANALYSIS_RATE_HZ, gravity_mps2=site.gravity_mps2
    )
    run, _ = simulate_by_hand(plan, config, oversample=OVERSAMPLE)
    # A noise-free run: the profile's weights (not earned ones) are the prediction's.
    options = HandFitOptions(g_sensitivity, requirements, partial=True, earn_weights=False)
    fit = fit_by_hand(HandSamples.of_run(run), site, profile, options, where=plan_name(plan))
    return prediction_of(fit)


def prediction_of(fit) -> HandPrediction:
    """The 21's sigma (inf where not estimable) and correlation of a hand fit's covariance."""
    cov = fit.covariance[: P.N_PARAMS, : P.N_PARAMS]
    sigma = np.where(fit.estimable[: P.N_PARAMS], np.sqrt(np.diag(cov)), np.inf)
    d = np.where(np.isfinite(sigma) & (sigma > 0), sigma, 1.0)
    return HandPrediction(
        sigma, cov / np.outer(d, d), fit.estimable[: P.N_PARAMS], tuple(fit.null_directions)
    )


def plan_name(plan) -> str:
    """How a plan is named in messages."""
    return f"a plan of {len(plan.C_b_n)} poses"


def perturbed(poses: PoseList, tolerance_deg: float, rng: np.random.Generator):
    """The plan with each pose placed within +-tolerance (each axis of a rotation, uniform)."""
    plan = poses.plan()
    tilt = rng.uniform(-1.0, 1.0, (len(plan.C_b_n), 3)) * math.radians(tolerance_deg)
    C = rotvec_to_dcm(tilt) @ plan.C_b_n
    return tipping_plan(C, plan.rest_s, plan.move_s)


@dataclass(frozen=True)
class HandAnalysis:
    """The report of ``analyze --by-hand``."""

    poses: PoseList
    profile: NoiseProfile
    requirements: Requirements
    nominal: HandPrediction
    worst_sigma: np.ndarray  # (21,) over the placement samples (== nominal without tolerance)
    tolerance_deg: float
    samples: int
    g_sensitivity: bool
    cure: tuple[str, float, int] | None  # (the face to add, the worst ratio with it, how many unobserved)
    recorded: bool = False  # from a recorded log's own rests and moves, not a pose list

    def entries(self) -> dict:
        return parameter_entries(self.worst_sigma, requirements=self.requirements)

    def to_json(self) -> dict:
        entries = self.entries()
        nominal = P.from_si(self.nominal.sigma)
        for p in P.PARAMETERS:
            entries[p.name]["sigma_as_planned"] = float(nominal[p.index])
        pairs = [
            {"a": P.NAMES[i], "b": P.NAMES[j], "correlation": float(self.nominal.correlation[i, j])}
            for i in range(P.N_PARAMS)
            for j in range(i + 1, P.N_PARAMS)
            if abs(self.nominal.correlation[i, j]) > 0.9
        ]
        return {
            "poses": self.poses.name,
            "n_poses": len(self.poses.up),
            "duration_s": self.poses.duration_s,
            "profile": self.profile.name,
            "requirements": self.requirements.name,
            "placement_tolerance_deg": self.tolerance_deg,
            "placement_samples": self.samples,
            "recorded": self.recorded,
            "g_sensitivity": self.g_sensitivity,
            "parameters": entries,
            "worst": worst(entries),
            "not_estimable": [n for n, ok in zip(P.NAMES, self.nominal.estimable, strict=True) if not ok],
            "unobserved_directions": list(self.nominal.null_directions),
            "correlated_pairs": pairs,
            "cure": None
            if self.cure is None
            else {"add_pose_up": self.cure[0], "worst_ratio": self.cure[1], "not_estimable": self.cure[2]},
        }

    def to_text(self) -> str:
        doc = self.to_json()
        w = doc["worst"]
        lines = [
            format_table(self.entries()),
            f"{doc['n_poses']} poses, {doc['duration_s']:.0f} s, profile {self.profile.name}, requirements "
            f"{self.requirements.name}; "
            + (
                "as recorded (the log's own rests and moves)"
                if self.recorded
                else f"worst over {self.samples} placements within +-{self.tolerance_deg:g} deg"
                if self.samples
                else "as planned"
            )
            + (f"; worst 3 sigma/requirement {w['ratio']:.2f} ({w['name']})" if w["name"] else ""),
        ]
        if doc["not_estimable"]:
            lines.append(
                "not estimable: "
                + ", ".join(doc["not_estimable"])
                + "; unobserved: "
                + "; ".join(doc["unobserved_directions"])
            )
        for pair in doc["correlated_pairs"]:
            lines.append(f"correlated: {pair['a']} and {pair['b']} ({pair['correlation']:+.2f})")
        if self.cure is not None:
            lines.append(
                f"one more pose with {self.cure[0]} up would make the worst ratio {self.cure[1]:.2f}"
            )
        return "\n".join(lines)


@dataclass(frozen=True)
class Placement:
    """How far a hand places each pose from the plan, and how that is sampled.

    Attributes
    ----------
    deg : float
        Each pose within this many degrees of the plan, each axis (0: as planned).
    samples : int
        Placements drawn within it; the sigmas reported are the worst over them.
    seed : int
        Seed of the draws.
    """

    deg: float = 0.0
    samples: int = 10
    seed: int = 0


def analyze_hand(
    poses: PoseList,
    profile: NoiseProfile,
    requirements: Requirements,
    *,
    latitude_deg: float = 45.0,
    placement: Placement | None = None,
    extras: OptionalTerms | None = None,
    cure: bool = True,
) -> HandAnalysis:
    """Predict the sigmas a recording of ``poses`` will give (see the module).

    Parameters
    ----------
    poses : PoseList
        The planned poses, holds and moves.
    profile, requirements : NoiseProfile, Requirements
        The unit's white noise and the scale its sigmas are judged at.
    latitude_deg : float
        Site latitude, deg.
    placement : Placement, optional
        The hand's placement error (default: none, the poses as planned).
    extras : OptionalTerms, optional
        Terms fitted beside the 21 (``g-sensitivity`` is the one a hand run's prediction models).
    cure : bool
        Also find the face that, added as one more pose, helps most.

    Returns
    -------
    HandAnalysis
    """
    placement = placement or Placement()
    tolerance_deg, samples = placement.deg, placement.samples
    if profile.has_gauss_markov:
        raise CalibError(
            f"profile {profile.name!r} has a Gauss-Markov bias; runs placed by hand are analysed with "
            "white noise only",
            poses.name,
            "give a profile of white noise (ARW, VRW)",
        )
    g_sens = extras is not None and "g-sensitivity" in extras.groups
    site = Site.at(math.radians(latitude_deg))  # a hand's table: normal gravity at 0 m
    nominal = predict(poses.plan(), profile, requirements, site, g_sens)
    worst_sigma = nominal.sigma.copy()
    n = samples if tolerance_deg > 0 else 0
    rng = np.random.default_rng(placement.seed)
    for _ in range(n):
        worst_sigma = np.maximum(
            worst_sigma,
            predict(perturbed(poses, tolerance_deg, rng), profile, requirements, site, g_sens).sigma,
        )
    best: tuple[str, float, int] | None = None
    if cure:
        # The face that, added as one more pose, leaves fewest parameters unobserved, then the
        # smallest worst ratio of those it estimates.
        ranked = []
        for name, up in AXES.items():
            extra = PoseList(
                poses.name,
                np.vstack([poses.up, up]),
                np.append(
                    poses.hold_s, np.median(poses.hold_s[1:]) if len(poses.hold_s) > 1 else poses.hold_s[0]
                ),
                np.append(poses.move_s, poses.move_s[-1]),
            )
            sigma = predict(extra.plan(), profile, requirements, site, g_sens).sigma
            ratios = requirements.ratio(sigma)
            finite = np.isfinite(ratios)
            ranked.append(
                (int((~finite).sum()), float(ratios[finite].max()) if finite.any() else math.inf, name)
            )
        missing, worst_ratio, face = min(ranked)
        best = (face, worst_ratio, missing)
    return HandAnalysis(poses, profile, requirements, nominal, worst_sigma, tolerance_deg, n, g_sens, best)


def analyze_recording(
    run, site, profile: NoiseProfile, requirements: Requirements, extras=None
) -> HandAnalysis:
    """The prediction of a recorded hand run from its own rests and moves (as the fit finds them).

    The sigmas are the fit's covariance before any Birge inflation, with the model and the
    weights `calib.hand.calibrate.hand_fit_of` chooses: what calibrating the recording reports.
    """
    ext = extras if extras is not None else OptionalTerms()
    profile = white_part(profile)  # as calibrate weights it (calib.hand.calibrate.fit_checked)
    # The fit calibrate makes (its model and weights chosen alike): the sigma it will report.
    hand, _, _ = hand_fit_of(run, site, profile, ext, True, requirements)
    rests = hand.data.rests
    period = float(np.median(sample_intervals(run.time_s)))
    poses = PoseList(
        Path(run.source).name,
        np.einsum("kji,j->ki", hand.C_rest, [0.0, 0.0, 1.0]),
        (rests.end - rests.start) * period,
        (rests.start[1:] - rests.end[:-1]) * period,
    )
    nominal = prediction_of(hand)
    sigma = nominal.sigma

    g_sens = "g-sensitivity" in ext.groups
    return HandAnalysis(poses, profile, requirements, nominal, sigma, 0.0, 0, g_sens, None, recorded=True)
