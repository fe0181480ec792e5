"""The Gauss-Markov noise filter of many mountings at once, in navigation-frame bias coordinates.

:func:`calib.noise.whitener` carries the GM biases in the body frame, where each
interval's model is ``R_k' Phi_nav R_k`` with ``R_k = diag(I, I, C_k, C_k)``: one
12 x 12 model per interval and per mounting. The same filter written in each
interval's *navigation-frame* bias coordinates, ``s~ = R_k s``, predicts with
``Phi_nav`` and ``Q_nav`` themselves, which depend on the interval's length only
(:func:`calib.noise.gm_interval_nav`): a handful of distinct models shared by
every interval and every mounting. Between intervals the bias coordinates turn
by ``C_k C_{k-1}'``; for base mounting ``R`` (``C_k = R C_nom,k``) that is
``R D_k R'``, with ``D_k = C_nom,k C_nom,k-1'`` of the sequence. A change of the
state's coordinates leaves the innovations and their covariances as they are,
so the information is the body-frame filter's, to rounding.
"""

from __future__ import annotations

import numpy as np

from .noise import filter_order, gm_interval_nav, rotations
from .profiles import NoiseProfile

STATES = 9  # [phi, b_g, b_a]: phi, then body-fixed 3-vectors (every one turns with the body)


