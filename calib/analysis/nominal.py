"""The error-free trajectory of a sequence and the Fisher information along it.

The analyser (:mod:`calib.analysis.observability`) and the estimator both need
what a sequence observes when nothing disturbs it: the analyser to predict,
the estimator to decide, as the analyser does, which parameters a
rank-deficient run can estimate (a run's own trajectory is bent by the
errors it has not yet estimated, which turns nearly-null directions).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from calib.model.optional_terms import NONE as NO_EXTRAS, OptionalTerms
from calib.nav.jacobian import MOVE_STEP_S, ObservationGrid, Trajectory, observation_jacobian, state_matrix
from calib.nav.site import Site
from calib.nav.transform import rotvec_to_dcm
from calib.noise.gm_filter import bias_turns, gm_start_covariance, gram_one, nav_table
from calib.noise.profiles import NoiseProfile
from calib.noise.whitening import (
    filter_blocks,
    gm_interval_arrays,
    noise_model,
    velocity_transitions,
    whiten,
    whiten_batch,
)
from calib.sequence.definition import Sequence, nominal_attitude, timeline
from calib.sequence.kinematics import SimConfig, true_increments


@dataclass(frozen=True)
class NominalRun(Trajectory):
    """The error-free trajectory of a sequence, sampled for the linear model.

    Observation intervals are the estimator's while turning (``MOVE_STEP_S``)
    and ``ANALYSIS_REST_STEP_S`` at rest. At rest the attitude is constant, so
    a few sub-samples per interval give the moments exactly but for the
    ``tau^2`` weighting of a term that is itself ``(omega_ie T)^2`` small;
    while turning, sub-samples are at most ``FLIP_SUBSAMPLE_DEG`` apart, so
    the mid-sample attitude is good to ``(0.5 deg)^2 / 8 ~ 1e-5``. Its sample boundaries
    ``time_nav`` start at 0.
    """


ANALYSIS_REST_STEP_S = 5.0  # at rest; 1 s (the estimator's) changes no sigma by more than 0.2 %
REST_SUBSAMPLES = 4
FLIP_SUBSAMPLE_DEG = 0.5


def nominal_samples(tl) -> tuple[np.ndarray, np.ndarray]:
    """Sample end times and observation bounds (indices into ``[0] + times``) of a timeline."""
    times, bounds = [np.zeros(1)], [0]
    n = 0
    for k, (t0, t1, rate) in enumerate(zip(tl.t0, tl.t1, tl.rate, strict=True)):
        step = ANALYSIS_REST_STEP_S if rate == 0.0 else MOVE_STEP_S
        m = max(1, int(round((t1 - t0) / step)))
        sub = (
            REST_SUBSAMPLES
            if rate == 0.0
            else max(1, int(math.ceil(abs(math.degrees(rate)) * (t1 - t0) / m / FLIP_SUBSAMPLE_DEG)))
        )
        edges = np.linspace(t0, t1, m * sub + 1)[1:]
        edges[-1] = t1
        ends = sub * np.arange(1, m + 1)
        if rate == 0.0 and k > 0 and tl.rate[k - 1] != 0.0 and edges[0] > t0 + MOVE_STEP_S:
            # The estimator's turning intervals run a few samples into the next rest, so a
            # velocity step at a flip's stop (lever arms) is seen over ~MOVE_STEP_S, not a
            # whole rest interval: split one such interval off here too.
            edges = np.concatenate([[t0 + MOVE_STEP_S], edges])
            ends = np.concatenate([[1], ends + 1])
        times.append(edges)
        bounds.extend(n + ends)
        n += len(edges)
    return np.concatenate(times), np.array(bounds)


def nominal_run(seq: Sequence, site: Site, setup_rotvec) -> NominalRun:
    """The nominal trajectory of one mounting, sampled as the analyser samples it."""
    tl = timeline(seq)
    R = rotvec_to_dcm(np.asarray(setup_rotvec, dtype=float))
    cfg = SimConfig(latitude_rad=site.latitude_rad, gravity_mps2=site.gravity_mps2)
    t_nav, bounds = nominal_samples(tl)
    _, dtheta, dv = true_increments(tl, R, cfg, time_s=t_nav[1:])
    C = np.einsum("ij,njk->nik", R, nominal_attitude(tl, t_nav))
    return NominalRun(t_nav, C, dtheta, dv, ObservationGrid(bounds))


@functools.lru_cache(maxsize=64)
def _noise(T_bytes: bytes, site: Site, profile: NoiseProfile, C_bytes: bytes | None = None):
    """Whitening of an interval pattern (cached): see :func:`noise_along`."""
    C = None if C_bytes is None else np.frombuffer(C_bytes).reshape(-1, 3, 3)
    return noise_model(state_matrix(site), np.frombuffer(T_bytes), profile, C_b_n=C)


def noise_along(
    time_nav: np.ndarray, C_b_n: np.ndarray, bounds: np.ndarray, site: Site, profile: NoiseProfile
):
    """The noise model of a trajectory's intervals.

    White noise depends only on the interval lengths, so every mounting of a
    sequence shares one (cached) model. With Gauss-Markov bias instability the
    weights also depend on the attitude of each interval (its middle sample
    boundary): :func:`calib.analysis.worst_case.analyze_tolerance` then evaluates every mounting along
    its own trajectory instead of through the mounting basis.
    """
    T = np.diff(time_nav[bounds])
    C = None
    if profile.has_gauss_markov:
        C = np.ascontiguousarray(C_b_n[(bounds[:-1] + bounds[1:]) // 2]).tobytes()
    return _noise(T.tobytes(), site, profile, C)


def information_along(
    nom: NominalRun, profile: NoiseProfile, site: Site, extras: OptionalTerms = NO_EXTRAS
) -> np.ndarray:
    """Fisher information (24 + e square, SI) of the shared model along one trajectory."""
    noise = noise_along(nom.time_nav, nom.C_b_n, nom.grid.bounds, site, profile)
    H = observation_jacobian(nom, site, noise.Phi_vv, extras)
    Hw = whiten(noise.whitener, H).reshape(-1, H.shape[-1])
    return Hw.T @ Hw


def information_one(
    nom: NominalRun, profile: NoiseProfile, site: Site, extras: OptionalTerms = NO_EXTRAS
) -> np.ndarray:
    """:func:`information_along` of one trajectory under a GM profile, the filter in nav-frame coordinates.

    The same Jacobian; the noise filter of :mod:`calib.noise.gm_filter` (a handful of
    interval models shared by every interval, the bias coordinates turned between
    them), compiled (:func:`calib.noise.gm_filter.gram_one`): the same information to
    rounding at a fraction of the cost, for what evaluates one mounting at a time (a
    design's screen at the nominal mounting).
    """
    A = state_matrix(site)
    bounds = nom.grid.bounds
    T = np.diff(nom.time_nav[bounds])
    Phi_vv = velocity_transitions(A, T, profile)
    H = observation_jacobian(nom, site, Phi_vv, extras, compiled=True)
    turns, turning = bias_turns(nom.C_b_n[(bounds[:-1] + bounds[1:]) // 2])
    return gram_one(nav_table(A, T, profile), turns, turning, H, gm_start_covariance(profile))


BATCH_INTERVALS = 1024  # intervals of noise model held per mounting (~2.4 MB each)


def same_grid(noms: list[NominalRun]) -> bool:
    """Whether trajectories share their sample times and observation intervals.

    True for every mounting of one sequence (:func:`nominal_samples` reads only the
    timeline), checked rather than assumed before their noise filters are batched.
    """
    first = noms[0]
    return all(
        np.array_equal(n.grid.bounds, first.grid.bounds) and np.array_equal(n.time_nav, first.time_nav)
        for n in noms[1:]
    )


def information_along_many(
    noms: list[NominalRun], profile: NoiseProfile, site: Site, extras: OptionalTerms = NO_EXTRAS
) -> np.ndarray:
    """:func:`information_along` of several trajectories of one sequence, (M, n, n).

    With Gauss-Markov bias each mounting has its own noise filter, a Riccati
    recursion over every interval: run once over the shared interval grid with
    the mountings on a batch axis (:func:`calib.noise.whitening.whiten_batch`, the same
    arithmetic), ``BATCH_INTERVALS`` intervals of noise model at a time. The
    observation columns of all ``M`` are held, (K, M, 3, n): callers bound ``M``.
    Without GM, or if the grids differ, each is evaluated on its own.
    """
    if not profile.has_gauss_markov or not same_grid(noms):
        return np.array([information_along(n, profile, site, extras) for n in noms])
    A = state_matrix(site)
    bounds, time_nav = noms[0].grid.bounds, noms[0].time_nav
    T = np.diff(time_nav[bounds])
    Phi_vv = velocity_transitions(A, T, profile)
    X = np.stack([observation_jacobian(n, site, Phi_vv, extras) for n in noms], axis=1)
    mid = (bounds[:-1] + bounds[1:]) // 2
    C_mid = [n.C_b_n[mid] for n in noms]
    M, c = len(noms), X.shape[-1]
    P = state = None
    for k0 in range(0, len(T), BATCH_INTERVALS):
        part = slice(k0, k0 + BATCH_INTERVALS)
        models = [gm_interval_arrays(A, T[part], profile, C[part]) for C in C_mid]
        if P is None:  # as calib.noise.whitening.whitener's default P0: phi unknown, biases stationary
            s = models[0][0].shape[-1] - 3
            P = np.zeros((M, s, s))
            P[:, 3:, 3:] = models[0][2]
            state = np.zeros((M, s, c))
        blocks = filter_blocks(
            np.stack([m[0] for m in models], axis=1), np.stack([m[1] for m in models], axis=1)
        )
        assert state is not None  # allocated with P
        _, P, state = whiten_batch(blocks, X[part], P, state, out=X[part])
    # Each mounting's Gram matrix as information_along forms it (one product over the
    # whole run, not summed block by block): the direct search's forward differences
    # over 1e-3 deg steps would turn a 1e-15 rounding difference into another path.
    out = np.empty((M, c, c))
    for m in range(M):
        Hw = np.ascontiguousarray(X[:, m]).reshape(-1, c)
        out[m] = Hw.T @ Hw
    return out


BATCH_MOUNTINGS = 9  # mountings per pass of the GM noise filter: the 27 box points in 3 passes


def mounting_informations(
    seq: Sequence,
    profile: NoiseProfile,
    site: Site,
    rotvecs: list,
    extras: OptionalTerms = NO_EXTRAS,
    batch: int = BATCH_MOUNTINGS,
) -> list[np.ndarray]:
    """Fisher information of each mounting, evaluated along its own nominal trajectory.

    For what the mounting basis (:mod:`calib.analysis.mounting`) does not hold: Gauss-Markov
    bias instability and the optional terms. ``batch`` mountings share a pass of the
    noise filter (:func:`information_along_many`); ``batch=1`` evaluates each on its
    own (:func:`information_along`), the reference the tests hold the batches to.
    """
    rotvecs = list(rotvecs)
    size = max(1, batch)
    out: list[np.ndarray] = []
    for part in (rotvecs[i : i + size] for i in range(0, len(rotvecs), size)):
        noms = [nominal_run(seq, site, rv) for rv in part]
        if batch > 1:
            out.extend(information_along_many(noms, profile, site, extras))
        else:
            out.extend(information_along(n, profile, site, extras) for n in noms)
    return out
