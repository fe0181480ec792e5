"""Weights that the data earn: variance components of a fit of a run placed by hand.

The profile's white noise gives each observation its sigma (a rest's mean
specific force and rate, ``VRW / sqrt(T)`` and ``ARW / sqrt(T)``; a move's turn,
``ARW sqrt(T)``). A real recording adds what the profile does not know: a hand
that trembles, a bias that wanders between rests, a move the model does not
describe (a sample-timing error, the gyro's response to a fast turn). Left at
the profile's weights, a move that does not fit bends the rest attitudes it
chains, and through them the accelerometer estimates.

So each group of observations whose residuals refute the profile's noise
(:func:`refuted`: its whitened residual power outside the 99 % band of a chi2 on
its redundancy, the blocks :func:`profile_outliers` names left out) gets the
noise its residuals show, as a sum of components of known shape and unknown size
(:func:`components`):

* rest specific force: white (``1 / T``) and a floor per rest (the same
  whatever the rest's length: a bias that wanders, a placing that settles);
* rest rate: white and a floor per rest (the gyro bias wandering);
* move turns: white (``T``) and a part proportional to the angle the gyro
  turned through (scale-factor nonlinearity, timing, a fast turn's response).

Their sizes are Förstner's variance components: each is rescaled by the
whitened residual power of its share over the redundancy of its share
(``1 - h_ii`` of the hat matrix), until they settle. And a block (one rest's
force, one rest's rate, one move's turn: three scalars) whose residual exceeds
what its group's noise allows at the 99.99 % level earns a variance of its own:
it keeps its place in the fit but no longer bends the rest; a rest's specific
force only where the rests alone call it outlying (:func:`confirmed`). The fit's
sigmas then carry the noise the data showed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

GROUPS = ("force", "rate", "move")  # the prior on the Earth rate keeps its weight
# Each group's components: (name, what it is in words).
COMPONENTS = {
    "force": (("white", "white"), ("floor", "a floor per rest")),
    "rate": (("white", "white"), ("floor", "a floor per rest")),
    "move": (("white", "white"), ("turn", "a part of the angle turned")),
}
GROUP_TEXT = {"force": "rest specific force", "rate": "rest rate", "move": "move turns"}
# A block beyond this chi2 quantile for its degrees of freedom (at its group's variance) is an
# outlier: one in ten thousand of honest blocks, so that white noise almost never triggers it.
OUTLIER_LEVEL = 0.9999
# A group's residual power outside this two-sided chi2 band at the profile's weights refutes the
# profile's noise for it: one honest recording in a hundred earns weights it did not need.
REFUTED_LEVEL = 0.99
# The second look at a group the first kept at the profile's weights (:func:`refuted_later`) calls
# it quieter only below this one-sided level's tail: one honest group in a thousand, where the
# first look's side allows five (a look again at data already judged asks for stronger evidence).
SECOND_LOOK_LEVEL = 0.998
# A profile may be pessimistic: a group whose residuals say so with this much redundancy (its
# factor then known to about 1/sqrt(2 r), 16 %) may go below the profile's white noise, to FLOOR
# (of its sigma) at most; on fewer degrees of freedom the profile's white noise stands.
SHRINK_REDUNDANCY = 20.0
FLOOR = 0.1
START = 0.01  # the size the non-white components start from (of the group's median profile variance)
SETTLED = 0.01  # relative change of every sigma below which the weights have settled


@dataclass
class Weights:
    """Variance components per group (over their shapes) and sigma scales of outlying blocks.

    Attributes
    ----------
    theta : dict of (group, component) to float
        Each component's size, relative to its shape (:func:`components`); the white
        ones are the squared factor on the profile's sigma.
    block : dict of tuple to float
        Extra sigma scale of each outlying block, keyed ``(kind, index)``.
    """

    theta: dict = field(
        default_factory=lambda: {
            (g, c): 1.0 if c == "white" else 0.0 for g in GROUPS for c, _ in COMPONENTS[g]
        }
    )
    block: dict = field(default_factory=dict)
    earning: tuple = ()  # the groups whose residuals refuted the profile's noise (`refuted`)

    def sigma(self, shapes: dict, s_profile: np.ndarray, labels: list) -> np.ndarray:
        """Each row's sigma: the components' variances summed, times any block's scale."""
        var = s_profile**2 * np.array([lab[0] not in GROUPS for lab in labels], dtype=float)
        for key, q in shapes.items():
            var = var + self.theta[key] * q
        return np.sqrt(var) * np.array([self.block.get(lab, 1.0) for lab in labels])

    def settled(self, before: Weights, shapes: dict, s_profile: np.ndarray, labels: list) -> bool:
        """Whether every row's sigma moved by less than `SETTLED` since ``before``."""
        a, b = self.sigma(shapes, s_profile, labels), before.sigma(shapes, s_profile, labels)
        return bool(np.all(np.abs(a - b) <= SETTLED * np.maximum(a, b)))

    def lines(self, sizes: dict | None = None) -> list[str]:
        """What the user reads: each group's components, then the outlying blocks."""
        parts = []
        for g in GROUPS:
            text = f"white x{math.sqrt(self.theta[(g, 'white')]):.2f}"
            if sizes and (g, "other") in sizes:
                text += f", {sizes[(g, 'other')]}"
            parts.append(f"{GROUP_TEXT[g]} {text}")
        out = ["noise the residuals show (white: over the profile's): " + "; ".join(parts)]
        if self.block:
            worst = sorted(self.block.items(), key=lambda kv: -kv[1])
            named = ", ".join(f"{k[0]} {k[1] + 1} x{v:.1f}" for k, v in worst[:5])
            more = f" and {len(worst) - 5} more" if len(worst) > 5 else ""
            out.append(
                f"{len(worst)} block(s) beyond their group's noise, weighted by their own: {named}{more}"
            )
        return out

    def to_json(self, sizes: dict | None = None) -> dict:
        return {
            "white_factor": {g: math.sqrt(self.theta[(g, "white")]) for g in GROUPS},
            "other": {g: sizes.get((g, "value")) for g in GROUPS} if sizes else {},
            "outliers": [
                {"kind": k[0], "index": int(k[1]) + 1, "sigma_scale": float(v)} for k, v in self.block.items()
            ],
        }


