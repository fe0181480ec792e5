"""The Gauss-Markov noise filter of many mountings at once, in navigation-frame bias coordinates.

:func:`calib.noise.whitening.whitener` carries the GM biases in the body frame, where each
interval's model is ``R_k' Phi_nav R_k`` with ``R_k = diag(I, I, C_k, C_k)``: one
12 x 12 model per interval and per mounting. The same filter written in each
interval's *navigation-frame* bias coordinates, ``s~ = R_k s``, predicts with
``Phi_nav`` and ``Q_nav`` themselves, which depend on the interval's length only
(:func:`calib.noise.whitening.gm_interval_nav`): a handful of distinct models shared by
every interval and every mounting. Between intervals the bias coordinates turn
by ``C_k C_{k-1}'``; for base mounting ``R`` (``C_k = R C_nom,k``) that is
``R D_k R'``, with ``D_k = C_nom,k C_nom,k-1'`` of the sequence. A change of the
state's coordinates leaves the innovations and their covariances as they are,
so the information is the body-frame filter's, to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .profiles import NoiseProfile
from .whitening import filter_order, gm_bias_covariance, gm_interval_nav, rotations

STATES = 9  # [phi, b_g, b_a]: phi, then body-fixed 3-vectors (every one turns with the body)


@dataclass(frozen=True)
class NavTable:
    """The distinct navigation-frame GM models of a run's intervals, and which one each has.

    Attributes
    ----------
    F : ndarray, shape (u, 12, 9)
        ``[F_ss; F_vs]`` of each distinct interval length: the rows of the filter
        state, then of the observed velocity; the columns of the filter state.
    Q : ndarray, shape (u, 12, 12)
        The noise covariance, same order.
    index : ndarray, shape (K,) of int
        Which model each interval has.
    """

    F: np.ndarray
    Q: np.ndarray
    index: np.ndarray

    def part(self, intervals: slice) -> NavTable:
        """The table of some of the intervals (the models shared, the index cut)."""
        return NavTable(self.F, self.Q, self.index[intervals])


def nav_table(A: np.ndarray, T: np.ndarray, profile: NoiseProfile) -> NavTable:
    """The distinct navigation-frame GM models of a run's intervals, in the filter's order."""
    key = np.ascontiguousarray(A, dtype=float).tobytes()
    keys, index = np.unique(np.round(np.asarray(T, dtype=float), 6), return_inverse=True)
    order = filter_order(STATES)
    F, Q = [], []
    for t in keys:
        Phi, q = gm_interval_nav(key, float(t), profile)
        F.append(Phi[order][:, order][:, :STATES])
        Q.append(q[order][:, order])
    return NavTable(np.array(F), np.array(Q), index)


def bias_turns(C_mid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``D_k = C_k C_{k-1}'`` (K, 3, 3) of the intervals' mid-point attitudes (polar factors), ``D_0 = I``.

    Returns ``(D, turning)``: ``turning`` (K,) marks the intervals whose attitude differs
    from the one before; the others' ``D`` is the identity exactly (the filter skips it).
    """
    C_mid = np.asarray(C_mid, dtype=float)
    turning = np.r_[False, np.any(C_mid[1:] != C_mid[:-1], axis=(1, 2))]
    R = rotations(C_mid)
    D = np.empty_like(R)
    D[0] = np.eye(3)
    D[1:] = R[1:] @ R[:-1].transpose(0, 2, 1)
    D[~turning] = np.eye(3)  # the same attitude: the identity, exactly
    return D, turning


def gm_start_covariance(profile: NoiseProfile) -> np.ndarray:
    """The filter covariance (9, 9) at a run's start: phi zero (an unknown of the fit), the
    biases at their stationary ``sigma^2 I`` (as :func:`calib.noise.whitening.whitener`).
    """
    P0 = np.zeros((STATES, STATES))
    P0[3:, 3:] = gm_bias_covariance(profile)
    return P0


