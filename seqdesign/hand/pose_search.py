"""Design a run placed by hand: which poses, in what order, how long each.

Given the time a user has, how long a move takes and the shortest hold, the search picks the
number of poses and, greedily, each next pose among a candidate set (the 6 faces of a cube, its
6 faces, 12 edges and 8 corners, or the 20 faces of an icosahedron) so that the plan's
``3 sigma / requirement`` falls most (summed in logarithms over the 21), growing a seed of twelve
poses that observes all 21; every pose is held equally long, the first as long as the static
start asks. Each candidate plan is scored by the fast path of the
fit's own information (:func:`calib.hand.predict.plan_sigma`, within 1 % of the simulated
prediction) and the result by :func:`seqdesign.hand.prediction.analyze_hand`.

The physical bound of a gyro bias: every second of a run, at rest or turning, tells the bias
through the ARW alone, so no plan of ``T`` seconds does better than ``ARW / sqrt(T)`` on any
axis (a plan reaches it when the gravity direction, or the rotation over each move, sees every
axis' bias); the accelerometer biases likewise ``VRW / sqrt(T_rest)`` over the time at rest.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError
from calib.hand.poses import AXES, PoseList, tip_to
from calib.hand.predict import plan_sigma
from calib.model import params as P
from calib.model.requirements import Requirements
from calib.nav.site import Site
from calib.noise.profiles import NoiseProfile


def candidate_ups(kind: str) -> dict[str, np.ndarray]:
    """Up vectors by name: ``cube`` (6 faces), ``grid`` (faces, edges, corners), ``icosahedron``."""
    faces = dict(AXES)
    if kind == "cube":
        return faces
    if kind == "grid":
        out = dict(faces)
        for a, b in itertools.combinations("xyz", 2):
            for sa, sb in itertools.product("+-", repeat=2):
                v = AXES[sa + a] + AXES[sb + b]
                out[f"{sa}{a}{sb}{b}"] = v / np.linalg.norm(v)
        for sx, sy, sz in itertools.product("+-", repeat=3):
            v = AXES[sx + "x"] + AXES[sy + "y"] + AXES[sz + "z"]
            out[f"{sx}x{sy}y{sz}z"] = v / np.linalg.norm(v)
        return out
    if kind == "icosahedron":
        # Face normals of an icosahedron: the vertices of a dodecahedron, normalised.
        g = (1 + math.sqrt(5)) / 2
        verts = [np.array(v, float) for v in itertools.product((-1, 1), repeat=3)]
        for p, q in itertools.product((-1.0, 1.0), repeat=2):
            verts += [np.array([0, p / g, q * g]), np.array([p / g, q * g, 0]), np.array([p * g, 0, q / g])]
        return {f"ico{k + 1}": v / np.linalg.norm(v) for k, v in enumerate(verts)}
    raise CalibError(f"unknown pose set {kind!r}", "--pose-set", "choose cube, grid or icosahedron")


MAX_POSES = 45
# Twelve poses around all three axes (faces and edges, tipped from one to the next) whose plan
# observes all 21: what the greedy search grows from.
SEED = [
    np.array(v, float) / np.linalg.norm(v)
    for v in (
        (0, 0, 1),
        (1, 0, 0),
        (1, 1, 0),
        (0, 1, 0),
        (0, 1, 1),
        (0, 0, -1),
        (-1, 0, -1),
        (-1, 0, 0),
        (-1, -1, 0),
        (0, -1, 0),
        (0, -1, 1),
        (1, 0, 1),
    )
]


def _nearest(ups: dict[str, np.ndarray], up: np.ndarray, exclude: str | None = None) -> str:
    """The candidate closest to ``up`` (not ``exclude``, the pose the unit is in)."""
    return max((n for n in ups if n != exclude), key=lambda n: float(ups[n] @ up))


@dataclass(frozen=True)
class HandDesign:
    """The chosen pose list, its predicted worst ratio and the bias bound of its length."""

    poses: PoseList
    names: tuple[str, ...]
    worst_ratio: float
    sigma: np.ndarray  # (21,) SI, fast path
    bias_bound_ratio: float  # the gyro biases' 3 sigma / requirement no plan of this length beats


def _score(sigma: np.ndarray, requirements: Requirements) -> float:
    """What a greedy step minimises: the sum of log ratios, an unobserved parameter counting as a
    ratio of 1e6. Smoother than the worst ratio alone, so that a step which brings a parameter in
    (or lowers any) is seen while another one still limits the plan.
    """
    ratios = np.nan_to_num(requirements.ratio(sigma), nan=1e6, posinf=1e6)
    return float(np.sum(np.log(np.clip(ratios, 1e-3, 1e6))))


def _worst(sigma: np.ndarray, requirements: Requirements) -> float:
    return float(np.max(requirements.ratio(sigma)))


@dataclass(frozen=True)
class HandDesignOptions:
    """How a run placed by hand is planned: the defaults of ``seqdesign design --by-hand``.

    Attributes
    ----------
    move_s : float
        How long a move from one pose to the next takes, s.
    min_hold_s : float
        Shortest hold, s.
    first_rest_s : float
        The static start, s.
    pose_set : str
        Candidate poses: ``grid`` (faces, edges and corners of a box), ``cube`` or ``icosahedron``.
    latitude_deg : float
        Site latitude, deg.
    """

    move_s: float = 3.0
    min_hold_s: float = 5.0
    first_rest_s: float = 30.0
    pose_set: str = "grid"
    latitude_deg: float = 45.0


def design_hand(
    budget_s: float,
    profile: NoiseProfile,
    requirements: Requirements,
    options: HandDesignOptions | None = None,
    *,
    counts: tuple[int, ...] | None = None,
    g_sensitivity: bool = False,
    name: str = "hand",
) -> HandDesign:
    """The best equal-hold plan found within ``budget_s`` (see the module).

    Parameters
    ----------
    budget_s : float
        The run's length, s.
    profile, requirements : NoiseProfile, Requirements
        The unit's white noise and the scale its sigmas are judged at.
    options : HandDesignOptions, optional
        Move, hold and start lengths, the candidate poses and the latitude (default: its defaults).
    counts : tuple of int, optional
        Pose counts to try (default: four from the seed's to the most the budget holds).
    g_sensitivity : bool
        Fit the gyros' g-sensitivity too.
    name : str
        The plan's name.

    Returns
    -------
    HandDesign
    """
    options = options or HandDesignOptions()
    move_s, min_hold_s, first_rest_s = options.move_s, options.min_hold_s, options.first_rest_s
    ups = candidate_ups(options.pose_set)
    site = Site.at(math.radians(options.latitude_deg))
    room = budget_s - first_rest_s
    n_max = int(room // (min_hold_s + move_s))
    if n_max < len(SEED):
        raise CalibError(
            f"{budget_s:g} s holds {n_max + 1} poses of {min_hold_s:g} s with {move_s:g} s moves after a "
            f"{first_rest_s:g} s start: fewer than the {len(SEED) + 1} a plan around all three axes needs",
            "--budget-min",
            "give more time, shorter holds or a shorter static start",
        )
    # Four pose counts from the seed's to the most the budget holds (at most 45: beyond, holds shrink
    # to the floor and a person loses count).
    top = min(n_max, MAX_POSES)
    counts = counts or tuple(sorted({int(round(x)) for x in np.linspace(len(SEED), top, 4)}))
    best: HandDesign | None = None
    for n in counts:
        hold = room / n - move_s
        # A greedy step cannot see a parameter that needs several new poses to come in: it starts
        # from a seed that observes all 21 (faces and edges around all three axes), cut to n + 1.
        chosen = [_nearest(ups, SEED[0])]
        C = [tip_to(np.eye(3), ups[chosen[0]])]
        for up in SEED[1 : n + 1]:
            chosen.append(_nearest(ups, up, exclude=chosen[-1]))
            C.append(tip_to(C[-1], ups[chosen[-1]]))
        for _ in range(n + 1 - len(chosen)):
            scored = []
            for cand, up in ups.items():
                if cand == chosen[-1]:
                    continue
                Cn = tip_to(C[-1], up)
                k = len(C) + 1
                holds = np.array([first_rest_s] + [hold] * (k - 1))
                sigma, _ = plan_sigma(
                    np.array(C + [Cn]),
                    holds,
                    np.full(k - 1, move_s),
                    profile,
                    requirements,
                    site,
                    g_sensitivity,
                )
                scored.append((_score(sigma, requirements), cand))
            _, pick = min(scored)
            chosen.append(pick)
            C.append(tip_to(C[-1], ups[pick]))
        holds = np.array([first_rest_s] + [hold] * n)
        sigma, _ = plan_sigma(
            np.array(C), holds, np.full(n, move_s), profile, requirements, site, g_sensitivity
        )
        worst = _worst(sigma, requirements)
        if best is None or worst < best.worst_ratio:
            poses = PoseList(
                name, np.array([ups[c] if c in ups else AXES[c] for c in chosen]), holds, np.full(n, move_s)
            )
            bound = (
                3 * profile.arw / math.sqrt(poses.duration_s) / float(np.min(requirements.si[P.GYRO_BIAS]))
            )
            best = HandDesign(poses, tuple(chosen), worst, sigma, bound)
    assert best is not None
    return best