def components(labels: list, s_profile: np.ndarray, move_turn_rad: np.ndarray) -> dict:
    """The shape of each variance component over the rows (zero outside its group).

    The white ones are the profile's variances; a floor is the group's median profile
    variance on each of its rows (so that its size reads against the white one's); the
    moves' turn part is that median times the move's angle over the median angle, squared.
    """
    kinds = np.array([lab[0] for lab in labels])
    index = np.array([lab[1] for lab in labels])
    shapes = {}
    for g in GROUPS:
        rows = kinds == g
        ref = float(np.median(s_profile[rows] ** 2)) if rows.any() else 0.0
        shapes[(g, "white")] = np.where(rows, s_profile**2, 0.0)
        if g == "move":
            angle = np.zeros(len(labels))
            angle[rows] = move_turn_rad[index[rows]]
            typical = float(np.median(angle[rows])) if rows.any() else 1.0
            shapes[(g, "turn")] = ref * (angle / max(typical, 1e-12)) ** 2
        else:
            shapes[(g, "floor")] = np.where(rows, ref, 0.0)
    return shapes


def component_sizes(weights: Weights, shapes: dict, labels: list, move_turn_rad: np.ndarray) -> dict:
    """The non-white components in the user's units: the floors' sigma, the turn part's share."""
    out: dict = {}
    kinds = np.array([lab[0] for lab in labels])
    rows = np.flatnonzero(kinds == "move")
    if rows.size:
        i = int(rows[0])
        angle = float(move_turn_rad[labels[i][1]])
        share = math.sqrt(weights.theta[("move", "turn")] * float(shapes[("move", "turn")][i])) / max(
            angle, 1e-12
        )
        out[("move", "other")] = f"{100 * share:.2g} % of the angle turned"
        out[("move", "value")] = share
    for g, unit, per in (("force", "mm/s^2", 1e3), ("rate", "deg/h", 180.0 / math.pi * 3600.0)):
        rows = kinds == g
        if rows.any():
            value = math.sqrt(weights.theta[(g, "floor")] * float(shapes[(g, "floor")][rows][0])) * per
            out[(g, "other")] = f"floor {value:.3g} {unit}"
            out[(g, "value")] = value
    return out


