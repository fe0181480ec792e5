"""The worst case over the mounting box: grid points, then an IPOPT search beyond them.

A sequence's figures are quoted at the worst base mounting within ``+-tolerance_deg``
(docs/conventions.md): :func:`analyze_tolerance` for the 21 parameters, :func:`analyze_extras` for
what fitting a real unit's optional terms costs them. Under white noise each mounting comes from
the mounting basis (:mod:`calib.analysis.mounting`), with an exact sigma gradient; with Gauss-Markov
bias instability from the GM basis (:mod:`calib.analysis.gm_mounting`), the optional terms' columns
too; white noise with optional terms, and ``Evaluation.direct`` (``how=``), along each mounting's own
nominal trajectory.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np

from calib.errors import CalibError
from calib.model import params as P
from calib.model.information import eliminate, projected_covariance, scaled_inverse
from calib.model.optional_terms import NONE as NO_EXTRAS, OptionalTerms
from calib.model.requirements import PAPER, Requirements
from calib.nav.jacobian import N_UNKNOWN, PHI0 as PHI0_IDX
from calib.nav.site import Site
from calib.noise.profiles import NoiseProfile
from calib.sequence.definition import Sequence

from . import ipopt
from .gm_mounting import (
    GmBasis,
    box_informations,
    extra_basis,
    gm_basis,
    informations,
    nominal_information,
)
from .mounting import SequenceModel, sequence_model
from .nominal import BATCH_MOUNTINGS, mounting_informations
from .observability import Observability, from_information


@dataclass(frozen=True)
class Evaluation:
    """How a worst case's mountings are evaluated: the search's starts, the reference paths."""

    starts: int = 2  # IPOPT starts of the white-noise search (its worst grid points)
    # Mountings along their own trajectories sharing a pass of the noise filter (1: each alone).
    batch: int = BATCH_MOUNTINGS
    direct: bool = False  # GM: each mounting along its own trajectory, not the GM basis (the reference)


EVALUATION = Evaluation()  # the defaults


@dataclass(frozen=True)
class Robustness:
    """Observability over the +-tolerance box of base mountings."""

    nominal: Observability
    worst: Observability  # the mounting with the largest worst ratio
    per_parameter_worst_sigma: np.ndarray  # (21,) SI, max over the box of each sigma
    points: int
    tolerance_deg: float
    searched: bool = False  # whether IPOPT refined the worst parameter beyond the 27 points

    @property
    def per_parameter_worst_ratio(self) -> np.ndarray:
        return self.nominal.requirements.ratio(self.per_parameter_worst_sigma)


def search_worst_mounting(
    model: SequenceModel,
    index: int,
    starts_deg: list,
    tolerance_deg: float,
    requirements: Requirements = PAPER,
) -> tuple[np.ndarray, float]:
    """Maximise one parameter's sigma over the mounting box with IPOPT, from several starts.

    The gradient is exact (:meth:`SequenceModel.sigma_gradient`: the mounting basis
    differentiated). Returns the mounting (rotation vector, rad) and that
    parameter's sigma (SI).
    """
    req = requirements.si[index]

    def value(theta_deg):
        # Judged by the same requirements as the box's points: against the paper's (the default),
        # a MEMS unit's parameter reads as not estimable, its sigma inf, and IPOPT's steps fail.
        return model.analyze(np.radians(theta_deg), requirements=requirements).sigma[index] / req

    def gradient(theta_deg):
        _, grad = model.sigma_gradient(np.radians(theta_deg), index)
        return grad * (math.pi / 180.0) / req

    f = ipopt.function(f"sigma_{P.NAMES[index]}", 3, 1, value, gradient)
    best_x, best = ipopt.maximize_in_box(f, starts_deg, tolerance_deg)
    if best_x is None:
        raise CalibError(
            f"no start gave a finite sigma of {P.NAMES[index]} in the mounting box",
            "worst-case search",
        )
    return np.radians(best_x), best * req


FD_STEP_DEG = 1e-3  # forward step of the direct search's gradient (see search_worst_direct)
DIRECT_MAX_ITER = 8


def search_worst_direct(
    sigma_of, start_deg, tolerance_deg: float, max_iter: int = DIRECT_MAX_ITER, sigmas_of=None
) -> tuple[np.ndarray, float]:
    """Maximise ``sigma_of(rotvec)`` over the box with IPOPT where no closed form exists.

    For Gauss-Markov bias instability the noise filter's gains depend on the
    attitude of every interval (a Riccati recursion), and the optional terms'
    sensitivities are polynomials of up to third degree in the mounting: neither
    enters the 63-term basis. Each value is then an exact evaluation along the
    mounting's own trajectory (as the 27 box points), and the gradient IPOPT is
    steered by is a forward difference of those values, ``FD_STEP_DEG`` apart
    (truncation ~ step / 2 x curvature: ~1e-4 of the gradient over a 3 deg box;
    rounding ~1e-12 / 2e-5 rad). What is returned is the best exact evaluation
    seen, so the search can only raise the worst case, never invent one.

    ``sigmas_of(rotvecs) -> sigmas``, if given, evaluates a gradient's points (the
    value and its three steps, those not yet seen) in one call: a batch shares one
    pass of the noise filter (:func:`calib.analysis.nominal.information_along_many`).

    Returns the mounting (rotation vector, rad) and its ``sigma_of``.
    """
    seen: dict[tuple, float] = {}

    def key_of(theta_deg):
        return tuple(np.round(theta_deg, 12))

    def value(theta_deg):
        key = key_of(theta_deg)
        if key not in seen:
            seen[key] = float(sigma_of(np.radians(theta_deg)))
        return seen[key]

    def gradient(theta_deg):
        points = [np.asarray(theta_deg, dtype=float)] + [theta_deg + FD_STEP_DEG * e for e in np.eye(3)]
        new = [t for t in points if key_of(t) not in seen]
        if sigmas_of is not None and len(new) > 1:
            for t, sigma in zip(new, sigmas_of([np.radians(t) for t in new]), strict=True):
                seen[key_of(t)] = float(sigma)
        f0 = value(points[0])
        return np.array([(value(t) - f0) / FD_STEP_DEG for t in points[1:]])

    scale = value(np.asarray(start_deg, dtype=float))
    f = ipopt.function("sigma", 3, 1, lambda t: value(t) / scale, lambda t: gradient(t) / scale)
    ipopt.maximize_in_box(f, [start_deg], tolerance_deg, max_iter=max_iter, tol=1e-5)
    # Only the box's evaluations count, not the forward-difference points outside it.
    inside = {k: v for k, v in seen.items() if max(abs(x) for x in k) <= tolerance_deg}
    key = max(inside, key=inside.__getitem__)
    return np.radians(np.array(key)), inside[key]


def _evaluator(seq: Sequence, profile: NoiseProfile, site: Site, requirements: Requirements, how: Evaluation):
    """``evaluate(rotvecs, nominal=None) -> [Observability]`` and the model steering the search.

    The model is the white path's :class:`calib.analysis.mounting.SequenceModel`, the GM
    profile's :class:`calib.analysis.gm_mounting.GmBasis`, or None with ``how.direct``: each
    mounting of a GM profile then evaluated along its own trajectory, ``how.batch`` at a
    time (the reference the GM basis is held to).
    """
    if profile.has_gauss_markov and how.direct:
        # Bias-instability weights depend on the mounting (measured: up to 4.7 % on a sigma
        # for designed-30min-9moves if the nominal weights are reused), so evaluate each directly.
        def evaluate_each(rotvecs, nominal=None):
            infos = mounting_informations(seq, profile, site, rotvecs, batch=how.batch)
            return [
                from_information(info, seq.duration_s, profile.name, rv, nominal, requirements)
                for info, rv in zip(infos, rotvecs, strict=True)
            ]

        return evaluate_each, None
    if profile.has_gauss_markov:
        basis = gm_basis(seq, profile, site)

        def evaluate_gm(rotvecs, nominal=None):
            return [
                from_information(info, seq.duration_s, profile.name, rv, nominal, requirements)
                for info, rv in zip(informations(basis, rotvecs), rotvecs, strict=True)
            ]

        return evaluate_gm, basis
    model = sequence_model(seq, profile, site)

    def evaluate(rotvecs, nominal=None):
        return [model.analyze(rv, nominal, requirements) for rv in rotvecs]

    return evaluate, model


INTERPOLATION_STEPS = 60  # the interpolant's search lattice: 61^3 points over the box


def _lagrange_3(x: np.ndarray, h: float) -> np.ndarray:
    """The three quadratic Lagrange polynomials of the nodes ``-h, 0, h`` at ``x``, (len(x), 3)."""
    x = np.asarray(x, dtype=float)[:, None]
    return np.hstack([x * (x - h) / (2 * h * h), (h * h - x * x) / (h * h), x * (x + h) / (2 * h * h)])


def box_interpolant_maximum(values: np.ndarray, tolerance_deg: float) -> tuple[np.ndarray, float]:
    """Where the triquadratic interpolant of the 27 box points' values peaks in the box.

    ``values`` (27,) are at the points ``itertools.product(levels, levels, levels)``,
    ``levels = (-t, 0, t)``; the interpolant through all 27 (a product of quadratic
    Lagrange polynomials, exact at the points) is maximised over a lattice of
    ``INTERPOLATION_STEPS + 1`` points per axis (the points among them). It steers
    the search for the worst mounting where each evaluation is a pass of a
    Gauss-Markov noise filter over the whole run: where the interpolant peaks away
    from the points, one exact evaluation there decides (:func:`analyze_tolerance`).
    Returns the peak (degrees) and the interpolant's value there.
    """
    V = np.asarray(values, dtype=float).reshape(3, 3, 3)
    x = np.linspace(-tolerance_deg, tolerance_deg, INTERPOLATION_STEPS + 1)
    L = _lagrange_3(x, tolerance_deg)
    lattice = np.einsum("abc,ia,jb,kc->ijk", V, L, L, L)
    i, j, k = np.unravel_index(int(np.argmax(lattice)), lattice.shape)
    return np.array([x[i], x[j], x[k]]), float(lattice[i, j, k])


def analyze_tolerance(
    seq: Sequence,
    profile: NoiseProfile,
    site: Site,
    tolerance_deg: float = 3.0,
    search: bool = True,
    requirements: Requirements = PAPER,
    extras: OptionalTerms = NO_EXTRAS,
    how: Evaluation = EVALUATION,
) -> Robustness:
    """Worst case over the +-tolerance box of base mountings at ``site``.

    The 27 corner/edge/face/centre points are evaluated; then, if ``search``,
    IPOPT maximises the sigma of the worst parameter, since the worst mounting
    need not be a grid point: under white noise from its ``how.starts`` worst grid
    points with the exact gradient of the mounting basis
    (:func:`search_worst_mounting`); under Gauss-Markov bias instability from its
    every mounting's information exact from the GM basis (:mod:`calib.analysis.gm_mounting`:
    the nominal and the 27 in one pass of the noise filter), the search steered by
    the 27 points' own values: where their interpolant peaks away from the points
    (:func:`box_interpolant_maximum`), one more exact evaluation.
    ``how.direct`` evaluates each GM mounting along its own trajectory instead, ``how.batch``
    at a time (``batch=1``: one at a time), the search then steered by forward
    differences (:func:`search_worst_direct`): the reference the GM basis is held to.
    ``extras``, the optional terms :func:`analyze_extras` will be asked about next: under
    a GM profile the box's pass of the filter then carries their columns too and serves
    both (:func:`calib.analysis.gm_mounting.box_informations`); the figures here are the same.
    """
    # One mounting alone costs less along its trajectory than through the GM basis (its
    # 543 columns): at zero tolerance the direct evaluation, the GM filter in one loop.
    if tolerance_deg == 0 and profile.has_gauss_markov and not how.direct:
        info = nominal_information(seq, profile, site)
        nominal = from_information(info, seq.duration_s, profile.name, np.zeros(3), None, requirements)
        return Robustness(nominal, nominal, nominal.sigma, 1, 0.0)
    if tolerance_deg == 0:
        how = replace(how, direct=True)
    evaluate, model = _evaluator(seq, profile, site, requirements, how)
    if tolerance_deg == 0:
        nominal = evaluate([np.zeros(3)])[0]
        return Robustness(nominal, nominal, nominal.sigma, 1, 0.0)
    levels = (-tolerance_deg, 0.0, tolerance_deg)
    grid = [np.array(p) for p in itertools.product(levels, levels, levels)]
    if isinstance(model, GmBasis):  # the nominal and the 27 in one pass of the filter
        rotvecs = [np.zeros(3)] + [np.radians(p) for p in grid]
        infos = box_informations(seq, profile, site, tolerance_deg, extras)
        infos = infos[:, :N_UNKNOWN, :N_UNKNOWN]
        nominal = from_information(infos[0], seq.duration_s, profile.name, rotvecs[0], None, requirements)
        results = [
            from_information(info, seq.duration_s, profile.name, rv, nominal, requirements)
            for info, rv in zip(infos[1:], rotvecs[1:], strict=True)
        ]
    else:
        nominal = evaluate([np.zeros(3)])[0]
        results = evaluate([np.radians(p) for p in grid], nominal)
    sigmas = np.array([r.sigma for r in results])
    per_param = sigmas.max(axis=0)
    worst = max(results, key=lambda r: r.worst[1])
    if not search or nominal.rank < P.N_PARAMS:
        return Robustness(nominal, worst, per_param, len(grid), tolerance_deg)
    index = int(np.argmax(requirements.ratio(per_param)))
    order = np.argsort(-sigmas[:, index])
    found = None
    if isinstance(model, SequenceModel):
        rotvec, sigma = search_worst_mounting(
            model, index, [grid[i] for i in order[: how.starts]], tolerance_deg, requirements
        )
    elif isinstance(model, GmBasis):
        peak, _ = box_interpolant_maximum(sigmas[:, index], tolerance_deg)
        rotvec, sigma = np.radians(grid[order[0]]), float(sigmas[order[0], index])
        if not any(np.allclose(peak, p, rtol=0.0, atol=1e-9) for p in grid):  # else: a point, exact already
            info = informations(model, [np.radians(peak)])[0]
            found = from_information(
                info, seq.duration_s, profile.name, np.radians(peak), nominal, requirements
            )
            rotvec, sigma = np.radians(peak), float(found.sigma[index])
    else:
        rotvec, sigma = search_worst_direct(
            lambda rv: evaluate([rv], nominal)[0].sigma[index],
            grid[order[0]],
            tolerance_deg,
            sigmas_of=lambda rvs: [o.sigma[index] for o in evaluate(rvs, nominal)],
        )
    if sigma > per_param[index]:
        found = found or evaluate([rotvec], nominal)[0]
        per_param = np.maximum(per_param, found.sigma)
        if found.worst[1] > worst.worst[1]:
            worst = found
    return Robustness(nominal, worst, per_param, len(grid), tolerance_deg, searched=True)


@dataclass(frozen=True)
class OptionalTermsCost:
    """What fitting a real unit's optional terms costs the 21, worst over the mounting box.

    Attributes
    ----------
    extras : OptionalTerms
    sigma_without, sigma_with : ndarray (21,)
        Each parameter's worst sigma over the box (SI) without and with the terms.
    extra_sigma : ndarray (e,)
        Each optional parameter's worst sigma (SI); inf where unobservable.
    unobservable : list of str
        Null directions of [21, extras] (scaled by requirements and typical sizes).
    points : int
    """

    extras: OptionalTerms
    sigma_without: np.ndarray
    sigma_with: np.ndarray
    extra_sigma: np.ndarray
    unobservable: list[str]
    points: int
    tolerance_deg: float
    searched: bool = False  # whether IPOPT searched beyond the points (analyze_extras)

    def verdicts(self) -> list[str]:
        """Per optional parameter: ``observable`` (3 sigma within its typical size),
        ``weak`` (beyond it) or ``unobservable``.
        """
        out = []
        for p, s in zip(self.extras.parameters, self.extra_sigma, strict=True):
            out.append(
                "unobservable" if not np.isfinite(s) else "observable" if 3.0 * s <= p.scale_si else "weak"
            )
        return out


def _extras_sigmas(
    seq: Sequence, profile: NoiseProfile, extras: OptionalTerms, requirements: Requirements, nom_info
):
    """``sigmas(rotvec, info) -> (sigma of the 21 without, with, sigma of the extras)`` (SI).

    What is observed is judged at the nominal mounting (information ``nom_info``),
    returned as the second value.
    """
    scale = np.concatenate([requirements.si, extras.scale_si])
    names = P.NAMES + extras.names
    nominal = scaled_inverse(eliminate(nom_info, PHI0_IDX) * np.outer(scale, scale), names)
    nominal_without = from_information(
        nom_info[:N_UNKNOWN, :N_UNKNOWN], seq.duration_s, profile.name, np.zeros(3), None, requirements
    )

    def sigmas(rotvec, info):
        obs = from_information(
            info[:N_UNKNOWN, :N_UNKNOWN], seq.duration_s, profile.name, rotvec, nominal_without, requirements
        )
        M = eliminate(info, PHI0_IDX) * np.outer(scale, scale)
        variance = np.diag(projected_covariance(M, nominal.null_basis))
        s = np.where(nominal.estimable, np.sqrt(np.abs(variance)), np.inf) * scale
        return obs.sigma, s[: P.N_PARAMS], s[P.N_PARAMS :]

    return sigmas, nominal


def _extras_evaluator(
    seq: Sequence,
    profile: NoiseProfile,
    site: Site,
    extras: OptionalTerms,
    requirements: Requirements,
    batch: int,
    one: bool,
):
    """``evaluate(rotvecs) -> [(sigma of the 21 without, with, sigma of the extras)]`` (SI).

    Each mounting is evaluated directly along its own nominal trajectory, ``batch`` at a time
    (:func:`calib.analysis.nominal.mounting_informations`); what is observed is judged at the
    nominal mounting (the first evaluation), returned second. ``one``: the nominal mounting's
    through :func:`calib.analysis.gm_mounting.nominal_information` (GM profile, zero tolerance).
    """
    if one:
        nom_info = nominal_information(seq, profile, site, extras)
    else:
        infos = mounting_informations(seq, profile, site, [np.zeros(3)], extras, batch)
        nom_info = infos[0]
    sigmas, nominal = _extras_sigmas(seq, profile, extras, requirements, nom_info)

    def evaluate(rotvecs):
        if len(rotvecs) == 1 and not np.any(rotvecs[0]):  # the nominal alone (a design's screen): as above
            return [sigmas(rotvecs[0], nom_info)]
        infos = mounting_informations(seq, profile, site, rotvecs, extras, batch)
        return [sigmas(rv, info) for rv, info in zip(rotvecs, infos, strict=True)]

    return evaluate, nominal


def _gm_extras(
    seq: Sequence,
    profile: NoiseProfile,
    site: Site,
    extras: OptionalTerms,
    requirements: Requirements,
    tolerance_deg: float,
):
    """The GM basis's ``evaluate`` (as :func:`_extras_evaluator`'s), the nominal and the points' results.

    The nominal mounting and the 27 box points in one pass of the noise filter
    (:func:`calib.analysis.gm_mounting.box_informations`; the terms' columns: ``extra_basis``).
    """
    points = [np.radians(p) for p in itertools.product(*[(-tolerance_deg, 0.0, tolerance_deg)] * 3)]
    basis = gm_basis(seq, profile, site)
    xb = extra_basis(seq, site, extras)

    def infos_of(rotvecs):
        return informations(basis, rotvecs, xb)

    infos = box_informations(seq, profile, site, tolerance_deg, extras)
    sigmas, nominal = _extras_sigmas(seq, profile, extras, requirements, infos[0])

    def evaluate(rotvecs):
        return [sigmas(rv, info) for rv, info in zip(rotvecs, infos_of(rotvecs), strict=True)]

    return evaluate, nominal, [sigmas(rv, info) for rv, info in zip(points, infos[1:], strict=True)]


def analyze_extras(
    seq: Sequence,
    profile: NoiseProfile,
    site: Site,
    extras: OptionalTerms,
    tolerance_deg: float = 3.0,
    requirements: Requirements = PAPER,
    search: bool = False,
    how: Evaluation = EVALUATION,
) -> OptionalTermsCost:
    """Sigma of the 21 with and without the optional terms, and theirs, worst over the box at ``site``.

    Both figures come from the same 27 mountings (corners, edges, faces and
    centre of the box), so their ratio is the cost of the terms alone. Under white
    noise each is evaluated directly along its nominal trajectory (the optional
    terms' moments are not in the 63-term mounting basis), ``how.batch`` at a time
    (``batch=1``: one at a time, the unbatched reference); with ``search``, IPOPT
    then maximises the sigma (with the terms) of the worst of the 21 from its worst
    grid point (:func:`search_worst_direct`), and that mounting counts as a 28th.
    Under Gauss-Markov bias instability (unless ``how.direct``, which keeps the above)
    the 21 and phi0 come from the GM basis and only the terms' columns from each
    trajectory, the nominal and the 27 whitened in one pass of the noise filter
    (:func:`calib.analysis.gm_mounting.informations`); the search is then the interpolant's
    peak, evaluated exactly if it is not one of the points, as in :func:`analyze_tolerance`.
    """
    levels = (-tolerance_deg, 0.0, tolerance_deg) if tolerance_deg > 0 else (0.0,)
    points = [np.radians(p) for p in itertools.product(levels, levels, levels)]
    fast = profile.has_gauss_markov and not how.direct and tolerance_deg > 0
    if fast:
        evaluate, nominal, results = _gm_extras(seq, profile, site, extras, requirements, tolerance_deg)
    else:
        one = profile.has_gauss_markov and not how.direct and tolerance_deg == 0
        evaluate, nominal = _extras_evaluator(seq, profile, site, extras, requirements, how.batch, one)
        results = evaluate(points)
    searched = search and tolerance_deg > 0 and bool(nominal.estimable[: P.N_PARAMS].all())
    if searched and fast:
        with_ = np.array([r[1] for r in results])
        index = int(np.argmax(requirements.ratio(with_.max(axis=0))))
        peak, _ = box_interpolant_maximum(with_[:, index], tolerance_deg)
        if not any(np.allclose(np.radians(peak), p, rtol=0.0, atol=1e-9) for p in points):
            results.extend(evaluate([np.radians(peak)]))
    elif searched:
        with_ = np.array([r[1] for r in results])
        index = int(np.argmax(requirements.ratio(with_.max(axis=0))))
        start = np.degrees(points[int(np.argmax(with_[:, index]))])
        rotvec, _ = search_worst_direct(
            lambda rv: evaluate([rv])[0][1][index],
            start,
            tolerance_deg,
            sigmas_of=lambda rvs: [r[1][index] for r in evaluate(rvs)],
        )
        results.extend(evaluate([rotvec]))
    without, with_, extra = (np.max([r[i] for r in results], axis=0) for i in range(3))
    return OptionalTermsCost(
        extras, without, with_, extra, nominal.null_directions(), len(points), tolerance_deg, searched
    )
