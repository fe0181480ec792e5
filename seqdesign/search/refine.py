"""Dwell refinement of a walk with casadi + IPOPT, on the search model's information."""

from __future__ import annotations

import functools
import math

import numpy as np

from calib.analysis import ipopt
from calib.model import params as P
from calib.model.information import inverse_diagonal
from calib.model.requirements import PAPER, Requirements
from calib.nav.jacobian import N_UNKNOWN
from calib.nav.site import Site
from calib.noise.gm_filter import gm_start_covariance
from calib.noise.profiles import NoiseProfile

from .constraints import Constraints, turn_rate, turn_seconds
from .gm import SegmentBlock, fold, fold_block, segment_blocks, stack, start_state
from .graph import apply_move, as_node, flip_graph
from .objective import scaled_marginal
from .segments import (
    SEARCH_REST_INTERVALS,
    rest_at,
    rest_columns,
    rest_steady_state,
    segment_effect,
    start_covariance,
    turn_columns,
    turn_effect,
)


def walk_information(
    walk, c: Constraints, dwells, site: Site, profile: NoiseProfile, P_ss: np.ndarray
) -> np.ndarray:
    """Search-model information of a walk with individual dwells (smooth in the dwells)."""
    graph = flip_graph(c.start, c.axes)
    node = as_node(c.start)
    if profile.has_gauss_markov:
        return _walk_information_exact(walk, c, dwells, site, profile)
    e = segment_effect(rest_at(node, dwells[0]), site, profile, None, SEARCH_REST_INTERVALS, initial=True)
    X, N = e.B, e.M3
    for mv, d in zip(walk, dwells[1:], strict=True):
        parts = [turn_effect(node, mv, turn_seconds(mv, c), turn_rate(mv, c), site, profile, P_ss.tobytes())]
        node = apply_move(graph, node, mv)
        rest = rest_at(node, d)
        parts.append(
            segment_effect(rest, site, profile, start_covariance(P_ss, rest.C), SEARCH_REST_INTERVALS)
        )
        for eff in parts:
            XM2 = X.T @ eff.M2
            N = N + X.T @ eff.M1 @ X + XM2 + XM2.T + eff.M3
            X = eff.A @ X + eff.B
    return N


def _walk_information_exact(walk, c: Constraints, dwells, site: Site, profile: NoiseProfile) -> np.ndarray:
    """:func:`walk_information` with the filter covariance carried along (GM profiles)."""
    return walk_informations_exact(walk, c, [dwells], site, profile)[0]


@functools.lru_cache(maxsize=8)
def _graph(start, axes: str):
    """:func:`flip_graph` of a start, built once per refinement (every IPOPT evaluation walks it)."""
    return flip_graph(start, axes)


@functools.lru_cache(maxsize=4096)
def turn_block(node, mv, duration, rate, site: Site, profile) -> SegmentBlock:
    """A turn's :class:`SegmentBlock` from ``node`` (cached: every IPOPT evaluation folds the same turns)."""
    cols = turn_columns(node, mv, duration, rate, site, profile)
    return segment_blocks(stack([cols]))


def walk_informations_exact(
    walk,
    c: Constraints,
    dwell_sets,
    site: Site,
    profile: NoiseProfile,
    closed_form: bool = True,
) -> np.ndarray:
    """Information ``(B, 24, 24)`` of one walk under ``B`` sets of dwells, batched (GM).

    The turns are shared; every rest has :data:`SEARCH_REST_INTERVALS` intervals
    whatever its length, so the rests of the ``B`` candidates stack and one fold
    carries them all (what IPOPT's finite differences need at once). Each turn is
    folded in closed form (:func:`turn_block`, built once per turn, not a loop over
    its intervals at every evaluation; ``closed_form=False``: the loop, the reference).
    """
    graph = _graph(as_node(c.start), c.axes)
    node = as_node(c.start)
    B = len(dwell_sets)
    X, N, Pc = (np.repeat(a[None], B, axis=0) for a in start_state(gm_start_covariance(profile), N_UNKNOWN))
    dwell_sets = np.asarray(dwell_sets, dtype=float)
    rows = np.arange(B)

    def rests(node, k):
        return stack([rest_columns(node, float(d), site, profile) for d in dwell_sets[:, k]])

    X, N, Pc = fold(rests(node, 0), X, N, Pc, rows)
    first = np.zeros(B, dtype=int)
    for k, mv in enumerate(walk, start=1):
        turn = (node, mv, turn_seconds(mv, c), turn_rate(mv, c), site, profile)
        if closed_form:
            X, N, Pc = fold_block(turn_block(*turn), X, N, Pc, first)
        else:
            X, N, Pc = fold(turn_columns(*turn), X, N, Pc)
        node = apply_move(graph, node, mv)
        X, N, Pc = fold(rests(node, k), X, N, Pc, rows)
    return N


