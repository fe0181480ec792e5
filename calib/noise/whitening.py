"""Noise structure of the observations and the whitening filter (exact GLS).

White gyro noise (ARW) makes the attitude error a random walk and the
velocity error an integrated random walk; white accelerometer noise (VRW)
makes the velocity error a random walk. Velocity changes over intervals are
therefore correlated across the whole run. The exact weighting is a Kalman
filter on the noise part of the unobserved error states, with the
observation noise of an interval correlated with that interval's process
noise (both come from the same white noise). Its innovations, normalised,
are white: applied column by column to ``[H | z]`` they give the GLS normal
equations, identical to a Kalman filter over all unknowns, but the gains are
computed once and shared by every column.

The filter state ``s`` is the noise part of the attitude error ``phi`` (3
states) or, when the profile has Gauss-Markov bias instability (see
:mod:`calib.noise.gauss_markov`), ``[phi, b_g, b_a]`` (9 states, biases in the body
frame)::

    phi' = -omega_ie x phi - C_b_n b_g - C_b_n w_g
    dv'  =  f_n x phi - 2 omega_ie x dv + C_b_n b_a + C_b_n w_a
    b'   = -b / tau + w_b,   PSD(w_b) = 2 sigma^2 / tau

``C_b_n`` is held constant over an interval (its mid-point attitude). The
velocity ``dv`` is observed exactly (``z_k = y_k - Phi_vv y_{k-1}``) and no
state depends on it, so ``s_k = F_ss s_{k-1} + w_s`` and
``z_k = F_vs s_{k-1} + w_v``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .matexp import expm  # not scipy.linalg: its import costs 0.15 s per command
from .profiles import NoiseProfile


@dataclass(frozen=True)
class IntervalModel:
    """Discrete error-state model of one interval.

    ``Phi`` and ``Q`` are of ``[phi, dv]`` (6 x 6) without GM bias, of
    ``[phi, dv, b_g, b_a]`` (12 x 12, biases in the body frame) with it;
    ``P_bias`` is then the (6, 6) stationary covariance of ``[b_g, b_a]``.
    """

    Phi: np.ndarray  # transition
    Q: np.ndarray  # noise covariance accumulated over the interval
    P_bias: np.ndarray | None = None

    @property
    def state_size(self) -> int:
        """Size of the filter state: every state but the observed velocity."""
        return self.Phi.shape[0] - 3


def _van_loan(A: np.ndarray, Qc: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact ``Phi = exp(A T)`` and ``Q = int_0^T Phi(s) Qc Phi(s)' ds``."""
    n = len(A)
    # Van Loan: expm([[-A, Qc], [0, A']] T) = [[., Phi^-1 Q], [0, Phi']].
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = Qc
    M[n:, n:] = A.T
    E = expm(M * T)
    Phi = E[n:, n:].T
    Q = Phi @ E[:n, n:]
    return Phi, 0.5 * (Q + Q.T)


@functools.lru_cache(maxsize=4096)
def _interval(A_bytes: bytes, T: float, arw: float, vrw: float) -> IntervalModel:
    A = np.frombuffer(A_bytes).reshape(6, 6)
    Phi, Q = _van_loan(A, np.diag([arw**2] * 3 + [vrw**2] * 3), T)
    return IntervalModel(Phi=Phi, Q=Q)


@functools.lru_cache(maxsize=4096)
def gm_interval_nav(A_bytes: bytes, T: float, profile: NoiseProfile) -> tuple[np.ndarray, np.ndarray]:
    """The 12-state model with the biases in the *navigation* frame, ``C_b_n b``.

    In that frame the model does not depend on the attitude: ``-b / tau`` and the
    isotropic ``2 sigma^2 / tau I`` are invariant under a rotation. The body-frame
    model of attitude ``C`` is then exactly ``R' Phi R``, ``R' Q R`` with
    ``R = diag(I, I, C, C)``, so one Van Loan per interval length serves every
    attitude (no cache over attitudes needed).
    """
    A6 = np.frombuffer(A_bytes).reshape(6, 6)
    A = np.zeros((12, 12))
    A[:6, :6] = A6
    A[:3, 6:9] = -np.eye(3)
    A[3:6, 9:] = np.eye(3)
    qc = [profile.arw**2, profile.vrw**2]
    for i, (sigma, tau) in enumerate(
        [
            (profile.gyro_gm_sigma, profile.gyro_bias_correlation_s),
            (profile.accel_gm_sigma, profile.accel_bias_correlation_s),
        ]
    ):
        # A sensor without GM keeps its bias states at exactly zero (no noise, zero P0).
        if sigma > 0:
            A[6 + 3 * i : 9 + 3 * i, 6 + 3 * i : 9 + 3 * i] = -np.eye(3) / tau
        qc.append(2.0 * sigma**2 / tau if sigma > 0 else 0.0)
    Phi, Q = _van_loan(A, np.diag(np.repeat(qc, 3)), T)
    # The [phi, dv] block is exp(A6 T) in exact arithmetic; take the 6-state model's own
    # so that Phi_vv, hence the observations z, are bit-identical with and without GM.
    Phi[:6, :6] = _interval(A_bytes, T, profile.arw, profile.vrw).Phi
    return Phi, Q