def nav_table(
    A: np.ndarray, T: np.ndarray, profile: NoiseProfile
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct navigation-frame GM models of a run's intervals, in the filter's order.

    Returns
    -------
    F : ndarray, shape (u, 12, 9)
        ``[F_ss; F_vs]`` of each distinct interval length: the rows of the filter
        state, then of the observed velocity; the columns of the filter state.
    Q : ndarray, shape (u, 12, 12)
        The noise covariance, same order.
    index : ndarray, shape (K,) of int
        Which model each interval has.
    """
    key = np.ascontiguousarray(A, dtype=float).tobytes()
    keys, index = np.unique(np.round(np.asarray(T, dtype=float), 6), return_inverse=True)
    order = filter_order(STATES)
    F, Q = [], []
    for t in keys:
        Phi, q = gm_interval_nav(key, float(t), profile)
        F.append(Phi[order][:, order][:, :STATES])
        Q.append(q[order][:, order])
    return np.array(F), np.array(Q), index


def bias_turns(C_mid: np.ndarray) -> np.ndarray:
    """``D_k = C_k C_{k-1}'`` (K, 3, 3) of the intervals' mid-point attitudes (polar factors), ``D_0 = I``."""
    R = rotations(np.asarray(C_mid, dtype=float))
    D = np.empty_like(R)
    D[0] = np.eye(3)
    D[1:] = R[1:] @ R[:-1].transpose(0, 2, 1)
    return D


def mounted_turns(D: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The bias turn ``R D_k R'`` of each interval (k, M, 3, 3) for mountings ``R`` (M, 3, 3)."""
    return R[None] @ D[:, None] @ R.transpose(0, 2, 1)[None]


def turned_models(F: np.ndarray, index: np.ndarray, turns: np.ndarray) -> np.ndarray:
    """``F D`` (k, M, 12, 9) of intervals whose bias coordinates turn by ``turns`` (k, M, 3, 3) first."""
    F = np.broadcast_to(F[index][:, None], turns.shape[:2] + F.shape[1:])
    out = np.array(F)
    for j in range(3, F.shape[-1], 3):  # every body-fixed 3-vector of the state
        out[..., j : j + 3] = F[..., j : j + 3] @ turns
    return out


def _cofactor_index() -> tuple[np.ndarray, ...]:
    """Flat indices with ``C_ij = S[a] S[b] - S[c] S[d]`` the cofactors of a 3 x 3 matrix."""
    i, j = np.divmod(np.arange(9), 3)
    i1, i2, j1, j2 = (i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3
    return i1 * 3 + j1, i2 * 3 + j2, i1 * 3 + j2, i2 * 3 + j1


_COFACTOR = _cofactor_index()


def inverse_3(S: np.ndarray) -> np.ndarray:
    """Inverses of a batch of symmetric 3 x 3 matrices (M, 3, 3), in closed form (cofactors).

    Elementwise over the batch, in a few operations on it: a LAPACK call per matrix
    costs more than the arithmetic. Raises ``numpy.linalg.LinAlgError`` unless every
    determinant is positive (an innovation covariance is positive definite).
    """
    f = S.reshape(-1, 9)
    a, b, c, d = _COFACTOR
    C = f[:, a] * f[:, b] - f[:, c] * f[:, d]
    det = np.einsum("mi,mi->m", f[:, :3], C[:, :3])
    if not det.min() > 0.0:
        raise np.linalg.LinAlgError("innovation covariance is not positive definite")
    return (C / det[:, None]).reshape(S.shape)


def gram_pass(
    F: np.ndarray,
    Q: np.ndarray,
    index: np.ndarray,
    turns: np.ndarray,
    turning: np.ndarray,
    X: np.ndarray,
    P: np.ndarray,
    state: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Filter ``M`` mountings' columns over some intervals; their whitened Gram matrices.

    The recursion of :func:`calib.noise.whitener` and :func:`calib.noise.whiten`, in
    fewer products (each a loop over the mountings in C, a Python step per interval):
    the gain and the inverse innovation covariance share their product with the
    innovations, and ``S^-1`` is formed in closed form (:func:`inverse_3`).

    Parameters
    ----------
    F, Q, index : ndarray
        :func:`nav_table` of these intervals (``index`` into ``F`` and ``Q``).
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
        whitened columns' Gram matrix (symmetric to rounding).
    P, state : ndarray
        After the last interval, to carry into the next ones.
    """
    n_k, M, _, c = X.shape
    s = F.shape[-1]
    E = np.empty((n_k, M, 3, c))
    U = np.empty((n_k, M, 3, c))
    turned = np.flatnonzero(turning)
    FD = dict(zip(turned, turned_models(F, index[turned], turns[turned]), strict=True))
    B = np.zeros((M, s + 3, 3))  # [cross covariance; I]: times S^-1 it is [gain; S^-1]
    B[:, s:] = np.eye(3)
    for k in range(n_k):
        Fk = FD[k] if turning[k] else F[index[k]]
        J = Fk @ P @ np.swapaxes(Fk, -1, -2) + Q[index[k]]  # predicted [state; velocity] covariance
        B[:, :s] = J[:, :s, s:]
        GS = B @ inverse_3(J[:, s:, s:])
        predicted = Fk @ state
        e = X[k] - predicted[:, s:]
        W = GS @ e
        P = J[:, :s, :s] - GS[:, :s] @ np.swapaxes(B[:, :s], 1, 2)
        P = 0.5 * (P + P.transpose(0, 2, 1))
        state = predicted[:, :s] + W[:, :s]
        E[k] = e
        U[k] = W[:, s:]
    E_m = E.transpose(1, 0, 2, 3).reshape(M, -1, c)
    U_m = U.transpose(1, 0, 2, 3).reshape(M, -1, c)
    return E_m.transpose(0, 2, 1) @ U_m, P, state


def _inverse_3(S: np.ndarray) -> np.ndarray:
    """Inverse of one symmetric 3 x 3 matrix, in closed form on Python floats (:func:`inverse_3`)."""
    (a, b, c), (_, e, f), (_, _, i) = S.tolist()
    A, B, C = e * i - f * f, c * f - b * i, b * f - c * e
    det = a * A + b * B + c * C
    if not det > 0.0:
        raise np.linalg.LinAlgError("innovation covariance is not positive definite")
    return np.array([[A, B, C], [B, a * i - c * c, b * c - a * f], [C, b * c - a * f, a * e - b * b]]) / det


def gram_one(
    F: np.ndarray,
    Q: np.ndarray,
    index: np.ndarray,
    turns: np.ndarray,
    turning: np.ndarray,
    X: np.ndarray,
    P: np.ndarray,
) -> np.ndarray:
    """:func:`gram_pass` of one mounting over a whole run: its whitened Gram matrix (c, c).

    For one mounting the batch axis costs more than it carries (each batched product
    and the batched 3 x 3 inverse are ~10 x a 2-D product's cost at this size): one
    loop of 2-D products, the inverse on Python floats. ``turns`` (K, 3, 3) and
    ``X`` (K, 3, c) are this mounting's; ``P`` (s, s) the covariance before the first
    interval. The arithmetic is :func:`gram_pass`'s, to rounding.
    """
    s = F.shape[-1]
    c = X.shape[-1]
    Fk = np.array(F[index])
    turned = np.flatnonzero(turning)
    Fk[turned] = turned_models(F, index[turned], turns[turned][:, None])[:, 0]
    Fk_t = np.ascontiguousarray(Fk.transpose(0, 2, 1))
    E = np.empty((len(X), 3, c))
    U = np.empty((len(X), 3, c))
    state = np.zeros((s, c))
    dot = np.dot
    for k in range(len(X)):
        J = dot(dot(Fk[k], P), Fk_t[k]) + Q[index[k]]  # predicted [state; velocity] covariance
        S_inv = _inverse_3(J[s:, s:])
        cross = J[:s, s:]
        gain = dot(cross, S_inv)
        P = J[:s, :s] - dot(gain, cross.T)
        P = 0.5 * (P + P.T)
        predicted = dot(Fk[k], state)
        e = X[k] - predicted[s:]
        state = predicted[:s] + dot(gain, e)
        E[k] = e
        U[k] = dot(S_inv, e)
    gram = E.reshape(-1, c).T @ U.reshape(-1, c)
    return 0.5 * (gram + gram.T)