def refine_dwells(
    walk,
    c: Constraints,
    dwell0: float,
    site: Site,
    profile: NoiseProfile,
    objective: str = "worst",
    requirements: Requirements = PAPER,
    repeats: int = 1,
) -> tuple[list[float], float, float]:
    """Optimise the dwells of a walk under the time budget (IPOPT).

    The dwells of a motif played ``repeats`` times are tied across the plays, and a
    motif longer than :data:`MAX_REFINE_DWELLS` moves ties them in that many blocks
    (:func:`dwell_groups`: IPOPT's derivatives are finite differences).

    Minimises ``t`` subject to ``ratio_i(dwells) <= t`` for all 21 (the worst ratio,
    smooth in epigraph form), ``sum(dwells) + turns <= budget`` and the dwell bounds;
    ratios from a casadi Callback over the search model.

    ``site`` is the latitude and gravity the search scores at (normal gravity at its height).
    Returns the dwells, the objective with uniform dwells and after.
    """
    import casadi as ca

    P_ss = rest_steady_state(site, profile, dwell0)
    groups = dwell_groups(len(walk), repeats)
    n = int(groups.max()) + 1
    count = np.bincount(groups, minlength=n).astype(float)
    turn_time = sum(turn_seconds(m, c) for m in walk)
    scale = 100.0  # dwells in units of 100 s for IPOPT

    def ratios_many(D):  # (B, n) dwell variables, s -> (B, 21) ratios
        sets = [list(d[groups]) for d in np.asarray(D, dtype=float)]
        if profile.has_gauss_markov:  # one batched fold for all (finite differences)
            Ns = walk_informations_exact(walk, c, sets, site, profile)
        else:
            Ns = [walk_information(walk, c, d, site, profile, P_ss) for d in sets]
        return np.array(
            [3.0 * np.sqrt(inverse_diagonal(scaled_marginal(N, False, requirements))) for N in Ns]
        )

    def ratios(dw):
        return ratios_many(np.asarray(dw, dtype=float)[None])[0]

    cb = _ratios_callback(ratios_many, n, scale)
    x = ca.MX.sym("d", n)
    t = ca.MX.sym("t")
    r = cb(x)
    total = ca.dot(ca.DM(count), x) * scale + turn_time
    if objective == "worst":
        f, gcon = t, ca.vertcat(r - t, total - c.budget_s)
        ubg = np.zeros(P.N_PARAMS + 1)
    else:  # A-optimal in the refinement for the other objectives
        f, gcon = ca.sum1(r**2) / 9.0, ca.vertcat(total - c.budget_s)
        ubg = np.zeros(1)
    uniform = np.full(n, dwell0)
    r0 = ratios(uniform)
    kept = list(uniform[groups]), float(r0.max()), float(r0.max())  # the uniform dwells kept
    if not np.all(np.isfinite(r0)):  # a parameter not estimable at this scale: no slope to follow
        return kept
    solver = ca.nlpsol(
        "dwells",
        "ipopt",
        {"x": ca.vertcat(x, t), "f": f, "g": gcon},
        ipopt.options(max_iter=40, tol=1e-4),
    )
    sol = solver(
        x0=np.concatenate([uniform / scale, [r0.max()]]),
        lbx=np.concatenate([np.full(n, c.min_dwell_s / scale), [0.0]]),
        ubx=np.concatenate([np.full(n, c.max_dwell_s / scale), [np.inf]]),
        lbg=np.full(len(ubg), -np.inf),
        ubg=ubg,
    )
    dw = np.asarray(sol["x"]).ravel()[:n] * scale
    dw = np.clip(dw, c.min_dwell_s, c.max_dwell_s)
    over = dw[groups].sum() + turn_time - c.budget_s
    if over > 0:  # IPOPT's tolerance: shave the excess off the longest dwell
        i = int(np.argmax(dw))
        dw[i] -= over / count[i]
    r1 = ratios(dw)
    if r1.max() >= r0.max():  # never return worse than the uniform start
        return kept
    return (dwells_in_ms(dw[groups], c.budget_s - turn_time), float(r0.max()), float(r1.max()))


def dwells_in_ms(dwells, available_s: float) -> list[float]:
    """Dwells rounded to the millisecond a sequence file holds, their sum within ``available_s``.

    Rounding each of ~60 dwells can add up to 30 ms; what overruns comes off the longest
    dwell (rounded down), so a design never lasts longer than its budget.
    """
    out = [round(float(d), 3) for d in dwells]
    excess = sum(out) - available_s
    if excess > 0:
        i = int(np.argmax(out))
        out[i] = math.floor((out[i] - excess) * 1000.0) / 1000.0
    return out


MAX_REFINE_DWELLS = 8  # IPOPT dwell variables besides the initial dwell


def dwell_groups(n_moves: int, repeats: int = 1) -> np.ndarray:
    """Which IPOPT variable each dwell is (initial dwell first, variable 0).

    One per motif move, tied across the ``repeats`` plays; a motif of more than
    :data:`MAX_REFINE_DWELLS` moves in that many contiguous blocks.
    """
    m = n_moves // repeats
    per_move = np.arange(m) if m <= MAX_REFINE_DWELLS else (np.arange(m) * MAX_REFINE_DWELLS) // m
    return np.concatenate([[0], 1 + np.tile(per_move, repeats)])


REFINE_FD_STEP = 1e-4  # central differences in dwells of 100 s units: 0.01 s


def _ratios_callback(ratios_many, n: int, scale: float):
    """The 21 ratios as a casadi function of ``n`` scaled dwells.

    Its Jacobian is central differences :data:`REFINE_FD_STEP` apart, all ``2 n``
    points in one call of ``ratios_many`` (batched: under GM one fold carries them).
    Truncation ~ step^2 x the third derivative (~1e-8 of a ratio); rounding ~1e-16 / 1e-4.
    """

    def value(x):
        return ratios_many(x[None] * scale)[0]

    def jacobian(x):
        steps = REFINE_FD_STEP * np.eye(n)
        r = ratios_many(np.vstack([x + steps, x - steps]) * scale)
        # A ratio that is infinite on both sides (a parameter not estimable there) has no slope to
        # give: zero, rather than the nan of inf - inf.
        with np.errstate(invalid="ignore"):
            slope = (r[:n] - r[n:]).T / (2.0 * REFINE_FD_STEP)
        return np.where(np.isfinite(slope), slope, 0.0)

    return ipopt.function("ratios", n, P.N_PARAMS, value, jacobian)
