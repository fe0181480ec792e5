"""Observability of a sequence: Fisher information, predicted sigma, separability.

The information is the one the estimator would gather: the same linear
model (:func:`calib.jacobian.observation_jacobian`) evaluated along the
nominal trajectory of the sequence, the same observation intervals and the
same noise whitening. Its inverse is the covariance the calibration will
reach with that noise profile; the Monte Carlo tests check that it does.
"""
from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np

from calib import earth
from calib import params as P
from calib.jacobian import (MOVE_STEP_S, N_UNKNOWN, PHI0, ObservationGrid, observation_jacobian,
                            state_matrix)
from calib.noise import noise_model, whiten
from calib.profiles import NoiseProfile
from calib.sequence import Sequence, nominal_attitude, timeline
from calib.sim import SimConfig, true_increments
from calib.transform import rotvec_to_dcm

UNKNOWN_NAMES = list(P.NAMES) + ["phi0_E", "phi0_N", "phi0_U"]
CORRELATION_LIMIT = 0.9


@dataclass(frozen=True)
class Observability:
    """Predicted accuracy and separability of the 21 parameters.

    Attributes
    ----------
    information : ndarray (24, 24)
        Fisher information of [21 parameters, phi0] in SI.
    covariance : ndarray (21, 21) or None
        Marginal covariance of the 21 (None when rank deficient).
    rank : int
        Numerical rank of the 21 parameters' marginal information.
    unobservable : list of str
        Unobservable directions as combinations of parameter names.
    """

    information: np.ndarray
    covariance: np.ndarray | None
    rank: int
    unobservable: list[str]
    duration_s: float
    profile: str
    setup_rotvec: np.ndarray

    @property
    def sigma(self) -> np.ndarray:
        if self.covariance is None:
            return np.full(P.N_PARAMS, np.inf)
        return np.sqrt(np.diag(self.covariance))

    @property
    def ratio(self) -> np.ndarray:
        return P.ratio(self.sigma)

    @property
    def worst(self) -> tuple[str, float]:
        r = self.ratio
        i = int(np.argmax(r))
        return P.NAMES[i], float(r[i])

    @property
    def correlation(self) -> np.ndarray:
        s = self.sigma
        return self.covariance / np.outer(s, s)

    def correlated_pairs(self, limit: float = CORRELATION_LIMIT) -> list[tuple[str, str, float]]:
        if self.covariance is None:
            return []
        rho = self.correlation
        out = [(P.NAMES[i], P.NAMES[j], float(rho[i, j]))
               for i, j in itertools.combinations(range(P.N_PARAMS), 2) if abs(rho[i, j]) > limit]
        return sorted(out, key=lambda t: -abs(t[2]))

    def scaled_information(self) -> np.ndarray:
        """Marginal information of the 21, in units of the requirements (dimensionless)."""
        return _marginal(self.information) * np.outer(P.REQUIREMENTS_SI, P.REQUIREMENTS_SI)

    def criteria(self) -> dict[str, float]:
        """D-, A-, E-criteria and condition number of the requirement-scaled information.

        D: log det of the scaled information (larger is better); A: trace of
        the scaled covariance, i.e. sum of (sigma/requirement)^2 (smaller is
        better); E: smallest eigenvalue of the scaled information (larger is
        better).
        """
        ev = np.linalg.eigvalsh(self.scaled_information())
        if ev[0] <= 0:
            return {"D": -math.inf, "A": math.inf, "E": 0.0, "condition": math.inf}
        return {"D": float(np.sum(np.log(ev))), "A": float(np.sum(1.0 / ev)),
                "E": float(ev[0]), "condition": float(ev[-1] / ev[0])}


def _marginal(info: np.ndarray) -> np.ndarray:
    """Information of the 21 after eliminating the initial attitude (Schur complement)."""
    a = info[:P.N_PARAMS, :P.N_PARAMS]
    b = info[:P.N_PARAMS, PHI0]
    c = info[PHI0, PHI0]
    return a - b @ np.linalg.solve(c, b.T)


