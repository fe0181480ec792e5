"""The fixed-interval smoother of the noise states (Rauch-Tung-Striebel) over the whitener's model.

The estimator's attitude feedback (:mod:`calib.fit.feedback`) asks it where the attitude
noise went, given every velocity observation of the run.
"""

from __future__ import annotations

import numpy as np

from .whitening import IntervalModel, filter_order


def _decorrelated(models: list[IntervalModel]):
    """Filter-state transition with the observation's share of the process noise taken out.

    The velocity noise ``w_v`` of an interval and the filter-state noise
    ``w_s`` come from the same white noise. Writing ``w_s = J w_v + w'`` with
    ``J = Q_sv Q_vv^-1`` and substituting ``w_v = z_k - F_vs s_k`` gives
    ``s_{k+1} = (F_ss - J F_vs) s_k + J z_k + w'``, with ``w'`` of covariance
    ``Q_ss - J Q_vs`` independent of the observation: a textbook smoother applies.
    """
    K = len(models)
    s = models[0].state_size
    order = filter_order(s)
    Phi = np.array([m.Phi for m in models]).reshape(K, s + 3, s + 3)[:, order][:, :, order]
    Q = np.array([m.Q for m in models]).reshape(K, s + 3, s + 3)[:, order][:, :, order]
    F_ss, F_vs = Phi[:, :s, :s], Phi[:, s:, :s]
    J = np.linalg.solve(Q[:, s:, s:], Q[:, s:, :s]).transpose(0, 2, 1)
    return F_ss - J @ F_vs, F_vs, J, Q[:, :s, :s] - J @ Q[:, s:, :s], Q[:, s:, s:]


def smooth(models: list[IntervalModel], z: np.ndarray, P0: np.ndarray | None = None) -> np.ndarray:
    """Smoothed filter states ``s_0 .. s_K`` given every observation (Rauch-Tung-Striebel).

    The same model as :func:`~calib.noise.whitener`: ``z_k = F_vs s_k + w_v`` observes the
    state at the start of interval ``k``. This is the noise part of the
    attitude error (and the GM biases) that best explains the residuals
    ``z`` (K, 3) of a fit: the estimator feeds it back into its reference
    trajectory (:func:`calib.fit.feedback.attitude_feedback`). Returns (K + 1, s).
    """
    F, F_vs, J, Qw, Qvv = _decorrelated(models)
    K, s = len(models), F.shape[-1]
    P = np.zeros((s, s)) if P0 is None else np.array(P0, dtype=float)
    if P0 is None and s != 3:
        P[3:, 3:] = models[0].P_bias
    m = np.zeros(s)
    a, Pa = np.empty((K, s)), np.empty((K, s, s))
    b, Pb = np.empty((K + 1, s)), np.empty((K + 1, s, s))
    for k in range(K):
        S = F_vs[k] @ P @ F_vs[k].T + Qvv[k]
        G = np.linalg.solve(S, F_vs[k] @ P).T
        a[k], Pa[k] = m + G @ (z[k] - F_vs[k] @ m), P - G @ S @ G.T
        m, P = F[k] @ a[k] + J[k] @ z[k], F[k] @ Pa[k] @ F[k].T + Qw[k]
        b[k + 1], Pb[k + 1] = m, P
    out = np.empty((K + 1, s))
    out[K] = b[K]
    for k in range(K - 1, -1, -1):
        # pinv: a sensor without Gauss-Markov bias keeps its bias states at exactly zero.
        C = Pa[k] @ F[k].T @ np.linalg.pinv(Pb[k + 1], hermitian=True)
        out[k] = a[k] + C @ (out[k + 1] - b[k + 1])
    return out