def mounted_turns(D: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The bias turn ``R D_k R'`` of each interval (k, M, 3, 3) for mountings ``R`` (M, 3, 3)."""
    return R[None] @ D[:, None] @ R.transpose(0, 2, 1)[None]


# From this many mountings on, :func:`calib.noise.kernels.filter_mountings` (their covariances a few at a
# time) is faster than :func:`calib.noise.kernels.filter_columns` (one by one): measured over a 30-min
# run, 8 mountings 0.27 against 0.34 s, 4 mountings 0.25 against 0.19 s.
MOUNTINGS_AT_ONCE = 6


def gram_pass(
    table: NavTable,
    turns: np.ndarray,
    turning: np.ndarray,
    X: np.ndarray,
    P: np.ndarray,
    state: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Filter ``M`` mountings' columns over some intervals; their whitened Gram matrices.

    The recursion of :func:`calib.noise.whitening.whitener` and :func:`calib.noise.whitening.whiten`, in
    fewer products, compiled (:func:`calib.noise.kernels.filter_columns`, or
    :func:`calib.noise.kernels.filter_mountings` for many mountings): the gain and the inverse
    innovation covariance share their product with the innovations, and ``S^-1`` is
    formed in closed form.

    Parameters
    ----------
    table : NavTable
        :func:`nav_table` of these intervals (:meth:`NavTable.part` of a run's).
    turns : ndarray, shape (k, M, 3, 3)
        :func:`mounted_turns` of these intervals.
    turning : ndarray of bool, shape (k,)
        Whether an interval's turn differs from the identity (at rest it does not:
        its turn is skipped, as exact).
    X : ndarray, shape (k, M, 3, c)
        The observation columns of each mounting.
    P : ndarray, shape (M, s, s)
        The filter's covariance before the first interval (navigation-frame biases of
        the interval before it); ``s`` is 9 (``[phi, b_g, b_a]``) for the profiles'
        first-order Gauss-Markov biases, phi then body-fixed 3-vectors in general.
    state : ndarray, shape (M, s, c)
        The filter's state of the columns before the first interval.

    Returns
    -------
    gram : ndarray, shape (M, c, c)
        ``sum_k e_k' S_k^-1 e_k`` over these intervals, ``e_k`` the innovations: the
        whitened columns' Gram matrix (symmetric).
    P, state : ndarray
        After the last interval, to carry into the next ones.
    """
    from .kernels import (  # numba: the GM paths alone
        compiled_arg,
        filter_columns,
        filter_mountings,
    )

    n_k, M, _, c = X.shape
    state = np.array(state, dtype=float, order="C")  # copies the filter updates
    E = np.empty((M, n_k, 3, c))  # mounting-major: each mounting's rows one block for the product
    U = np.empty((M, n_k, 3, c))
    models = compiled_arg(table.F), compiled_arg(table.Q), compiled_arg(table.index, np.int64)
    columns = compiled_arg(turning, np.bool_), compiled_arg(X)
    if M >= MOUNTINGS_AT_ONCE:  # the mountings on the last axis of the turns and the covariance
        P = np.array(np.moveaxis(P, 0, -1), dtype=float, order="C")
        filter_mountings(*models, compiled_arg(np.moveaxis(turns, 1, -1)), *columns, P, state, E, U)
        P = np.moveaxis(P, -1, 0)
    else:
        P = np.array(P, dtype=float, order="C")
        filter_columns(*models, compiled_arg(turns), *columns, P, state, E, U)
    # sum_k e_k' S_k^-1 e_k of each mounting as one product over all its intervals.
    gram = E.reshape(M, -1, c).transpose(0, 2, 1) @ U.reshape(M, -1, c)
    return 0.5 * (gram + gram.transpose(0, 2, 1)), P, state


def gram_one(
    table: NavTable, turns: np.ndarray, turning: np.ndarray, X: np.ndarray, P: np.ndarray
) -> np.ndarray:
    """:func:`gram_pass` of one mounting over a whole run from a zero state: its Gram matrix (c, c).

    ``turns`` (K, 3, 3) and ``X`` (K, 3, c) are this mounting's; ``P`` (s, s) the
    covariance before the first interval.
    """
    s, c = table.F.shape[-1], X.shape[-1]
    gram, _, _ = gram_pass(table, turns[:, None], turning, X[:, None], P[None], np.zeros((1, s, c)))
    return gram[0]
