"""Iterated least squares for the 21 parameters from a run (the paper's 2.3.1-2.3.5).

Each iteration compensates the raw increments with the current estimate,
navigates on the stationary base, and fits the navigation velocity errors
with the linearised model of :mod:`calib.jacobian` weighted by the exact
noise structure of :mod:`calib.noise` (a Gauss-Newton step of the GLS
problem). The unknowns are the 21 parameters, the initial attitude error
and any optional terms switched on (:mod:`calib.extras`); nothing about the
heading is assumed: the first guess comes from levelling and gyrocompassing
on the first rest. A profile with Gauss-Markov bias instability re-weights
the observations along the navigated attitude.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import earth
from . import params as P
from . import sanity
from .errormodel import ErrorModel
from .errors import CalibError
from . import extras as X
from .extras import Extras
from .information import UNKNOWN_NAMES, null_directions
from .jacobian import N_UNKNOWN, PHI0, default_grid, observation_jacobian, state_matrix
from .noise import noise_model, whiten
from .profiles import NoiseProfile
from .strapdown import navigate
from .transform import rotvec_to_dcm

MOTION_THRESHOLD = 0.01  # rad/s: far above Earth rate + bias + noise, far below a flip
MIN_ALIGN_S = 10.0
PHI0_SCALE = 1e-4  # rad, for scaling the normal equations only


@dataclass(frozen=True)
class Segmentation:
    """Which samples are turning, and the first rest used for alignment."""

    moving: np.ndarray  # (n,) bool
    first_rest_end: int  # samples [0, first_rest_end) are the first rest


def _grow(moving: np.ndarray, samples: int = 2) -> np.ndarray:
    """Widen turning stretches by ``samples`` each side: partial samples at a flip's ends turn too."""
    grown = moving.copy()
    for s in range(1, samples + 1):
        grown[s:] |= moving[:-s]
        grown[:-s] |= moving[s:]
    return grown


def detect_motion(dtheta: np.ndarray, dt: np.ndarray, where: str = "run") -> Segmentation:
    """Rest/rotation segments from the gyro increments alone."""
    rate = np.linalg.norm(dtheta, axis=1) / dt
    grown = _grow(rate > MOTION_THRESHOLD)
    motion = sanity.diagnose_motion(dtheta, dt, MOTION_THRESHOLD)
    if not motion.has_flip:  # vibration or quantisation spikes alone are no flip
        raise sanity.never_rotates(motion, MOTION_THRESHOLD, where)
    first = int(np.argmax(grown))
    return Segmentation(moving=grown, first_rest_end=first)


def coarse_alignment(dtheta: np.ndarray, dv: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """``C_b_n`` from levelling and gyrocompassing over a rest segment."""
    T = dt.sum()
    f = dv.sum(axis=0) / T
    w = dtheta.sum(axis=0) / T
    up = f / np.linalg.norm(f)
    east = np.cross(w, up)
    east /= np.linalg.norm(east)
    north = np.cross(up, east)
    return np.vstack([east, north, up])


@dataclass
class Fit:
    """Everything an iteration leaves behind (SI)."""

    values: np.ndarray  # (21,)
    C_b_n0: np.ndarray  # (3, 3) at the run's start instant
    covariance: np.ndarray  # (24 + e, 24 + e) of [params, phi0, extras]
    converged: bool
    iterations: int
    residual_rms_mps: float
    chi2_per_dof: float
    n_observations: int
    history: list = field(default_factory=list)
    extras: Extras = X.NONE
    extra_values: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (e,) SI

    @property
    def sigma(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance)[:P.N_PARAMS])

    @property
    def extra_sigma(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance)[N_UNKNOWN:])

    @property
    def correlation(self) -> np.ndarray:
        d = np.sqrt(np.diag(self.covariance))
        return self.covariance / np.outer(d, d)


def _scale(extras: Extras = X.NONE) -> np.ndarray:
    return np.concatenate([P.REQUIREMENTS_SI, np.full(3, PHI0_SCALE), extras.scale_si])


def scaled_design(Hw: np.ndarray, extras: Extras = X.NONE):
    """Whitened observation matrix with columns in units of the requirements, and the scale.

    The optional terms are scaled by their typical size (:mod:`calib.extras`).
    """
    D = _scale(extras)
    return Hw.reshape(-1, Hw.shape[-1]) * D, D