def rotations(C: np.ndarray) -> np.ndarray:
    """Nearest rotation matrices (polar factor): a mid-point average of two attitudes
    is not exactly orthogonal, and the frame change above needs ``C^-1 = C'``.
    """
    U, _, Vt = np.linalg.svd(C)
    R = U @ Vt
    flip = np.linalg.det(R) < 0
    if np.any(flip):
        U[flip, :, -1] *= -1.0
        R = U @ Vt
    return R


def interval_models(
    A: np.ndarray, T: np.ndarray, profile: NoiseProfile, C_b_n: np.ndarray | None = None
) -> list[IntervalModel]:
    """One :class:`IntervalModel` per interval (cached by length to 1 us).

    Parameters
    ----------
    A : ndarray, shape (6, 6)
        Continuous ``[phi, dv]`` matrix (:func:`calib.nav.jacobian.state_matrix`).
    T : ndarray, shape (K,)
        Interval lengths, s.
    profile : NoiseProfile
    C_b_n : ndarray, shape (K, 3, 3), optional
        Attitude of each interval (at its mid-point). Required when
        ``profile.has_gauss_markov``, ignored otherwise.
    """
    if not profile.has_gauss_markov:
        return _white_models(A, T, profile)
    Phi, Q, P_bias = gm_interval_arrays(A, T, profile, C_b_n)
    return [IntervalModel(Phi=p, Q=q, P_bias=P_bias) for p, q in zip(Phi, Q, strict=True)]