def _unobservable(evals: np.ndarray, evecs: np.ndarray, tol: float) -> list[str]:
    """Null directions of the requirement-scaled information, as sparse name combinations.

    The null space has no preferred basis, so it is put in reduced row-echelon
    form: each direction then has one pivot parameter and as few others as the
    physics forces (e.g. ``+1.00*saz -0.02*baz``: z bias and scale factor only
    ever seen together). Coefficients are in units of each requirement.
    """
    from scipy.linalg import qr

    null = evecs[:, evals <= tol].T  # (k, 21)
    _, _, piv = qr(null, pivoting=True)
    k = null.shape[0]
    basis = np.linalg.solve(null[:, piv[:k]], null)  # identity on the pivot columns
    out = []
    for row in basis:
        idx = [i for i in np.argsort(-np.abs(row)) if abs(row[i]) > 0.01][:6]
        out.append(" ".join(f"{row[i]:+.2f}*{P.NAMES[i]}" for i in idx))
    return out


def from_information(info: np.ndarray, duration_s: float, profile: str,
                     setup_rotvec) -> Observability:
    M = _marginal(info)
    D = P.REQUIREMENTS_SI
    Ms = M * np.outer(D, D)
    evals, evecs = np.linalg.eigh(Ms)
    tol = max(evals[-1], 1e-300) * 1e-12
    rank = int(np.sum(evals > tol))
    cov = None
    unobs = []
    if rank == P.N_PARAMS:
        cov = ((evecs / evals) @ evecs.T) * np.outer(D, D)
    else:
        unobs = _unobservable(evals, evecs, tol)
    return Observability(information=info, covariance=cov, rank=rank, unobservable=unobs,
                         duration_s=duration_s, profile=profile,
                         setup_rotvec=np.asarray(setup_rotvec, dtype=float))


@dataclass(frozen=True)
class NominalRun:
    """The error-free trajectory of a sequence, sampled for the linear model.

    Observation intervals are the estimator's while turning (``MOVE_STEP_S``)
    and ``ANALYSIS_REST_STEP_S`` at rest. At rest the attitude is constant, so
    a few sub-samples per interval give the moments exactly but for the
    ``tau^2`` weighting of a term that is itself ``(omega_ie T)^2`` small;
    while turning, sub-samples are at most ``FLIP_SUBSAMPLE_DEG`` apart, so
    the mid-sample attitude is good to ``(0.5 deg)^2 / 8 ~ 1e-5``.
    """

    time_nav: np.ndarray  # (n + 1,) sample boundaries, 0 first
    C_b_n: np.ndarray  # (n + 1, 3, 3)
    dtheta: np.ndarray  # (n, 3)
    dv: np.ndarray  # (n, 3)
    grid: ObservationGrid


ANALYSIS_REST_STEP_S = 5.0  # at rest; 1 s (the estimator's) changes no sigma by more than 0.2 %
REST_SUBSAMPLES = 4
FLIP_SUBSAMPLE_DEG = 0.5


def nominal_samples(tl) -> tuple[np.ndarray, np.ndarray]:
    """Sample end times and observation bounds (indices into ``[0] + times``) of a timeline."""
    times, bounds = [np.zeros(1)], [0]
    n = 0
    for t0, t1, rate in zip(tl.t0, tl.t1, tl.rate):
        step = ANALYSIS_REST_STEP_S if rate == 0.0 else MOVE_STEP_S
        m = max(1, int(round((t1 - t0) / step)))
        sub = REST_SUBSAMPLES if rate == 0.0 else max(
            1, int(math.ceil(abs(math.degrees(rate)) * (t1 - t0) / m / FLIP_SUBSAMPLE_DEG)))
        edges = np.linspace(t0, t1, m * sub + 1)[1:]
        edges[-1] = t1
        times.append(edges)
        bounds.extend(n + sub * np.arange(1, m + 1))
        n += m * sub
    return np.concatenate(times), np.array(bounds)