WEAK_INFORMATION = 1e-6  # scaled by the requirements: sigma > 1000 x requirement


def solve_information(N: np.ndarray, where: str = "run", names=None):
    """Inverse of a requirement-scaled information matrix.

    Directions the run cannot observe (numerically singular, or so weak that
    their sigma exceeds 1000 times the requirement) are refused by name
    instead of being returned as numbers.
    """
    evals, evecs = np.linalg.eigh(N)
    weak = evals < max(evals[-1] * 1e-14, WEAK_INFORMATION)
    if np.any(weak):
        dirs = null_directions(evecs, weak, names or UNKNOWN_NAMES)
        raise CalibError(f"the run cannot observe {len(dirs)} direction(s) of the parameters "
                         "(in units of each requirement): " + "; ".join(dirs), where,
                         "use a sequence that excites them; `seqdesign analyze` shows which")
    return (evecs / evals) @ evecs.T


def calibrate(time_s: np.ndarray, dtheta_m: np.ndarray, dv_m: np.ndarray, latitude_rad: float,
              gravity_mps2: float, profile: NoiseProfile, moving: np.ndarray | None = None,
              max_iterations: int = 12, tol_sigma: float = 1e-3, where: str = "run",
              extras: Extras = X.NONE) -> Fit:
    """Identify the 21 parameters, the initial attitude and any optional terms from raw increments.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        End time of each sample.
    dtheta_m, dv_m : ndarray, shape (n, 3)
        Raw (uncompensated) increments.
    latitude_rad, gravity_mps2 : float
    profile : NoiseProfile
        Weights the observations and scales the covariance.
    moving : ndarray of bool, optional
        Which samples turn (from the sequence); detected from the gyros if None.
    max_iterations : int
    tol_sigma : float
        Converged when every correction is below this fraction of its sigma.
    extras : Extras
        Optional terms (:mod:`calib.extras`) to estimate with the 21.

    Returns
    -------
    Fit
    """
    dt = np.diff(np.concatenate([[time_s[0] - (time_s[1] - time_s[0])], time_s]))
    sanity.check_latitude(latitude_rad, where)
    sanity.check_rates(dtheta_m, dt, where)
    seg = detect_motion(dtheta_m, dt, where)
    if moving is not None:
        seg = Segmentation(moving=moving, first_rest_end=int(np.argmax(moving)))
    t_align = float(dt[:seg.first_rest_end].sum())
    if t_align < MIN_ALIGN_S:
        raise CalibError(f"the first rest lasts {t_align:.1f} s, too short to align "
                         f"(needs >= {MIN_ALIGN_S:.0f} s)", where,
                         "start the run with the IMU at rest")
    sanity.check_rest_rate(dtheta_m, dt, slice(0, seg.first_rest_end), where)
    sanity.check_gravity(dv_m, dt, slice(0, seg.first_rest_end), gravity_mps2, where)
    sanity.check_saturation(dtheta_m, dv_m, where)
    sanity.check_rests(dv_m, dt, seg.moving, profile.vrw, where)
    fs = 1.0 / np.median(dt)
    grid = default_grid(seg.moving, fs)
    t_nav = np.concatenate([[time_s[0] - dt[0]], time_s])
    A, T = state_matrix(latitude_rad, gravity_mps2), np.diff(t_nav[grid.bounds])
    mid = (grid.bounds[:-1] + grid.bounds[1:]) // 2
    values = np.zeros(P.N_PARAMS)
    extra_values = np.zeros(extras.n)
    names = UNKNOWN_NAMES + extras.names
    omega_ie_n = earth.omega_ie_n(latitude_rad)
    C0 = coarse_alignment(dtheta_m[:seg.first_rest_end], dv_m[:seg.first_rest_end],
                          dt[:seg.first_rest_end])
    # Until the first navigation, the Earth's turn as seen at the start attitude.
    turn = X.earth_turn(np.broadcast_to(C0, (len(dt), 3, 3)), omega_ie_n, dt)
    noise = None
    history = []
    converged = False
    N = cov = None
    for it in range(1, max_iterations + 1):
        model = ErrorModel(values)
        dth, dvv = model.compensate(dtheta_m, dv_m, dt)
        if extras.n:
            dvv = X.compensate(extras.unpack(extra_values), dth, dv_m, dt,
                               lambda x: model.compensate(dtheta_m, x, dt)[1], turn)
        nav = navigate(dth, dvv, time_s, C0, latitude_rad, gravity_mps2, t0=t_nav[0])
        if extras.n:  # the Earth's turn in the body, for the next compensation
            turn = X.earth_turn(0.5 * (nav.C_b_n[1:] + nav.C_b_n[:-1]), omega_ie_n, dt)
        if noise is None or (profile.has_gauss_markov and it <= 3):
            # Gauss-Markov bias noise enters through the attitude (C_b_n b): its weights follow
            # the navigated attitude while the Jacobian does. Phi_vv does not depend on it.
            noise = noise_model(A, T, profile, C_b_n=nav.C_b_n[mid])
            W, Phi_vv = noise.whitener, noise.Phi_vv
        y = nav.v_n[grid.bounds]
        z = y[1:] - np.einsum("kij,kj->ki", Phi_vv, y[:-1])
        if not np.all(np.isfinite(z)) or np.abs(y).max() > 1e5:
            raise CalibError(f"the fit diverged at iteration {it} (navigation velocity "
                             f"{np.abs(y).max():.3g} m/s)", where,
                             "check units and that the run is a stationary-base calibration")
        if N is None or it <= 3:
            # The Jacobian changes little once the big errors are compensated.
            H = observation_jacobian(nav.C_b_n, dth, dvv, nav.time_s, grid, latitude_rad,
                                     gravity_mps2, Phi_vv, extras)
            Hs, D = scaled_design(whiten(W, H), extras)
            N = Hs.T @ Hs
            cov_scaled = solve_information(N, where, names)
            cov = cov_scaled * np.outer(D, D)
        zw = whiten(W, z[:, :, None]).reshape(-1)
        delta_scaled = cov_scaled @ (Hs.T @ zw)
        delta = D * delta_scaled
        values = values + delta[:P.N_PARAMS]
        extra_values = extra_values + delta[N_UNKNOWN:]
        C0 = rotvec_to_dcm(delta[PHI0]) @ C0
        step = np.max(np.abs(delta) / np.sqrt(np.diag(cov)))
        resid = zw - Hs @ delta_scaled
        history.append({"iteration": it, "max_step_sigma": float(step),
                        "chi2_per_dof": float(resid @ resid / max(1, resid.size - delta.size))})
        if step < tol_sigma:
            converged = True
            break
    # Residual in m/s of the velocity changes after the last correction.
    z_fit = z - np.einsum("kin,n->ki", H, delta)
    return Fit(values=values, C_b_n0=C0, covariance=cov, converged=converged, iterations=it,
               residual_rms_mps=float(np.sqrt(np.mean(z_fit ** 2))),
               chi2_per_dof=history[-1]["chi2_per_dof"], n_observations=int(z.size),
               history=history, extras=extras, extra_values=extra_values)