def gm_interval_arrays(
    A: np.ndarray, T: np.ndarray, profile: NoiseProfile, C_b_n: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Phi`` and ``Q`` (K, 12, 12) of every interval with Gauss-Markov bias, and ``P_bias``.

    The arrays :func:`interval_models` wraps, for a caller that wants them stacked
    (:func:`whiten_batch`). ``C_b_n`` (K, 3, 3) is each interval's mid-point attitude.
    """
    if C_b_n is None:
        raise ValueError(
            f"profile {profile.name!r} has Gauss-Markov bias instability: "
            "the noise model needs the attitude of every interval (C_b_n)"
        )
    C_b_n = np.asarray(C_b_n, dtype=float)
    if C_b_n.shape != (len(T), 3, 3):
        raise ValueError(f"C_b_n must have shape ({len(T)}, 3, 3), got {C_b_n.shape}")
    key = np.ascontiguousarray(A, dtype=float).tobytes()
    keys, index = np.unique(np.round(np.asarray(T, dtype=float), 6), return_inverse=True)
    nav = [gm_interval_nav(key, float(t), profile) for t in keys]
    Phi_nav = np.array([p for p, _ in nav])[index]
    Q_nav = np.array([q for _, q in nav])[index]
    R = np.zeros((len(T), 12, 12))
    R[:, :3, :3] = R[:, 3:6, 3:6] = np.eye(3)
    R[:, 6:9, 6:9] = R[:, 9:, 9:] = rotations(C_b_n)
    Rt = R.transpose(0, 2, 1)
    Phi, Q = Rt @ Phi_nav @ R, Rt @ Q_nav @ R
    Q = 0.5 * (Q + Q.transpose(0, 2, 1))
    return Phi, Q, gm_bias_covariance(profile)


def gm_bias_covariance(profile: NoiseProfile) -> np.ndarray:
    """The GM biases' stationary covariance (6, 6): ``sigma^2 I`` per sensor, the gyro's first."""
    return np.diag(np.repeat([profile.gyro_gm_sigma**2, profile.accel_gm_sigma**2], 3))


def velocity_transitions(A: np.ndarray, T: np.ndarray, profile: NoiseProfile) -> np.ndarray:
    """``Phi_vv`` (K, 3, 3) of every interval: the ``dv`` block of :func:`interval_models`.

    It does not depend on the attitude, with or without GM bias (the GM model
    takes its ``[phi, dv]`` block from the 6-state one, and the frame change
    leaves the velocity rows alone), so every mounting of a sequence shares it.
    """
    return np.array([m.Phi[3:6, 3:6] for m in _white_models(A, T, profile)])


def _white_models(A: np.ndarray, T: np.ndarray, profile: NoiseProfile) -> list[IntervalModel]:
    """The 6-state ``[phi, dv]`` model of every interval (cached by length to 1 us)."""
    key = np.ascontiguousarray(A, dtype=float).tobytes()
    return [_interval(key, round(float(t), 6), profile.arw, profile.vrw) for t in T]


@dataclass(frozen=True)
class Whitener:
    """Gains of the noise filter for a sequence of intervals (state size ``s``)."""

    F_ss: np.ndarray  # (K, s, s) transition of the filter state
    F_vs: np.ndarray  # (K, 3, s) its effect on the velocity change
    gain: np.ndarray  # (K, s, 3)
    L_inv: np.ndarray  # (K, 3, 3) inverse Cholesky factor of the innovation covariance
    logdet_S: float  # sum of log det of the innovation covariances
    P_end: np.ndarray  # (s, s) covariance of the filter state after the last interval

    @property
    def state_size(self) -> int:
        """3 (``phi``) without GM bias, 9 (``[phi, b_g, b_a]``) with it."""
        return self.F_ss.shape[-1]


def _cholesky_inverse_3(S: np.ndarray) -> tuple[np.ndarray, float]:
    """``L^-1`` and ``log det L`` of the Cholesky factor ``S = L L'`` of one 3 x 3 SPD matrix.

    The same closed form as :func:`cholesky_inverse_3`, written on Python floats:
    :func:`whitener` calls it once per interval (tens of thousands of times), where
    two LAPACK calls, or the batched form's dozen small-array operations, cost more
    than the arithmetic. Raises ``numpy.linalg.LinAlgError`` when ``S`` is not
    positive definite.
    """
    (s11, _, _), (s21, s22, _), (s31, s32, s33) = S.tolist()
    d1 = s11
    l11 = math.sqrt(d1) if d1 > 0.0 else math.nan
    l21, l31 = s21 / l11, s31 / l11
    d2 = s22 - l21 * l21
    l22 = math.sqrt(d2) if d2 > 0.0 else math.nan
    l32 = (s32 - l31 * l21) / l22
    d3 = s33 - l31 * l31 - l32 * l32
    l33 = math.sqrt(d3) if d3 > 0.0 else math.nan
    if math.isnan(l11 + l22 + l33):
        raise np.linalg.LinAlgError("innovation covariance is not positive definite")
    m11, m22, m33 = 1.0 / l11, 1.0 / l22, 1.0 / l33
    m21, m32 = -l21 * m11 * m22, -l32 * m22 * m33
    m31 = -(l31 * m33 + l21 * m32) * m11
    Li = np.array([[m11, 0.0, 0.0], [m21, m22, 0.0], [m31, m32, m33]])
    return Li, math.log(l11 * l22 * l33)


def cholesky_inverse_3(S: np.ndarray) -> np.ndarray:
    """``L^-1`` of the Cholesky factors ``S = L L'`` of a batch of 3 x 3 SPD matrices.

    Closed form, elementwise over the batch: a LAPACK call per 3 x 3 matrix costs
    more than the arithmetic. :func:`_cholesky_inverse_3` is the same formula for
    a single matrix on Python floats.

    Parameters
    ----------
    S : ndarray, shape (..., 3, 3)
        Symmetric positive definite matrices; only the lower triangle is read.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Lower-triangular ``L^-1`` of each matrix.

    Raises
    ------
    numpy.linalg.LinAlgError
        If any matrix of the batch is not positive definite.
    """
    l11 = np.sqrt(S[..., 0, 0])
    l21, l31 = S[..., 1, 0] / l11, S[..., 2, 0] / l11
    l22 = np.sqrt(S[..., 1, 1] - l21 * l21)
    l32 = (S[..., 2, 1] - l31 * l21) / l22
    m33 = 1.0 / np.sqrt(S[..., 2, 2] - l31 * l31 - l32 * l32)
    # A pivot <= 0 (or NaN) anywhere leaves m33 NaN or infinite: one check on it
    # costs 2 us per call where checking each pivot before its root costs 8 us,
    # in the search's innermost loop. (numpy warns about the root first.)
    if not np.isfinite(m33).all():
        raise np.linalg.LinAlgError("innovation covariance is not positive definite")
    Li = np.zeros(S.shape)
    Li[..., 0, 0] = 1.0 / l11
    Li[..., 1, 1] = 1.0 / l22
    Li[..., 2, 2] = m33
    Li[..., 1, 0] = -l21 * Li[..., 0, 0] * Li[..., 1, 1]
    Li[..., 2, 1] = -l32 * Li[..., 1, 1] * m33
    Li[..., 2, 0] = -(Li[..., 2, 1] * l21 + m33 * l31) * Li[..., 0, 0]
    return Li


def filter_order(s: int) -> np.ndarray:
    """Index putting an interval model's rows and columns in the noise filter's order.

    Filter state first, observed velocity last: ``[phi, (b_g, b_a,) dv]`` from the
    models' ``[phi, dv, (b_g, b_a)]``; the identity for the 3-state filter (``s = 3``).
    """
    return np.r_[0:3, 6 : s + 3, 3:6]


def whitener(models: list[IntervalModel], P0: np.ndarray | None = None) -> Whitener:
    """Riccati recursion of the noise filter (data-independent).

    ``P0`` (s x s) is the covariance of the filter state before the first
    interval. Default: zero for ``phi`` (at the start of a run the initial
    attitude error is an unknown of the fit, not noise) and, with GM bias,
    the stationary ``sigma^2 I`` for the biases, uncorrelated with ``phi``.
    """
    K = len(models)
    s = models[0].state_size if K else 3
    order = filter_order(s)
    Phi = np.array([m.Phi for m in models]).reshape(K, s + 3, s + 3)
    Q = np.array([m.Q for m in models]).reshape(K, s + 3, s + 3)
    if s != 3:  # (no copy without GM: the arithmetic stays bit-identical to the 3-state filter)
        Phi, Q = Phi[:, order][:, :, order], Q[:, order][:, :, order]
    F_ss = np.ascontiguousarray(Phi[:, :s, :s])
    F_vs = np.ascontiguousarray(Phi[:, s:, :s])
    gain = np.empty((K, s, 3))
    L_inv = np.empty((K, 3, 3))
    if P0 is not None:
        P = np.array(P0, dtype=float)
    else:
        P = np.zeros((s, s))
        if s != 3:
            P[3:, 3:] = models[0].P_bias
    if P.shape != (s, s):
        raise ValueError(f"P0 must have shape ({s}, {s}), got {P.shape}")
    logdet = 0.0
    for k in range(K):
        Fss, Fvs = F_ss[k], F_vs[k]
        Qss, Qsv, Qvv = Q[k, :s, :s], Q[k, :s, s:], Q[k, s:, s:]
        PFvs = P @ Fvs.T
        S = Fvs @ PFvs + Qvv
        Li, log_det_L = _cholesky_inverse_3(S)
        G = (Fss @ PFvs + Qsv) @ (Li.T @ Li)
        P = Fss @ P @ Fss.T + Qss - G @ S @ G.T
        P = 0.5 * (P + P.T)
        gain[k], L_inv[k] = G, Li
        logdet += 2.0 * log_det_L
    return Whitener(F_ss, F_vs, gain, L_inv, logdet, P)


def whiten(w: Whitener, X: np.ndarray, phi0: np.ndarray | None = None, return_final: bool = False):
    """Whitened innovations of observation columns.

    Parameters
    ----------
    w : Whitener
    X : ndarray, shape (K, 3, c)
        Observation-shaped columns (``H`` and/or ``z[..., None]``).
    phi0 : ndarray, shape (s, c), optional
        The filter's state before the first interval (zero at a run's start).
    return_final : bool
        Also return the filter's state after the last interval, shape (s, c).

    Returns
    -------
    ndarray, shape (K, 3, c)
        ``L_k^-1 (X_k - F_vs s_hat_k)``, white with unit covariance when X is
        the noise of the model.
    """
    K, _, c = X.shape
    out = np.empty_like(X)
    phi = np.zeros((w.state_size, c)) if phi0 is None else np.array(phi0, dtype=float)
    for k in range(K):
        e = X[k] - w.F_vs[k] @ phi
        phi = w.F_ss[k] @ phi + w.gain[k] @ e
        out[k] = w.L_inv[k] @ e
    return (out, phi) if return_final else out


def filter_blocks(Phi: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, ...]:
    """``F_ss, F_vs, Q_ss, Q_sv, Q_vv`` of stacked interval models (..., s + 3, s + 3).

    The blocks :func:`whitener` reads, filter state first and observed velocity
    last, each a contiguous copy.
    """
    s = Phi.shape[-1] - 3
    order = filter_order(s)
    Phi, Q = Phi[..., order, :][..., order], Q[..., order, :][..., order]

    def block(a, rows, cols):
        return np.ascontiguousarray(a[..., rows, cols])

    return (
        block(Phi, slice(None, s), slice(None, s)),
        block(Phi, slice(s, None), slice(None, s)),
        block(Q, slice(None, s), slice(None, s)),
        block(Q, slice(None, s), slice(s, None)),
        block(Q, slice(s, None), slice(s, None)),
    )


def whiten_batch(
    blocks: tuple[np.ndarray, ...],
    X: np.ndarray,
    P: np.ndarray,
    state: np.ndarray,
    out: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`whitener` and :func:`whiten` in one pass, over a batch of ``M`` noise models.

    Several mountings of one sequence share its interval grid but not its
    filter (the GM biases are seen through each mounting's attitude): one loop
    over the intervals with the mountings on a batch axis costs little more
    than one mounting's. The arithmetic is :func:`whitener`'s and
    :func:`whiten`'s, operation for operation, on ``(M, ., .)`` stacks.

    Parameters
    ----------
    blocks : tuple of ndarray
        :func:`filter_blocks` of the intervals, interval axis first:
        ``F_ss (K, M, s, s)``, ``F_vs (K, M, 3, s)``, ``Q_ss``, ``Q_sv``, ``Q_vv``.
    X : ndarray, shape (K, M, 3, c)
        Observation-shaped columns of each mounting.
    P : ndarray, shape (M, s, s)
        Filter covariance before the first interval.
    state : ndarray, shape (M, s, c)
        The filter's state (of the columns) before the first interval.
    out : ndarray, shape (K, M, 3, c), optional
        Where to write the whitened rows; may be ``X`` itself (an interval's rows
        are read before they are overwritten).

    Returns
    -------
    Xw : ndarray, shape (K, M, 3, c)
        Whitened innovations, as :func:`whiten` returns them per mounting.
    P, state : ndarray
        After the last interval, to carry into the next block of intervals.
    """
    F_ss, F_vs, Q_ss, Q_sv, Q_vv = blocks
    out = np.empty_like(X) if out is None else out
    for k in range(len(X)):
        Fss, Fvs = F_ss[k], F_vs[k]
        Fss_t = Fss.transpose(0, 2, 1)
        PFvs = P @ Fvs.transpose(0, 2, 1)
        S = Fvs @ PFvs + Q_vv[k]
        Li = cholesky_inverse_3(S)
        G = (Fss @ PFvs + Q_sv[k]) @ (Li.transpose(0, 2, 1) @ Li)
        P = Fss @ P @ Fss_t + Q_ss[k] - G @ S @ G.transpose(0, 2, 1)
        P = 0.5 * (P + P.transpose(0, 2, 1))
        e = X[k] - Fvs @ state
        state = Fss @ state + G @ e
        out[k] = Li @ e
    return out, P, state


