"""Exact noise whitening along each candidate walk (Gauss-Markov profiles).

With white noise the filter covariance at a segment start is close to its rest
steady state, so :mod:`seqdesign.search.beam` folds precomputed segment matrices.
With Gauss-Markov bias instability it is not: the filter's knowledge of the
body-frame biases depends on the whole attitude history (a rest's steady state
rotated into the next attitude is off by 20-30 % on a sigma). Here each
candidate carries its own filter covariance ``P`` (9 x 9, ``[phi, b_g, b_a]``),
and a segment is folded by running the Riccati recursion and the whitening of
the candidate's columns, batched over all candidates that take the same
segment. The observation columns of a segment do not depend on ``P``: they are
computed once per search (:func:`segment_columns`). The recursions are those
of :func:`calib.noise.whitening.whitener` and :func:`calib.noise.whitening.whiten`, rearranged for
speed (same arithmetic to rounding):

- the state and velocity rows of the transition are one ``(s + 3, s)`` matrix
  ``F`` and the noise one ``(s + 3, s + 3)`` matrix ``Q``, so ``F P F' + Q``
  gives the predicted covariance, the innovation covariance and their
  cross term in two products;
- the 3 x 3 innovation covariance is factored in closed form
  (:func:`calib.noise.whitening.cholesky_inverse_3`, no LAPACK call per candidate);
- the whitened rows of every interval are kept and the information is one
  product ``W' W`` per segment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.noise.whitening import cholesky_inverse_3, filter_order, interval_models


@dataclass(frozen=True)
class SegmentColumns:
    """A segment's unwhitened observations and noise intervals.

    ``H[k]`` is ``(3, 6 + 24)``: the response to a unit sensitivity ``S`` (6 x 24
    columns of ``[phi, dv]``) at the segment start, then the 24 unknowns'
    particular responses; ``S_end = A S + B``. ``F[k]`` stacks the filter-state
    rows ``F_ss`` over the velocity rows ``F_vs``; ``Q[k]`` is the interval's noise
    covariance in the same order (filter state first, velocity last).

    Stacked (:func:`stack`, one per node) the interval axis comes first,
    ``H (K, n, 3, 30)``, ``F (K, n, s + 3, s)``, ``Q (K, n, s + 3, s + 3)``, and
    ``A (n, 6, 6)``, ``B (n, 6, 24)``: a fold gathers one interval at a time.
    """

    H: np.ndarray  # (K, 3, 30)
    A: np.ndarray  # (6, 6)
    B: np.ndarray  # (6, 24)
    F: np.ndarray  # (K, s + 3, s)
    Q: np.ndarray  # (K, s + 3, s + 3)


def noise_blocks(A6: np.ndarray, T: np.ndarray, profile, C_mid: np.ndarray | None):
    """``F`` and ``Q`` of each interval, in the filter's state order (velocity last)."""
    models = interval_models(A6, T, profile, C_mid)
    s = models[0].state_size
    order = filter_order(s)
    Phi = np.array([m.Phi for m in models])[:, order][:, :, order]
    Q = np.array([m.Q for m in models])[:, order][:, :, order]
    return np.ascontiguousarray(Phi[:, :, :s]), Q


