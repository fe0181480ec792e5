"""Noise structure of the observations and the whitening filter (exact GLS).

White gyro noise (ARW) makes the attitude error a random walk and the
velocity error an integrated random walk; white accelerometer noise (VRW)
makes the velocity error a random walk. Velocity changes over intervals are
therefore correlated across the whole run. The exact weighting is a
three-state Kalman filter on the noise part of the attitude error, with the
observation noise of an interval correlated with that interval's process
noise (both come from the same white noise). Its innovations, normalised,
are white: applied column by column to ``[H | z]`` they give the GLS normal
equations, identical to a Kalman filter over all unknowns, but the gains are
computed once and shared by every column.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from .profiles import NoiseProfile


@dataclass(frozen=True)
class IntervalModel:
    """Discrete error-state model of one interval length."""

    Phi: np.ndarray  # (6, 6) transition of [phi, dv]
    Q: np.ndarray  # (6, 6) noise covariance accumulated over the interval


@functools.lru_cache(maxsize=4096)
def _interval(A_bytes: bytes, T: float, arw: float, vrw: float) -> IntervalModel:
    A = np.frombuffer(A_bytes).reshape(6, 6)
    Qc = np.diag([arw ** 2] * 3 + [vrw ** 2] * 3)
    # Van Loan: expm([[-A, Qc], [0, A']] T) = [[., Phi^-1 Q], [0, Phi']].
    M = np.zeros((12, 12))
    M[:6, :6] = -A
    M[:6, 6:] = Qc
    M[6:, 6:] = A.T
    E = expm(M * T)
    Phi = E[6:, 6:].T
    Q = Phi @ E[:6, 6:]
    return IntervalModel(Phi=Phi, Q=0.5 * (Q + Q.T))


def interval_models(A: np.ndarray, T: np.ndarray, profile: NoiseProfile) -> list[IntervalModel]:
    """One :class:`IntervalModel` per interval (cached by length to 1 us)."""
    key = np.ascontiguousarray(A).tobytes()
    return [_interval(key, round(float(t), 6), profile.arw, profile.vrw) for t in T]


@dataclass(frozen=True)
class Whitener:
    """Gains of the noise filter for a sequence of intervals."""

    Phi_pp: np.ndarray  # (K, 3, 3)
    Phi_vp: np.ndarray  # (K, 3, 3)
    gain: np.ndarray  # (K, 3, 3)
    L_inv: np.ndarray  # (K, 3, 3) inverse Cholesky factor of the innovation covariance
    logdet_S: float  # sum of log det of the innovation covariances
    P_end: np.ndarray  # (3, 3) covariance of the noise part of phi after the last interval


def whitener(models: list[IntervalModel], P0: np.ndarray | None = None) -> Whitener:
    """Riccati recursion of the three-state noise filter (data-independent).

    ``P0`` is the covariance of the noise part of phi before the first
    interval: zero at the start of a run (the initial attitude error is an
    unknown of the fit, not noise).
    """
    K = len(models)
    Phi_pp = np.empty((K, 3, 3))
    Phi_vp = np.empty((K, 3, 3))
    gain = np.empty((K, 3, 3))
    L_inv = np.empty((K, 3, 3))
    P = np.zeros((3, 3)) if P0 is None else np.array(P0, dtype=float)
    logdet = 0.0
    for k, m in enumerate(models):
        Fpp, Fvp = m.Phi[:3, :3], m.Phi[3:, :3]
        Qpp, Qpv, Qvv = m.Q[:3, :3], m.Q[:3, 3:], m.Q[3:, 3:]
        S = Fvp @ P @ Fvp.T + Qvv
        L = np.linalg.cholesky(S)
        Li = np.linalg.inv(L)
        G = (Fpp @ P @ Fvp.T + Qpv) @ (Li.T @ Li)
        P = Fpp @ P @ Fpp.T + Qpp - G @ S @ G.T
        P = 0.5 * (P + P.T)
        Phi_pp[k], Phi_vp[k], gain[k], L_inv[k] = Fpp, Fvp, G, Li
        logdet += 2.0 * np.sum(np.log(np.diag(L)))
    return Whitener(Phi_pp, Phi_vp, gain, L_inv, logdet, P)


def whiten(w: Whitener, X: np.ndarray, phi0: np.ndarray | None = None,
           return_final: bool = False):
    """Whitened innovations of observation columns.

    Parameters
    ----------
    w : Whitener
    X : ndarray, shape (K, 3, c)
        Observation-shaped columns (``H`` and/or ``z[..., None]``).
    phi0 : ndarray, shape (3, c), optional
        The filter's state before the first interval (zero at a run's start).
    return_final : bool
        Also return the filter's state after the last interval.

    Returns
    -------
    ndarray, shape (K, 3, c)
        ``L_k^-1 (X_k - Phi_vphi phi_hat_k)``, white with unit covariance
        when X is the noise of the model.
    """
    K, _, c = X.shape
    out = np.empty_like(X)
    phi = np.zeros((3, c)) if phi0 is None else np.array(phi0, dtype=float)
    for k in range(K):
        e = X[k] - w.Phi_vp[k] @ phi
        phi = w.Phi_pp[k] @ phi + w.gain[k] @ e
        out[k] = w.L_inv[k] @ e
    return (out, phi) if return_final else out


@dataclass(frozen=True)
class NoiseModel:
    """Whitening gains and the velocity transition of every interval."""

    whitener: Whitener
    Phi_vv: np.ndarray  # (K, 3, 3)


def noise_model(A: np.ndarray, T: np.ndarray, profile: NoiseProfile,
                P0: np.ndarray | None = None) -> NoiseModel:
    models = interval_models(A, T, profile)
    return NoiseModel(whitener(models, P0), np.array([m.Phi[3:, 3:] for m in models]))
