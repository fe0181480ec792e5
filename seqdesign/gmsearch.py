"""Exact noise whitening along each candidate walk (Gauss-Markov profiles).

With white noise the filter covariance at a segment start is close to its rest
steady state, so :mod:`seqdesign.design` folds precomputed segment matrices.
With Gauss-Markov bias instability it is not: the filter's knowledge of the
body-frame biases depends on the whole attitude history (a rest's steady state
rotated into the next attitude is off by 20-30 % on a sigma). Here each
candidate carries its own filter covariance ``P`` (9 x 9, ``[phi, b_g, b_a]``),
and a segment is folded by running the Riccati recursion and the whitening of
the candidate's columns, batched over all candidates that take the same
segment. The observation columns of a segment do not depend on ``P``: they are
computed once per search (:func:`segment_columns`). The recursions are those
of :func:`calib.noise.whitener` and :func:`calib.noise.whiten`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.noise import interval_models, whitener


@dataclass(frozen=True)
class SegmentColumns:
    """A segment's unwhitened observations and noise intervals.

    ``H[k]`` is ``(3, 6 + 24)``: the response to a unit sensitivity ``S`` (6 x 24
    columns of ``[phi, dv]``) at the segment start, then the 24 unknowns'
    particular responses; ``S_end = A S + B``. The noise blocks are ordered as the
    filter orders them (filter state first, velocity last).
    """

    H: np.ndarray  # (K, 3, 30)
    A: np.ndarray  # (6, 6)
    B: np.ndarray  # (6, 24)
    F_ss: np.ndarray  # (K, s, s)
    F_vs: np.ndarray  # (K, 3, s)
    Q_ss: np.ndarray  # (K, s, s)
    Q_sv: np.ndarray  # (K, s, 3)
    Q_vv: np.ndarray  # (K, 3, 3)


def noise_blocks(A6: np.ndarray, T: np.ndarray, profile, C_mid: np.ndarray | None):
    """``F_ss, F_vs, Q_ss, Q_sv, Q_vv`` of each interval, in the filter's state order."""
    models = interval_models(A6, T, profile, C_mid)
    w = whitener(models[:1])  # the ordering convention of calib.noise.whitener
    s = w.state_size
    order = np.r_[0:3, 6:s + 3, 3:6] if s != 3 else np.r_[0:6]
    Phi = np.array([m.Phi for m in models])[:, order][:, :, order]
    Q = np.array([m.Q for m in models])[:, order][:, :, order]
    return (Phi[:, :s, :s], Phi[:, s:, :s], Q[:, :s, :s], Q[:, :s, s:], Q[:, s:, s:])


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
    """Segments of equal interval count stacked on a leading axis (one per candidate or node)."""
    return SegmentColumns(*(np.stack([getattr(c, f) for c in cols])
                            for f in SegmentColumns.__dataclass_fields__))


def take(cols: SegmentColumns, index) -> SegmentColumns:
    """Rows ``index`` of stacked columns (one per candidate)."""
    return SegmentColumns(*(getattr(cols, f)[index] for f in SegmentColumns.__dataclass_fields__))


def fold(cols: SegmentColumns, X: np.ndarray, N: np.ndarray, P: np.ndarray):
    """Fold one segment into a batch of candidates.

    Parameters
    ----------
    cols : SegmentColumns
        One segment shared by the batch, or stacked (:func:`take`): one per candidate.
    X : ndarray, shape (b, 6 + s, 24)
        ``[S; filter state]`` of each candidate.
    N : ndarray, shape (b, 24, 24)
        Information so far.
    P : ndarray, shape (b, s, s)
        Filter covariance.

    Returns
    -------
    X, N, P after the segment (new arrays).
    """
    def tr(a):
        return np.swapaxes(a, -1, -2)

    S, ph = X[:, :6], X[:, 6:]
    N = N.copy()
    for k in range(cols.H.shape[-3]):
        Fss, Fvs = cols.F_ss[..., k, :, :], cols.F_vs[..., k, :, :]
        H = cols.H[..., k, :, :6] @ S + cols.H[..., k, :, 6:]
        PFt = P @ tr(Fvs)
        Sk = Fvs @ PFt + cols.Q_vv[..., k, :, :]
        Li = np.linalg.inv(np.linalg.cholesky(Sk))
        G = (Fss @ PFt + cols.Q_sv[..., k, :, :]) @ (tr(Li) @ Li)
        P = Fss @ P @ tr(Fss) + cols.Q_ss[..., k, :, :] - G @ Sk @ tr(G)
        P = 0.5 * (P + tr(P))
        e = H - Fvs @ ph
        ph = Fss @ ph + G @ e
        w = Li @ e
        N += tr(w) @ w
    S = cols.A @ S + cols.B
    return np.concatenate([S, ph], axis=1), N, P
