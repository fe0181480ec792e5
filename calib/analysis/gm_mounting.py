"""The mounting basis under Gauss-Markov bias instability: any mounting's exact information fast.

Under white noise a sequence's whitened basis (:mod:`calib.analysis.mounting`) serves every
mounting. With GM bias instability the whitening filter itself depends on the
mounting (the biases are body-fixed, the filter sees them through ``R C_nom``),
so no one whitened basis serves them all; but the *unwhitened* basis still does:
``H(R) = X A(R)`` with the same 63-term weights (:func:`calib.analysis.mounting.combination`),
and the filter of mounting ``R`` differs from the nominal one only in how its
bias coordinates turn between intervals (:mod:`calib.noise.gm_filter`). So one
pass over the intervals filters the ``H`` of many mountings at once, built from
``X`` without a trajectory of their own (:func:`informations`, the exact
information). The optional terms' sensitivities are polynomials of the second degree
in the Earth rate and gravity seen in the body, so their columns too come from
moments built once (:func:`extra_basis`), weighted per mounting.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass

import numpy as np

from calib.model import params as P
from calib.model.optional_terms import NONE as NO_EXTRAS, OptionalTerms
from calib.nav import earth
from calib.nav.jacobian import ObservationGrid, propagate, sample_layout, state_matrix, step_model
from calib.nav.site import Site
from calib.nav.transform import rotvec_to_dcm
from calib.noise.gm_filter import (
    NavTable,
    bias_turns,
    gm_start_covariance,
    gram_pass,
    mounted_turns,
    nav_table,
)
from calib.noise.profiles import NoiseProfile
from calib.noise.whitening import velocity_transitions
from calib.sequence.definition import Sequence, nominal_attitude, timeline
from calib.sequence.kinematics import body_integrals

from .mounting import CHUNK_INTERVALS, N_BASIS, basis_chunks, basis_weights, combination
from .nominal import information_one, nominal_run, nominal_samples


@dataclass(frozen=True)
class GmBasis:
    """A sequence's unwhitened mounting basis and its navigation-frame GM filter.

    ``X`` holds the kept basis columns and phi0's of ``H`` for every interval, in
    chunks of ``CHUNK_INTERVALS`` intervals (:func:`calib.analysis.mounting.basis_chunks`: kept
    as they come, since one array of a 30-min run's ~200 MB cost more to allocate and
    fill than any use of it); ``table`` the distinct interval models and which one
    each interval has (:func:`calib.noise.gm_filter.nav_table`); ``turns`` the nominal
    attitude's turn between consecutive intervals (:func:`calib.noise.gm_filter.bias_turns`),
    exactly the identity where ``turning`` is False.
    """

    X: tuple[np.ndarray, ...]  # chunks (k, 3, n + 3), K intervals in all
    column_basis: np.ndarray  # (n,) int
    column_param: np.ndarray  # (n,) int
    omega_ie_n: np.ndarray
    f_n: np.ndarray
    table: NavTable  # the K intervals' models
    turns: np.ndarray  # (K, 3, 3)
    turning: np.ndarray  # (K,) bool
    P0: np.ndarray  # (9, 9) filter covariance at the start
    T: np.ndarray  # (K,) interval lengths, s
    Phi_vv: np.ndarray  # (K, 3, 3) velocity transitions
    duration_s: float
    profile: str

    def combination(self, rotvec) -> np.ndarray:
        """(n + 3, 24) map from the basis columns to ``H`` at a mounting."""
        return combination(rotvec, self.column_basis, self.column_param, self.omega_ie_n, self.f_n)


@functools.lru_cache(maxsize=2)  # ~200 MB for a 30-minute sequence: the last two analysed
def gm_basis(seq: Sequence, profile: NoiseProfile, site: Site) -> GmBasis:
    """Build (and cache) the :class:`GmBasis` of a sequence under a GM profile."""
    A = state_matrix(site)
    tl = timeline(seq)
    t_nav, bounds = nominal_samples(tl)
    T = np.diff(t_nav[bounds])
    Phi_vv = velocity_transitions(A, T, profile)
    chunks = list(basis_chunks(seq, site, Phi_vv, compiled=True))
    keep = chunks[-1][2]
    turns, turning = bias_turns(nominal_attitude(tl, t_nav)[(bounds[:-1] + bounds[1:]) // 2])
    return GmBasis(
        X=tuple(X for _, X, _ in chunks),
        column_basis=keep // P.N_PARAMS,
        column_param=keep % P.N_PARAMS,
        omega_ie_n=site.omega_ie_n,
        f_n=earth.specific_force_n(site.gravity_mps2),
        table=nav_table(A, T, profile),
        turns=turns,
        turning=turning,
        P0=gm_start_covariance(profile),
        T=T,
        Phi_vv=Phi_vv,
        duration_s=seq.duration_s,
        profile=profile.name,
    )


def whitened_grams(basis: GmBasis, rotvecs: list, columns) -> np.ndarray:
    """Gram matrices of each mounting's columns whitened by its own filter, (M, c, c).

    One pass over the intervals, the mountings on a batch axis. ``columns(X_chunk)``
    maps a chunk of the basis, (k, 3, n + 3), to the columns to whiten per mounting,
    (k, M, 3, c).
    """
    R = np.array([rotvec_to_dcm(np.asarray(rv, dtype=float)) for rv in rotvecs])
    s = len(basis.P0)
    P_ = np.array(np.broadcast_to(basis.P0, (len(R), s, s)))
    state = gram = None
    k0 = 0
    for chunk in basis.X:
        part = slice(k0, k0 + len(chunk))
        k0 += len(chunk)
        X = columns(chunk)
        if state is None:
            state = np.zeros((len(R), s, X.shape[-1]))
        turns = mounted_turns(basis.turns[part], R)
        g, P_, state = gram_pass(basis.table.part(part), turns, basis.turning[part], X, P_, state)
        gram = g if gram is None else gram + g
    assert gram is not None
    return 0.5 * (gram + gram.transpose(0, 2, 1))


def informations(basis: GmBasis, rotvecs: list, extra: OptionalTermsBasis | None = None) -> np.ndarray:
    """The exact Fisher information (M, 24 [+ e], ...) of each mounting, in one pass of the filter.

    ``H`` of a mounting is ``X A(R)`` (:func:`calib.analysis.mounting.combination`), whose one
    non-zero per row is a basis weight: the basis laid out (rows, parameter, term)
    times the weights of all mountings is one product, 21 x fewer operations than
    ``X A(R)`` mounting by mounting. With ``extra`` (:func:`extra_basis`) the optional
    terms' columns of each mounting (:func:`extra_chunks`) are appended after phi0's.
    """
    W = np.array(
        [
            basis_weights(rotvec_to_dcm(np.asarray(rv, dtype=float)), basis.omega_ie_n, basis.f_n)
            for rv in rotvecs
        ]
    )
    n = len(basis.column_basis)
    chunks = extra_chunks(basis, extra, rotvecs) if extra is not None else None

    def columns(X):
        k = len(X)
        laid = np.zeros((k, 3, P.N_PARAMS, N_BASIS))
        laid[:, :, basis.column_param, basis.column_basis] = X[:, :, :n]
        H = (laid.reshape(-1, N_BASIS) @ W.T).reshape(k, 3, P.N_PARAMS, len(W)).transpose(0, 3, 1, 2)
        parts = [H, np.broadcast_to(X[:, None, :, n:], (k, len(W), 3, 3))]
        if chunks is not None:
            parts.append(next(chunks))
        return np.concatenate(parts, axis=3)

    return whitened_grams(basis, rotvecs, columns)


# The mounting's monomials the optional terms' sensitivities are polynomials in: with
# u = R' omega_ie_n and v = R' f_n (the Earth rate and gravity in the body),
# [1, u, u (x) u, v, v (x) v, u (x) v] (:func:`_monomials`).
_U, _UU, _V, _VV, _UV = slice(1, 4), slice(4, 13), slice(13, 16), slice(16, 25), slice(25, 34)


def _monomials(R: np.ndarray, omega_ie_n: np.ndarray, f_n: np.ndarray) -> np.ndarray:
    """The monomials (M, 34) of mountings ``R`` (M, 3, 3), in the order of ``_U`` .. ``_UV``."""
    u = np.einsum("mab,a->mb", R, omega_ie_n)
    v = np.einsum("mab,a->mb", R, f_n)

    def outer(x, y):
        return np.einsum("mc,md->mcd", x, y).reshape(len(R), 9)

    return np.hstack([np.ones((len(R), 1)), u, outer(u, u), v, outer(v, v), outer(u, v)])


def _skew_rows(d: np.ndarray) -> np.ndarray:
    """``[d x]`` of each row of ``d`` (n, 3) -> (n, 3, 3)."""
    out = np.zeros(d.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -d[..., 2], d[..., 1], -d[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = d[..., 2], -d[..., 1], d[..., 0]
    return out


def _rate_steps(x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``x_j / h_j - x_{j-1} / h_{j-1}`` along the samples, the first zero (as in ``lever_matrix``)."""
    w = x / h.reshape((-1,) + (1,) * (x.ndim - 1))
    return np.diff(w, axis=0, prepend=w[:1])


