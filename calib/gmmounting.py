"""The mounting basis under Gauss-Markov bias instability: any mounting's exact information fast.

Under white noise a sequence's whitened basis (:mod:`calib.mounting`) serves every
mounting. With GM bias instability the whitening filter itself depends on the
mounting (the biases are body-fixed, the filter sees them through ``R C_nom``),
so no one whitened basis serves them all; but the *unwhitened* basis still does:
``H(R) = X A(R)`` with the same 63-term weights (:func:`calib.mounting.combination`),
and the filter of mounting ``R`` differs from the nominal one only in how its
bias coordinates turn between intervals (:mod:`calib.gmfilter`). So one
pass over the intervals filters the ``H`` of many mountings at once, built from
``X`` without a trajectory of their own (:func:`informations`, the exact
information).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from . import earth
from . import params as P
from .extras import Extras
from .gmfilter import bias_turns, gram_pass, mounted_turns, nav_table
from .jacobian import extra_inputs, observation_matrix, propagate, sample_layout, state_matrix
from .mounting import CHUNK_INTERVALS, N_BASIS, basis_chunks, basis_weights, combination
from .noise import velocity_transitions
from .nominal import nominal_run, nominal_samples
from .profiles import NoiseProfile
from .sequence import Sequence, nominal_attitude, timeline
from .transform import rotvec_to_dcm


@dataclass(frozen=True)
class GmBasis:
    """A sequence's unwhitened mounting basis and its navigation-frame GM filter.

    ``X`` holds the kept basis columns and phi0's of ``H`` for every interval
    (:func:`calib.mounting.basis_chunks`); ``F``, ``Q`` and ``index`` the distinct
    interval models (:func:`calib.gmfilter.nav_table`); ``turns`` the nominal
    attitude's turn between consecutive intervals (:func:`calib.gmfilter.bias_turns`),
    exactly the identity where ``turning`` is False.
    """

    X: np.ndarray  # (K, 3, n + 3)
    column_basis: np.ndarray  # (n,) int
    column_param: np.ndarray  # (n,) int
    omega_ie_n: np.ndarray
    f_n: np.ndarray
    F: np.ndarray  # (u, 12, 9)
    Q: np.ndarray  # (u, 12, 12)
    index: np.ndarray  # (K,) int
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


@functools.lru_cache(maxsize=2)  # ~100 MB for a 30-minute sequence: the last two analysed
def gm_basis(seq: Sequence, profile: NoiseProfile, latitude_rad: float, height_m: float = 0.0) -> GmBasis:
    """Build (and cache) the :class:`GmBasis` of a sequence under a GM profile."""
    g = earth.gravity(latitude_rad, height_m)
    A = state_matrix(latitude_rad, g)
    tl = timeline(seq)
    t_nav, bounds = nominal_samples(tl)
    T = np.diff(t_nav[bounds])
    Phi_vv = velocity_transitions(A, T, profile)
    chunks = list(basis_chunks(seq, latitude_rad, height_m, Phi_vv))
    keep = chunks[-1][2]
    C = nominal_attitude(tl, t_nav)[(bounds[:-1] + bounds[1:]) // 2]
    turning = np.r_[False, np.any(C[1:] != C[:-1], axis=(1, 2))]
    turns = bias_turns(C)
    turns[~turning] = np.eye(3)  # the same attitude: the identity, exactly
    F, Q, index = nav_table(A, T, profile)
    return GmBasis(
        X=np.concatenate([X for _, X, _ in chunks]),
        column_basis=keep // P.N_PARAMS,
        column_param=keep % P.N_PARAMS,
        omega_ie_n=earth.omega_ie_n(latitude_rad),
        f_n=earth.specific_force_n(g),
        F=F,
        Q=Q,
        index=index,
        turns=turns,
        turning=turning,
        P0=np.diag(np.repeat([0.0, profile.gyro_gm_sigma**2, profile.accel_gm_sigma**2], 3)),
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
    for k0 in range(0, len(basis.X), CHUNK_INTERVALS):
        part = slice(k0, k0 + CHUNK_INTERVALS)
        X = columns(basis.X[part])
        if state is None:
            state = np.zeros((len(R), s, X.shape[-1]))
        turns = mounted_turns(basis.turns[part], R)
        g, P_, state = gram_pass(
            basis.F, basis.Q, basis.index[part], turns, basis.turning[part], X, P_, state
        )
        gram = g if gram is None else gram + g
    assert gram is not None
    return 0.5 * (gram + gram.transpose(0, 2, 1))


def informations(basis: GmBasis, rotvecs: list, extra: np.ndarray | None = None) -> np.ndarray:
    """The exact Fisher information (M, 24 [+ e], ...) of each mounting, in one pass of the filter.

    ``H`` of a mounting is ``X A(R)`` (:func:`calib.mounting.combination`), whose one
    non-zero per row is a basis weight: the basis laid out (rows, parameter, term)
    times the weights of all mountings is one product, 21 x fewer operations than
    ``X A(R)`` mounting by mounting. ``extra`` (K, M, 3, e), the optional terms'
    columns of each mounting (:func:`extra_columns`), are appended after phi0's.
    """
    W = np.array(
        [
            basis_weights(rotvec_to_dcm(np.asarray(rv, dtype=float)), basis.omega_ie_n, basis.f_n)
            for rv in rotvecs
        ]
    )
    n = len(basis.column_basis)
    start = 0

    def columns(X):
        nonlocal start
        k = len(X)
        laid = np.zeros((k, 3, P.N_PARAMS, N_BASIS))
        laid[:, :, basis.column_param, basis.column_basis] = X[:, :, :n]
        H = (laid.reshape(-1, N_BASIS) @ W.T).reshape(k, 3, P.N_PARAMS, len(W)).transpose(0, 3, 1, 2)
        parts = [H, np.broadcast_to(X[:, None, :, n:], (k, len(W), 3, 3))]
        if extra is not None:
            parts.append(extra[start : start + k])
        start += k
        return np.concatenate(parts, axis=3)

    return whitened_grams(basis, rotvecs, columns)


def extra_columns(
    seq: Sequence, basis: GmBasis, latitude_rad: float, height_m: float, rotvecs: list, extras: Extras
) -> np.ndarray:
    """The optional terms' columns of ``H`` (K, M, 3, e), each mounting along its own trajectory.

    Their sensitivities are not in the mounting basis (polynomials of up to third
    degree in the mounting), so each mounting's moments come from its nominal
    trajectory (:func:`calib.jacobian.extra_inputs`, as :func:`calib.jacobian.observation_jacobian`
    forms them); the propagation, linear and column by column, is one recursion for
    all mountings.
    """
    g = earth.gravity(latitude_rad, height_m)
    inputs = []
    for rv in rotvecs:
        nom = nominal_run(seq, latitude_rad, height_m, rv)
        layout = sample_layout(nom.C_b_n, nom.time_nav, nom.grid)
        inputs.append(extra_inputs(nom.dtheta, nom.dv, layout, extras, latitude_rad, g))
    stacked = np.concatenate(inputs, axis=2)  # (K, 6, M e)
    S_v = propagate(stacked, basis.T, np.zeros((6, stacked.shape[-1])), latitude_rad, g)
    H = observation_matrix(S_v, basis.Phi_vv)
    return H.reshape(len(H), 3, len(rotvecs), extras.n).transpose(0, 2, 1, 3)