def redundancy(jac_w: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Each row's redundancy ``1 - h_ii`` for whitened Jacobian rows and their scaled covariance."""
    h = np.einsum("ij,jk,ik->i", jac_w, cov, jac_w)
    return np.clip(1.0 - h, 0.0, 1.0)


def _block_powers(e: np.ndarray, red: np.ndarray, labels: list, sigma: np.ndarray) -> list[tuple]:
    """Each block of the weighted groups: its label ``(kind, index)``, whitened power, redundancy, rows."""
    blocks: dict[tuple, list[int]] = {}
    for i, lab in enumerate(labels):
        if lab[0] in GROUPS:
            blocks.setdefault(lab, []).append(i)
    return [
        (lab, float(np.sum((e[rows] / sigma[rows]) ** 2)), float(red[rows].sum()), len(rows))
        for lab, rows in blocks.items()
    ]


def _beyond(q: float, r: float, size: int, level: float) -> bool:
    """Whether a block's whitened power ``q`` on redundancy ``r`` exceeds `OUTLIER_LEVEL` at ``level``."""
    return r > 0.1 and q > level * chi2.ppf(OUTLIER_LEVEL, size) * r / size


def confirmed(blocks, force_confirmed) -> set:
    """The outlying blocks less any rest's specific force the rests alone do not call outlying.

    A rest's mean specific force is the fit's cleanest reading: its magnitude is gravity
    through the accelerometer's errors, whatever the attitude. Moves that do not fit (a
    timing error, a gyro's response the model lacks) bend the chained attitudes, and on a
    recording of few rests they can pull the accelerometer estimates until a rest's
    magnitude misses: judged in the joint fit, that rest is then called an outlier, its
    weight goes, and the pull grows (on a real 77 s recording of 12 rests, two rests whose
    magnitude the other ten confirm within 1 mm/s^2 were weighted down x9 and x12, and the
    accelerometer's x bias came out 5 of its sigmas from the whole recording's). So a force
    block is an outlier only where the rests alone say so (``force_confirmed``, the force
    blocks of a fit without the moves; None: no such fit, every block stands); what is left
    of a move's misfit is the moves' to carry.
    """
    if force_confirmed is None:
        return set(blocks)
    return {lab for lab in blocks if lab[0] != "force" or lab in force_confirmed}


def profile_outliers(
    e: np.ndarray, red: np.ndarray, labels: list, s_profile: np.ndarray, force_confirmed=None
) -> set:
    """The blocks beyond their group's noise at the profile's weights, that noise judged robustly.

    An outlier is a minority of its group: where most of a group's blocks exceed the
    profile's noise (a unit noisier than its profile says), the profile is what is wrong,
    not those blocks. So each group's level is the profile's, or the median of its blocks'
    whitened power per redundancy over that median's value for white noise (``chi2(k)/k``
    of a block of ``k`` rows), if that is higher; a block is an outlier beyond the 99.99 %
    quantile at that level. Judged at the profile's level alone, a unit 5x noisier than its
    profile had 13 blocks (most of its moves) called outliers and the quietest moves left
    to say that the profile held: its gyro sigmas came out 2.5x too small.
    """
    out: set = set()
    by_group: dict[str, list] = {g: [] for g in GROUPS}
    for block in _block_powers(e, red, labels, s_profile):
        by_group[block[0][0]].append(block)
    for items in by_group.values():
        ratios = [q / r / (chi2.median(k) / k) for _, q, r, k in items if r > 0.1]
        level = max(1.0, float(np.median(ratios))) if ratios else 1.0
        out |= {lab for lab, q, r, k in items if _beyond(q, r, k, level)}
    return confirmed(out, force_confirmed)


def refuted(
    e: np.ndarray,
    red: np.ndarray,
    labels: list,
    s_profile: np.ndarray,
    outliers=(),
    quieter_only=False,
    level=REFUTED_LEVEL,
) -> tuple:
    """The groups whose residuals at the profile's weights its noise cannot explain (with
    ``quieter_only``, only those whose residuals are too small for it).

    A group keeps the profile's weights unless its whitened residual power lies outside
    the two-sided ``level`` band (`REFUTED_LEVEL`) of a chi2 on its redundancy: a recording
    whose noise is the profile's keeps its weights (and the sigmas `analyze` predicts), one whose noise
    is not earns its own. The blocks in ``outliers`` are left out (they earn their own):
    name them with :func:`profile_outliers`, which judges a group noisier than the profile
    as a whole at its own median level, so that its loudest half is not left out and its
    quietest half left to vouch for the profile.
    """
    kinds = np.array([lab[0] for lab in labels])
    kept = np.array([lab not in outliers for lab in labels], dtype=bool)
    out = []
    for g in GROUPS:
        rows = (kinds == g) & kept
        r = float(red[rows].sum())
        if r < 1.0:
            continue
        power = float(np.sum((e[rows] / s_profile[rows]) ** 2))
        p = float(chi2.cdf(power, r))
        if min(p, 1.0 if quieter_only else 1.0 - p) < 0.5 * (1.0 - level):
            out.append(g)
    return tuple(out)


def refuted_later(weights: Weights, e: np.ndarray, red: np.ndarray, labels: list, s_profile: np.ndarray):
    """The weights with the groups that keep the profile's noise and now refute it earning too, or None.

    A group is judged at the profile's weights before any earns its own (:func:`refuted`);
    there the misfit of another group can hide its own noise: on a real recording whose moves
    missed by x12 their noise, the rests' rates, bent by those moves, showed a power of 103 on
    a redundancy of 114, and 23 on 114 once the moves were weighted by their own (a gyro five
    times quieter than its profile). Judged again when the weights settle, such a group
    earns its weights too: its sigmas are what its residuals show, not the profile's. A misfit
    elsewhere only adds to a group's power, so it can hide only a group quieter than its
    profile: the second look judges that side alone, and at `SECOND_LOOK_LEVEL`. The group
    passed the first look; judged again at the first look's level, an honest group near its
    edge crosses it when the weights move elsewhere (on simulated runs of the profile's noise,
    a power of 18 on a redundancy of 30 at the first look, 13 on 29 at the second, p = 0.004),
    and its sigmas shrink below what the noise gives.
    """
    rest = tuple(g for g in GROUPS if g not in weights.earning)
    if not rest:
        return None
    outliers = tuple(weights.block)
    quieter = refuted(e, red, labels, s_profile, outliers, quieter_only=True, level=SECOND_LOOK_LEVEL)
    later = tuple(g for g in quieter if g in rest)
    if not later:
        return None
    return Weights(dict(weights.theta), dict(weights.block), weights.earning + later)


def reweighted(
    weights: Weights,
    e: np.ndarray,
    red: np.ndarray,
    labels: list,
    shapes: dict,
    s_profile: np.ndarray,
    force_confirmed=None,
) -> Weights:
    """One Förstner step of every component, then the outlier test, at the current fit.

    Parameters
    ----------
    weights : Weights
        Those the residuals ``e`` were fitted with.
    e : ndarray, shape (m,)
        Residuals (SI).
    red : ndarray, shape (m,)
        Each row's redundancy at ``weights``.
    labels : list of tuple
        ``(kind, index)`` of each row's block.
    shapes : dict
        :func:`components`.
    s_profile : ndarray, shape (m,)
        The profile's sigma of each row.
    force_confirmed : set, optional
        The rests' force blocks that may be outliers (:func:`confirmed`).

    Returns
    -------
    Weights
    """
    sigma = weights.sigma(shapes, s_profile, labels)
    z2 = (e / sigma) ** 2
    inlier = np.array([lab not in weights.block for lab in labels], dtype=bool)
    theta = dict(weights.theta)
    for g in GROUPS:
        if g not in weights.earning:
            continue
        for c, _ in COMPONENTS[g]:
            share = np.where(inlier, weights.theta[(g, c)] * shapes[(g, c)] / sigma**2, 0.0)
            if c != "white" and theta[(g, c)] == 0.0:  # a component starts small, not at zero
                theta[(g, c)] = START
                continue
            r = float(red @ share)
            if r > 1e-3:
                theta[(g, c)] *= float(z2 @ share) / r
        rows = np.array([lab[0] == g for lab in labels])
        r_group = float(red[rows & inlier].sum())
        floor = FLOOR if r_group >= SHRINK_REDUNDANCY else 1.0
        theta[(g, "white")] = max(theta[(g, "white")], floor**2)
    new = Weights(theta, {}, weights.earning)
    base = new.sigma(shapes, s_profile, labels)
    for lab, q, r, k in _block_powers(e, red, labels, base):
        if _beyond(q, r, k, 1.0) and confirmed({lab}, force_confirmed):
            new.block[lab] = math.sqrt(q / r)
    return new