def sequence_motion(seq, time_s: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Per sample, whether a sequence says the IMU turns (grown by two samples as detected motion is)."""
    from .sequence import timeline

    tl = timeline(seq)
    start = time_s - dt - (time_s[0] - dt[0])
    end = time_s - (time_s[0] - dt[0])
    moving = np.zeros(len(time_s), dtype=bool)
    for a, b in zip(tl.t0[~tl.rest], tl.t1[~tl.rest]):
        moving |= (end > a) & (start < b)
    return _grow(moving)


def check_sequence_matches(seq, detected: np.ndarray, from_sequence: np.ndarray, dt: np.ndarray,
                           where: str) -> None:
    """Refuse a sequence file whose flips are not where the log turns."""
    def runs(mask):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
        return edges[::2], edges[1::2]

    d0, _ = runs(detected)
    s0, _ = runs(from_sequence)
    if len(d0) != len(s0):
        raise CalibError(f"the sequence {seq.name!r} has {len(s0)} flips where the log turns "
                         f"{len(d0)} times", where,
                         "give the sequence the run was made with, or omit --sequence")
    t = np.cumsum(dt)
    offsets = np.abs(t[d0] - t[s0])
    if offsets.max() > 2.0:
        k = int(np.argmax(offsets))
        raise CalibError(f"flip {k + 1} of sequence {seq.name!r} starts at {t[s0[k]]:.2f} s but the "
                         f"log turns at {t[d0[k]]:.2f} s", where,
                         "give the sequence the run was made with, or omit --sequence")