def nominal_run(seq: Sequence, latitude_rad: float, height_m: float, setup_rotvec) -> NominalRun:
    tl = timeline(seq)
    R = rotvec_to_dcm(np.asarray(setup_rotvec, dtype=float))
    cfg = SimConfig(latitude_rad=latitude_rad, height_m=height_m)
    t_nav, bounds = nominal_samples(tl)
    _, dtheta, dv = true_increments(tl, R, cfg, time_s=t_nav[1:])
    C = np.einsum("ij,njk->nik", R, nominal_attitude(tl, t_nav))
    return NominalRun(t_nav, C, dtheta, dv, ObservationGrid(bounds))


@functools.lru_cache(maxsize=64)
def _noise(T_bytes: bytes, latitude_rad: float, gravity_mps2: float, profile: NoiseProfile):
    """Whitening of an interval pattern: shared by every mounting of one sequence."""
    return noise_model(state_matrix(latitude_rad, gravity_mps2), np.frombuffer(T_bytes), profile)


def information(seq: Sequence, profile: NoiseProfile, latitude_rad: float, height_m: float = 0.0,
                setup_rotvec=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Fisher information (24 x 24, SI) of [21 parameters, phi0] for one base mounting."""
    g = earth.gravity(latitude_rad, height_m)
    nom = nominal_run(seq, latitude_rad, height_m, setup_rotvec)
    T = np.diff(nom.time_nav[nom.grid.bounds])
    noise = _noise(T.tobytes(), latitude_rad, g, profile)
    H = observation_jacobian(nom.C_b_n, nom.dtheta, nom.dv, nom.time_nav, nom.grid,
                             latitude_rad, g, noise.Phi_vv)
    Hw = whiten(noise.whitener, H).reshape(-1, N_UNKNOWN)
    return Hw.T @ Hw


def analyze(seq: Sequence, profile: NoiseProfile, latitude_rad: float, height_m: float = 0.0,
            setup_rotvec=(0.0, 0.0, 0.0)) -> Observability:
    """Observability of a sequence at one base mounting."""
    info = information(seq, profile, latitude_rad, height_m, setup_rotvec)
    return from_information(info, seq.duration_s, profile.name, setup_rotvec)


@dataclass(frozen=True)
class Robustness:
    """Observability over the +-tolerance box of base mountings."""

    nominal: Observability
    worst: Observability  # the mounting with the largest worst ratio
    per_parameter_worst_sigma: np.ndarray  # (21,) SI, max over the box of each sigma
    points: int
    tolerance_deg: float

    @property
    def per_parameter_worst_ratio(self) -> np.ndarray:
        return P.ratio(self.per_parameter_worst_sigma)


def analyze_tolerance(seq: Sequence, profile: NoiseProfile, latitude_rad: float,
                      height_m: float = 0.0, tolerance_deg: float = 3.0) -> Robustness:
    """Worst case over the 27 corner/edge/face/centre mountings of the tolerance box."""
    nominal = analyze(seq, profile, latitude_rad, height_m)
    if tolerance_deg == 0:
        return Robustness(nominal, nominal, nominal.sigma, 1, 0.0)
    worst, per_param = nominal, nominal.sigma.copy()
    levels = (-tolerance_deg, 0.0, tolerance_deg)
    count = 1
    for e, n, u in itertools.product(levels, levels, levels):
        if e == n == u == 0.0:
            continue
        obs = analyze(seq, profile, latitude_rad, height_m, np.radians([e, n, u]))
        count += 1
        per_param = np.maximum(per_param, obs.sigma)
        if obs.worst[1] > worst.worst[1]:
            worst = obs
    return Robustness(nominal, worst, per_param, count, tolerance_deg)


def accel_scale_bound(duration_s: float, profile: NoiseProfile, gravity_mps2: float) -> float:
    """Best possible worst ratio of the accelerometer scale factors (conventions.md).

    Gravity is their only excitation and ``sum f_i^2 = g^2``: the three share
    at most ``g^2 T / VRW^2`` of information, so at best each gets a third,
    ``sigma >= VRW sqrt(3 / T) / g``.
    """
    sigma = profile.vrw * math.sqrt(3.0 / duration_s) / gravity_mps2
    return 3.0 * sigma / P.REQUIREMENTS_SI[P.ACCEL_SCALE][0]