def start_state(P0: np.ndarray, n_unknown: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lifted state, information and filter covariance at a run's start (before any rest).

    ``S`` holds the initial attitude error's unit columns (the last three unknowns);
    the filter state is zero.
    """
    s = len(P0)
    X = np.zeros((6 + s, n_unknown))
    X[:3, -3:] = np.eye(3)
    return X, np.zeros((n_unknown, n_unknown)), np.array(P0, dtype=float)


def stack(cols: list[SegmentColumns]) -> SegmentColumns:
    """Segments of equal interval count stacked, one per node (interval axis first)."""

    def st(f, axis):
        return np.ascontiguousarray(np.stack([getattr(c, f) for c in cols], axis=axis))

    return SegmentColumns(H=st("H", 1), A=st("A", 0), B=st("B", 0), F=st("F", 1), Q=st("Q", 1))


def then(first: SegmentColumns, second: SegmentColumns) -> SegmentColumns:
    """Two segments one after the other as one (e.g. a turn and the rest after it), stacked alike.

    The second's columns are relative to its own start ``S' = A1 S + B1``: written
    relative to the first's start they are ``[H2_hom A1 | H2_hom B1 + H2_part]``, and
    the end state ``S_end = A2 A1 S + A2 B1 + B2``. Its :class:`SegmentBlock` then folds
    both in one step (:func:`fold_block`), the same as folding them in turn to rounding.
    """
    H2 = second.H
    hom, part = H2[..., :6], H2[..., 6:]
    H = np.concatenate([hom @ first.A, hom @ first.B + part], axis=-1)
    return SegmentColumns(
        H=np.ascontiguousarray(np.concatenate([first.H, H])),
        A=second.A @ first.A,
        B=second.A @ first.B + second.B,
        F=np.ascontiguousarray(np.concatenate([first.F, second.F])),
        Q=np.ascontiguousarray(np.concatenate([first.Q, second.Q])),
    )


def _tr(a: np.ndarray) -> np.ndarray:
    return np.swapaxes(a, -1, -2)


def fold(cols: SegmentColumns, X: np.ndarray, N: np.ndarray, P: np.ndarray, index=None):
    """Fold one segment into a batch of candidates.

    Parameters
    ----------
    cols : SegmentColumns
        One segment shared by the batch, or stacked (:func:`stack`) with
        ``index`` giving each candidate's row.
    X : ndarray, shape (b, 6 + s, 24)
        ``[S; filter state]`` of each candidate.
    N : ndarray, shape (b, 24, 24)
        Information so far.
    P : ndarray, shape (b, s, s)
        Filter covariance.
    index : array of int, optional
        Each candidate's row of stacked columns.

    Returns
    -------
    X, N, P after the segment (new arrays).
    """

    def at(a, k):
        return a[k] if index is None else a[k, index]

    s = P.shape[-1]
    S, ph = X[:, :6], X[:, 6:]
    K = cols.H.shape[0]
    W: np.ndarray = np.empty((len(X), K, 3, X.shape[-1]))
    for k in range(K):
        F, Hk = at(cols.F, k), at(cols.H, k)
        M = F @ P @ _tr(F) + at(cols.Q, k)  # predicted [state; velocity] covariance
        Li = cholesky_inverse_3(M[:, s:, s:])
        C = M[:, :s, s:]
        G = C @ (_tr(Li) @ Li)
        P = M[:, :s, :s] - G @ _tr(C)
        P = 0.5 * (P + _tr(P))
        Fph = F @ ph
        e = Hk[..., :6] @ S + Hk[..., 6:] - Fph[:, s:]
        ph = Fph[:, :s] + G @ e
        W[:, k] = Li @ e
    W = W.reshape(len(X), 3 * K, -1)
    N = N + _tr(W) @ W
    A, B = (cols.A, cols.B) if index is None else (cols.A[index], cols.B[index])
    return np.concatenate([A @ S + B, ph], axis=1), N, P


@dataclass(frozen=True)
class SegmentBlock:
    """A segment's effect on any candidate in closed form, whatever its filter covariance.

    The segment's observations stacked, ``Z = O s_0 + n`` (``s_0`` the filter state at
    its start, ``n`` the segment's noise, covariance ``Sigma``), and its end state
    ``s_L = Phi s_0 + n_s``, with ``n_s = K0 n + r`` (``r`` independent of ``n``). A
    candidate's columns enter as ``y = x - O s^_0 = C c``, ``C = [Hh | Hp | O]`` and
    ``c = [S; I; -s^_0]``. With the candidate's covariance ``P`` and
    ``T = I + O' Sigma^-1 O P`` (Woodbury, valid for a singular ``P``):

    - information added: ``y' (O P O' + Sigma)^-1 y = c' G c - v' P T^-1 v``,
      ``G = C' Sigma^-1 C``, ``v = O' Sigma^-1 y`` (rows ``O`` of ``G c``);
    - end state: ``s^_L = D (s^_0 + P T^-1 v) + K0 x``, ``D = Phi - K0 O``;
    - end covariance: ``P_L = P_L0 + D P T^-1 D'``.

    ``G``, ``K0 C``, ``D`` and ``P_L0`` do not depend on the candidate: one Kalman pass
    over the segment from a known state (``P = 0``) gives them (:func:`segment_blocks`).
    The sequential fold's whitened innovations have the same Gram matrix (the
    prediction-error decomposition), so a candidate's information, state and
    covariance are :func:`fold`'s, to rounding. Arrays carry a leading node axis
    when stacked.
    """

    G: np.ndarray  # (39, 39): [S (6), particular (24), O (9)]
    K0C: np.ndarray  # (s, 30): K0 [Hh | Hp]
    D: np.ndarray  # (s, s)
    P_L0: np.ndarray  # (s, s)
    A: np.ndarray  # (6, 6)
    B: np.ndarray  # (6, 24)


def segment_blocks(cols: SegmentColumns) -> SegmentBlock:
    """:class:`SegmentBlock` of stacked segments (:func:`stack`), one Kalman pass for all.

    The filter of :func:`fold` started from a known state (``P = 0``) over the data
    columns ``C = [Hh | Hp | O]``, ``O_k = F_vs,k Phi_{k-1}`` the response to the start
    state (``Phi_k = F_ss,k ... F_ss,1``).
    """
    K, n = cols.H.shape[:2]
    s = cols.F.shape[-1]
    P = np.zeros((n, s, s))
    Phi = np.broadcast_to(np.eye(s), (n, s, s)).copy()
    state = np.zeros((n, s, 30 + s))
    gram = np.zeros((n, 30 + s, 30 + s))
    for k in range(K):
        F = cols.F[k]
        M = F @ P @ _tr(F) + cols.Q[k]
        S_inv = np.linalg.inv(M[:, s:, s:])
        C = M[:, :s, s:]
        G = C @ S_inv
        P = M[:, :s, :s] - G @ _tr(C)
        P = 0.5 * (P + _tr(P))
        data = np.concatenate([cols.H[k], F[:, s:] @ Phi], axis=2)  # (n, 3, 30 + s)
        pred = F @ state
        e = data - pred[:, s:]
        state = pred[:, :s] + G @ e
        gram += _tr(e) @ (S_inv @ e)
        Phi = F[:, :s] @ Phi
    return SegmentBlock(
        G=0.5 * (gram + _tr(gram)),
        K0C=state[:, :, :30],
        D=Phi - state[:, :, 30:],
        P_L0=P,
        A=cols.A,
        B=cols.B,
    )


def fold_block(block: SegmentBlock, X: np.ndarray, N: np.ndarray, P: np.ndarray, index=None):
    """:func:`fold` of one segment through its :class:`SegmentBlock` (same arguments and returns)."""

    def at(a):
        return a if index is None else a[index]

    s = P.shape[-1]
    G, K0C, D = at(block.G), at(block.K0C), at(block.D)
    S, ph = X[:, :6], X[:, 6:]
    Gc = G[..., :6] @ S + G[..., 6:30] - G[..., 30:] @ ph  # G c, (b, 39, 24)
    v = Gc[:, 30:]
    T = np.eye(s) + G[..., 30:, 30:] @ P
    PT = _tr(np.linalg.solve(_tr(T), P))  # P T^-1
    info = _tr(S) @ Gc[:, :6] + Gc[:, 6:30] - _tr(ph) @ v - _tr(v) @ (PT @ v)
    N = N + 0.5 * (info + _tr(info))
    ph = D @ (ph + PT @ v) + K0C[..., :6] @ S + K0C[..., 6:]
    P = at(block.P_L0) + D @ PT @ _tr(D)
    P = 0.5 * (P + _tr(P))
    A, B = at(block.A), at(block.B)
    return np.concatenate([A @ S + B, ph], axis=1), N, P