def _sensitivity_coefficients(
    extras: OptionalTerms, flip: np.ndarray, E: np.ndarray, C_mid: np.ndarray, h: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`calib.model.optional_terms.dv_sensitivity` of every mounting as polynomials in its monomials.

    A mounting ``R`` sees ``dtheta = flip + E u``, ``dv = E v`` and the Earth's turn
    ``C_mid' u h`` (:func:`calib.sequence.kinematics.true_increments`,
    :func:`calib.model.optional_terms.earth_turn`),
    so each term's per-sample sensitivity is a polynomial of degree two in ``u`` and
    ``v``: the lever arm's in ``u`` (the centripetal term is quadratic in the rate),
    k2's in ``v``, the time offset's bilinear. Returns, per group,
    ``(columns, monomials, D)``: the group's columns among the extras', the monomials
    it uses and their coefficients ``D`` (n, 3 accelerometers, columns, monomials).
    """
    n, hh = len(h), h[:, None, None]
    eye = np.eye(3)
    parts = []
    if "lever-arm" in extras.groups:
        # A r with A = (t t' - |t|^2 I) / h + [d x] (extras.lever_matrix), t = flip + E u.
        A = np.zeros((n, 3, 3, 13))
        t = flip
        A[..., 0] = (np.einsum("ni,nm->nim", t, t) - np.einsum("n,im->nim", np.sum(t * t, 1), eye)) / hh
        A[..., 0] += _skew_rows(_rate_steps(t, h))
        tE = np.einsum("ni,nic->nc", t, E)
        hc = hh[..., None]
        A[..., _U] = (np.einsum("ni,nmc->nimc", t, E) + np.einsum("nic,nm->nimc", E, t)) / hc
        A[..., _U] -= 2.0 * np.einsum("nc,im->nimc", tE, eye) / hc
        A[..., _U] += _skew_rows(_rate_steps(E, h).transpose(0, 2, 1)).transpose(0, 2, 3, 1)
        EE = np.einsum("nic,nid->ncd", E, E)
        A[..., _UU] = (
            (np.einsum("nic,nmd->nimcd", E, E) - np.einsum("ncd,im->nimcd", EE, eye)) / hh[..., None, None]
        ).reshape(n, 3, 3, 9)
        D = np.zeros((n, 3, 9, 13))
        for i in range(3):
            D[:, i, 3 * i : 3 * i + 3] = A[:, i]
        lever = extras.index("lever-arm")
        parts.append((np.arange(lever.start, lever.stop), np.arange(_UU.stop), D))
    if "k2" in extras.groups:
        # k2_i (E v)_i^2 / h.
        D = np.zeros((n, 3, 3, 9))
        for i in range(3):
            D[:, i, i] = np.einsum("nc,nd->ncd", E[:, i], E[:, i]).reshape(n, 9) / h[:, None]
        k2 = extras.index("k2")
        parts.append((np.arange(k2.start, k2.stop), np.r_[_VV], D))
    if "time-offset" in extras.groups:
        # (dtheta - Earth's turn) x dv / h = (flip + G u) x E v / h, G = E - C_mid' h.
        G = E - C_mid.transpose(0, 2, 1) * hh
        D = np.zeros((n, 3, 1, 12))
        D[:, :, 0, :3] = np.cross(flip[:, :, None], E, axis=1) / hh
        D[:, :, 0, 3:] = np.cross(G[:, :, :, None], E[:, :, None, :], axis=1).reshape(n, 3, 9) / hh
        parts.append((np.r_[extras.index("time-offset").start], np.r_[_V, _UV], D))
    return parts


@dataclass(frozen=True)
class OptionalTermsBasis:
    """The optional terms' interval moments for every mounting, as :class:`GmBasis` holds the 21's.

    ``parts`` per group: its columns among the extras', the monomials it uses
    (:func:`_monomials`) and ``moments`` (K, 2, columns, 3 * monomials): the moments
    ``sum tau^w C_nom[b] D`` (w = 0, 1) of each interval, row ``b`` of the nominal
    attitude (and monomial ``u``: index ``b * monomials + u``). A mounting ``R`` places
    row ``b`` on navigation axis ``a`` with weight ``R[a, b]`` and each monomial with
    its value.
    """

    parts: tuple
    n: int
    site: Site


def _interval_moments(x: np.ndarray, starts: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """``sum tau^w x`` (w = 0, 1) over the samples of each interval, (K, 2, ...).

    One sparse product (a row per interval and weight): ``np.add.reduceat`` of
    these wide rows costs several times more.
    """
    from scipy import sparse  # lazy: 0.26 s to import, and only the optional terms need it

    n, K = len(x), len(starts)
    interval = np.repeat(np.arange(K), np.diff(np.append(starts, n)))
    rows = np.concatenate([2 * interval, 2 * interval + 1])
    values = np.concatenate([np.ones(n), tau])
    S = sparse.csr_matrix((values, (rows, np.tile(np.arange(n), 2))), shape=(2 * K, n))
    return (S @ x.reshape(n, -1)).reshape((K, 2) + x.shape[1:])


@functools.lru_cache(maxsize=2)
def extra_basis(seq: Sequence, site: Site, extras: OptionalTerms) -> OptionalTermsBasis:
    """Build (and cache) the :class:`OptionalTermsBasis` of a sequence: one pass over its samples."""
    tl = timeline(seq)
    t_nav, bounds = nominal_samples(tl)
    flip, E = body_integrals(tl, t_nav[1:])
    L = sample_layout(nominal_attitude(tl, t_nav), t_nav, ObservationGrid(bounds))
    parts = []
    for columns, monomials, D in _sensitivity_coefficients(extras, flip, E, L.C_mid, L.h):
        Y = np.einsum("nbi,nicu->ncbu", L.C_mid, D).reshape(len(D), len(columns), -1)
        parts.append((columns, monomials, _interval_moments(Y, L.starts, L.tau)))
    return OptionalTermsBasis(tuple(parts), extras.n, site)


def extra_chunks(basis: GmBasis, xb: OptionalTermsBasis, rotvecs: list):
    """The optional terms' columns of ``H`` of mountings, ``CHUNK_INTERVALS`` intervals at a time.

    Yields (k, M, 3, e). Each mounting's moments are its weights on the basis
    moments (no trajectory of its own: the sensitivities of
    :func:`calib.nav.jacobian.extra_inputs` along it, the arithmetic reordered); the
    propagation, linear and column by column, is one recursion for all mountings,
    its state carried from chunk to chunk.
    """
    R = np.array([rotvec_to_dcm(np.asarray(rv, dtype=float)) for rv in rotvecs])
    mono = _monomials(R, basis.omega_ie_n, basis.f_n)
    M, e = len(R), xb.n
    G = step_model(xb.site).extra_map
    # Each mounting's weight of basis moment (b, u) on navigation axis a: R[a, b] times monomial u.
    weights = [
        np.einsum("mab,mu->buam", R, mono[:, monomials]).reshape(3 * len(monomials), 3 * M)
        for _, monomials, _ in xb.parts
    ]
    S = np.zeros((6, e * M))
    for k0 in range(0, len(basis.T), CHUNK_INTERVALS):
        part = slice(k0, k0 + CHUNK_INTERVALS)
        k = len(basis.T[part])
        moments = np.zeros((k, 2, 3, e, M))
        for (columns, _, basis_moments), W in zip(xb.parts, weights, strict=True):
            mom = basis_moments[part]  # one 2-D product: a stacked matmul is ~10 x slower here
            weighted = (mom.reshape(-1, mom.shape[-1]) @ W).reshape(k, 2, len(columns), 3, M)
            moments[..., columns, :] = weighted.transpose(0, 1, 3, 2, 4)
        inputs = G @ moments.reshape(k, 6, e * M)
        S_v, S = propagate(inputs, basis.T[part], S, xb.site, return_final=True, compiled=True)
        H = S_v[1:] - basis.Phi_vv[part] @ S_v[:-1]  # calib.nav.jacobian.observation_matrix
        yield H.reshape(k, 3, e, M).transpose(0, 3, 1, 2)


def extra_columns(basis: GmBasis, xb: OptionalTermsBasis, rotvecs: list) -> np.ndarray:
    """The optional terms' columns of ``H`` (K, M, 3, e) of mountings (:func:`extra_chunks`, whole)."""
    return np.concatenate(list(extra_chunks(basis, xb, rotvecs)))