@dataclass(frozen=True)
class NoiseModel:
    """Whitening gains and the velocity transition of every interval."""

    whitener: Whitener
    Phi_vv: np.ndarray  # (K, 3, 3)
    models: tuple = ()  # the IntervalModel of every interval (for :func:`calib.noise.smoother.smooth`)


def noise_model(
    A: np.ndarray,
    T: np.ndarray,
    profile: NoiseProfile,
    P0: np.ndarray | None = None,
    C_b_n: np.ndarray | None = None,
) -> NoiseModel:
    """The noise filter of a run's intervals.

    Parameters
    ----------
    A : ndarray, shape (6, 6)
        Continuous ``[phi, dv]`` matrix (:func:`calib.nav.jacobian.state_matrix`).
    T : ndarray, shape (K,)
        Interval lengths, s.
    profile : NoiseProfile
    P0 : ndarray, shape (s, s), optional
        Filter-state covariance before the first interval (see :func:`whitener`).
    C_b_n : ndarray, shape (K, 3, 3), optional
        Mid-point attitude of each interval; required when
        ``profile.has_gauss_markov`` (``ValueError`` otherwise), ignored without GM.
    """
    models = interval_models(A, T, profile, C_b_n)
    return NoiseModel(whitener(models, P0), np.array([m.Phi[3:6, 3:6] for m in models]), tuple(models))