def nominal_information(
    seq: Sequence, profile: NoiseProfile, site: Site, extras: OptionalTerms = NO_EXTRAS
) -> np.ndarray:
    """The nominal mounting's information alone under a GM profile (as :func:`~.nominal.information_one`).

    What a design's screen asks of every candidate: the same information as the
    direct evaluation to rounding, at about half its cost.
    """
    return information_one(nominal_run(seq, site, np.zeros(3)), profile, site, extras)


def box_points(tolerance_deg: float) -> list:
    """The 27 corners, edge and face centres and centre of the box (rotation vectors, rad)."""
    levels = (-tolerance_deg, 0.0, tolerance_deg)
    return [np.radians(p) for p in itertools.product(levels, levels, levels)]


@functools.lru_cache(maxsize=1)
def box_informations(
    seq: Sequence, profile: NoiseProfile, site: Site, tolerance_deg: float, extras: OptionalTerms = NO_EXTRAS
) -> np.ndarray:
    """The informations (28, 24 + e, 24 + e) of the nominal mounting and the 27 box points.

    Under a GM profile, in one pass of the filter over the GM basis
    (:func:`calib.analysis.gm_mounting.informations`), the optional terms' columns after phi0's.
    The filter whitens column by column, so the leading 24 x 24 block is the
    information without the terms: :func:`calib.analysis.worst_case.analyze_tolerance` and
    :func:`calib.analysis.worst_case.analyze_extras` of the same terms share this pass (the last one is kept).
    """
    basis = gm_basis(seq, profile, site)
    xb = extra_basis(seq, site, extras) if extras.n else None
    infos = informations(basis, [np.zeros(3)] + box_points(tolerance_deg), xb)
    infos.setflags(write=False)
    return infos


def release_caches() -> None:
    """Let go of the cached bases and box informations (a 30-min sequence's are ~0.3 GB).

    For a process that analyses each sequence once (a design's exact-scoring worker, kept
    for all its rounds): what the caches hold serves no later job there.
    """
    gm_basis.cache_clear()
    extra_basis.cache_clear()
    box_informations.cache_clear()
