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

The run is streamed (:mod:`calib.stream`): each navigation is one pass over
the samples, a chunk at a time, that leaves only per-interval quantities,
and :func:`fit_intervals` navigates only while a step can still matter.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from . import earth, sanity
from . import extras as X
from . import params as P
from .errormodel import ErrorModel
from .errors import CalibError
from .extras import Extras
from .gyrocompass import rest_gyrocompass
from .information import UNKNOWN_NAMES, ScaledInverse, eliminate, scaled_inverse
from .jacobian import (
    N_UNKNOWN,
    PHI0,
    default_grid,
    observation_jacobian,
    observation_matrix,
    sensitivities,
    state_matrix,
)
from .matexp import expm  # not scipy.linalg: its import costs 0.15 s per command
from .noise import noise_model, smooth, whiten
from .profiles import NoiseProfile
from .requirements import PAPER, Requirements
from .seqinfer import infer_sequence
from .strapdown import navigate, sample_intervals
from .stream import Site, array_chunks, chunk_cuts, navigate_pass
from .transform import rotvec_to_dcm

MOTION_THRESHOLD = 0.01  # rad/s: far above Earth rate + bias + noise, far below a flip
# The first rest seeds Gauss-Newton by levelling and gyrocompassing (the fit then estimates the
# initial attitude error itself); 8 s levels a navigation-grade unit to ~1e-5 rad. It sits below
# the designs' shortest dwell (10 s) by more than motion detection takes from a rest's ends, so a
# designed sequence whose first dwell is at the minimum still aligns (seqdesign.design checks
# --min-dwell-s against it).
MIN_ALIGN_S = 8.0
FIRST_REST_MARGIN_S = 1.0  # what motion detection may take from the first rest's end, at most
PHI0_SCALE = 1e-4  # rad, for scaling the normal equations only
# Past the third iteration the Jacobian is rebuilt only while the last step exceeded this many
# sigmas: below it the linearisation error is far below the convergence tolerance.
RELINEARISE_STEP_SIGMA = 0.1
# The observations are linear in the attitude noise; gravity leaks through a tilt phi at second
# order, g phi^2 / 2. When that term, for the attitude wander the gyro noise builds over the run,
# exceeds this fraction of the accelerometer-bias resolution vrw / sqrt(T), the fit re-linearises
# about the smoothed attitude noise (:func:`attitude_feedback`). A MEMS unit's
# 30-min run is at about 40, a tactical unit's at 0.15, a navigation-grade one's at 1e-8.
ATTITUDE_FEEDBACK_RATIO = 0.5
# The feedback is updated after this many Gauss-Newton steps and then held. The first update
# moves the estimate by several sigmas (the leak it removes); the later ones by hundredths of
# a sigma, converging at 0.07-0.65 per update (measured on MEMS paper-9pos runs). Held after
# 4 updates, the estimate is within 0.002 sigma of the fully iterated one (measured on two runs
# iterated 30 times), and the plain loop ends the fit with its usual convergence test.
FEEDBACK_UPDATES = 4
# The first update waits for a step below this many sigmas: the residuals of the first step from
# a MEMS unit's 1000 deg/h (hundreds of sigmas) are mostly linearisation error, not noise.
FEEDBACK_START_SIGMA = 100.0
MAX_ITERATIONS = 12
WANDER_MAX_ITERATIONS = 30  # measured: 6-15 iterations on MEMS paper-9pos runs


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


def motion_window(arw: float, period_s: float) -> int:
    """Samples to average a gyro of ``arw`` (rad/sqrt(s)) over: its noise 5x below the threshold."""
    return max(1, int(math.ceil((5.0 * arw / MOTION_THRESHOLD) ** 2 / period_s)))


def windowed_motion(window: int, steady: np.ndarray) -> bool:
    """Whether motion is judged on windowed rates less the ``steady`` rate (noise or a MEMS bias)."""
    return window > 1 or float(np.linalg.norm(steady)) > 0.1 * MOTION_THRESHOLD


def window_rate(
    angle: np.ndarray, clock: np.ndarray, i: np.ndarray, n: int, window: int, offset: int = 0
) -> np.ndarray:
    """Mean rate (norm) over the window about each sample ``i`` of a run of ``n`` samples.

    ``angle`` (m, 3) and ``clock`` (m,) are the running sums of the steady-free
    increments and of the intervals, ``angle[j - offset]`` being the sum of the
    first ``j`` samples: a whole run (``offset`` 0) or the part of it a stream holds.
    """
    half = window // 2
    lo = np.clip(i - half, 0, n) - offset
    hi = np.clip(i + window - half, 0, n) - offset
    return np.linalg.norm(angle[hi] - angle[lo], axis=1) / (clock[hi] - clock[lo])


def detect_motion(dtheta: np.ndarray, dt: np.ndarray, where: str = "run", arw: float = 0.0) -> Segmentation:
    """Rest/rotation segments from the gyro increments alone.

    A noisy gyro (``arw``, rad/sqrt(s)) is averaged over a window long enough
    for its noise to stay five times below the motion threshold, and a large
    constant rate (a MEMS bias) is removed first; a navigation-grade gyro is
    judged sample by sample, as before.
    """
    window = motion_window(arw, float(np.median(dt)))
    # Rests dominate a calibration run. Column by column: one whole-run temporary, not four.
    steady = np.array([np.median(dtheta[:, i] / dt) for i in range(3)])
    if windowed_motion(window, steady):
        rate_vec = dtheta / dt[:, None]
        angle = np.cumsum(np.vstack([np.zeros((1, 3)), (rate_vec - steady) * dt[:, None]]), axis=0)
        clock = np.concatenate([[0.0], np.cumsum(dt)])
        rate = window_rate(angle, clock, np.arange(len(dt)), len(dt), window)
        grown = _grow(rate > MOTION_THRESHOLD, 2 + window)
    else:
        rate = sanity.row_norm(dtheta) / dt  # = np.linalg.norm(dtheta, axis=1), 10x faster
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
    """Everything an iteration leaves behind (SI).

    ``covariance`` is over ``[21 parameters, phi0, extras]``. When the run
    leaves some directions unobserved and the fit was asked to be partial,
    the weak combinations are left at their minimum-norm values: the rows of
    the parameters that take part in them are not estimable (``estimable``
    false, sigma inf) and ``null_directions`` names the combinations.
    """

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
    estimable: np.ndarray | None = None  # (21 + e,) bool, over [params, extras]
    null_directions: list = field(default_factory=list)

    def _std(self) -> np.ndarray:
        d = np.sqrt(np.diag(self.covariance)).copy()
        if self.estimable is not None:
            d[_param_index(len(d))[~self.estimable]] = np.inf
        return d

    @property
    def sigma(self) -> np.ndarray:
        return self._std()[: P.N_PARAMS]

    @property
    def extra_sigma(self) -> np.ndarray:
        return self._std()[N_UNKNOWN:]

    @property
    def correlation(self) -> np.ndarray:
        d = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = self.covariance / np.outer(d, d)
        if self.estimable is not None:
            bad = _param_index(len(d))[~self.estimable]
            rho[bad, :] = np.nan
            rho[:, bad] = np.nan
        return rho


def _param_index(n_total: int) -> np.ndarray:
    """Indices of [21 parameters, extras] in the full unknown vector (phi0 skipped)."""
    return np.r_[0 : P.N_PARAMS, N_UNKNOWN:n_total]


def _scale(extras: Extras = X.NONE, requirements: Requirements = PAPER) -> np.ndarray:
    return np.concatenate([requirements.si, np.full(3, PHI0_SCALE), extras.scale_si])


def scaled_design(Hw: np.ndarray, extras: Extras = X.NONE, requirements: Requirements = PAPER):
    """Whitened observation matrix with columns in units of the requirements, and the scale.

    The optional terms are scaled by their typical size (:mod:`calib.extras`).
    """
    D = _scale(extras, requirements)
    return Hw.reshape(-1, Hw.shape[-1]) * D, D


@dataclass(frozen=True)
class Solution:
    """Scaled covariance of the unknowns and what the run leaves unobserved."""

    covariance: np.ndarray  # scaled, (24 + e, 24 + e)
    estimable: np.ndarray  # (21 + e,) over [params, extras]
    null_directions: list
    null_basis: np.ndarray | None = None  # (21 + e, k) scaled, orthonormal

    def project(self, x_scaled: np.ndarray) -> np.ndarray:
        """Remove the unobserved combinations from scaled [params, extras] values."""
        if self.null_basis is None or self.null_basis.shape[1] == 0:
            return x_scaled
        return x_scaled - self.null_basis @ (self.null_basis.T @ x_scaled)


def solve_information(
    N: np.ndarray, where: str = "run", names=None, partial: bool = False, nominal=None
) -> Solution:
    """Covariance of the unknowns from a requirement-scaled information matrix.

    Observability is judged by :mod:`calib.information`'s one rule on the
    information of [21, extras] with the initial attitude eliminated (as the
    analyser does). A run that leaves directions unobserved is refused by
    naming the parameters it cannot estimate, unless ``partial``: then the
    weak combinations are constrained to zero (a minimum-norm solution)
    and the estimable parameters keep the variance any solution would give.

    ``nominal``, a callable returning the :class:`ScaledInverse` of the
    run's nominal (error-free) trajectory or None, decides instead of the
    run's own trajectory when that one leaves directions unobserved: as the
    analyser judges, and unmoved by the errors not yet estimated.
    """
    names = tuple(names or UNKNOWN_NAMES)
    kept = [n for i, n in enumerate(names) if not P.N_PARAMS <= i < N_UNKNOWN]
    inv = scaled_inverse(eliminate(N, PHI0), kept)
    if inv.full_rank:
        evals, evecs = np.linalg.eigh(N)
        return Solution((evecs / evals) @ evecs.T, inv.estimable, [])
    judged = nominal() if nominal is not None else None
    if judged is not None and not judged.full_rank:
        # The nominal trajectory says which directions are unobserved and which parameters are
        # estimable. Held fixed, those directions stay at zero in the estimate, so they cannot
        # bend the navigated trajectory the next Jacobians are taken along.
        inv = judged
    dirs = inv.null_directions()
    if not partial:
        raise CalibError(
            f"the run cannot observe {len(dirs)} direction(s) of the parameters, so it cannot "
            f"estimate {', '.join(inv.not_estimable()) or 'them'} on their own; unobserved "
            "(in units of each requirement): " + "; ".join(dirs),
            where,
            "use a sequence that excites them (`seqdesign analyze` shows which), or fit the "
            "estimable part with --partial",
        )
    null_full = np.zeros((N.shape[0], inv.null_basis.shape[1]))
    null_full[_param_index(N.shape[0])] = inv.null_basis
    u, _, _ = np.linalg.svd(null_full, full_matrices=True)
    Q = u[:, null_full.shape[1] :]  # unknowns with no component along the weak subspace
    cov = Q @ np.linalg.inv(Q.T @ N @ Q) @ Q.T
    return Solution(cov, inv.estimable, dirs, inv.null_basis)


def nominal_decision(
    seq, latitude_rad: float, profile: NoiseProfile, extras: Extras, requirements: Requirements, names
) -> ScaledInverse:
    """What the error-free trajectory of ``seq`` observes, by :mod:`calib.information`'s rule."""
    from .nominal import information_along, nominal_run

    nom = nominal_run(seq, latitude_rad, 0.0, np.zeros(3))
    info = information_along(nom, profile, latitude_rad, earth.gravity(latitude_rad), extras)
    D = _scale(extras, requirements)
    kept = [n for i, n in enumerate(names) if not P.N_PARAMS <= i < N_UNKNOWN]
    return scaled_inverse(eliminate(info * np.outer(D, D), PHI0), kept)


def start_values(dtheta_m: np.ndarray, dt: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """Where Gauss-Newton starts, from the mean gyro rate over all rests (:func:`start_from_rests`)."""
    rest = ~moving
    return start_from_rests(dtheta_m[rest].sum(axis=0) / dt[rest].sum())


def start_from_rests(mean_rate: np.ndarray) -> np.ndarray:
    """Where Gauss-Newton starts: zero, or the gyro biases when they dwarf the Earth rate.

    A gyro bias of 1000 deg/h (a MEMS unit) tilts an uncompensated navigation
    by hundreds of degrees in half an hour, far outside what a linearisation
    can correct. The mean rate over all rests (``mean_rate``, rad/s) is the
    bias to within the Earth rate (15 deg/h), which the rests' different
    attitudes average down: from there the fit is in its linear range. A
    navigation-grade unit, whose biases are far below the Earth rate, starts
    from zero as it always did.
    """
    values = np.zeros(P.N_PARAMS)
    if np.linalg.norm(mean_rate) > 2.0 * earth.RATE:
        values[P.GYRO_BIAS] = mean_rate
    return values


def attitude_wander_ratio(profile: NoiseProfile, duration_s: float, gravity_mps2: float) -> float:
    """Second-order gravity through the run's attitude wander over the accelerometer-bias resolution.

    White gyro noise makes the tilt a random walk of variance ``arw^2 T`` at
    the run's end; gravity leaks through it as ``g phi^2 / 2``, which the
    linear model does not have. The bias resolution of a run of length ``T``
    is ``vrw / sqrt(T)``.
    """
    if profile.vrw <= 0.0:
        return math.inf
    return 0.5 * gravity_mps2 * profile.arw**2 * duration_s**1.5 / profile.vrw


@dataclass(frozen=True)
class AttitudeFeedback:
    """A gyro correction that takes the estimated attitude noise out of the navigation.

    ``body_rate`` (K, 3), rad/s per interval, is added to the compensated gyro
    increments; ``dv`` (K + 1, 3), m/s at the interval ends, is its effect on
    the navigation velocity to first order, which the observations add back.
    """

    body_rate: np.ndarray
    dv: np.ndarray


@functools.lru_cache(maxsize=256)
def _rate_response(A_bytes: bytes, T: float) -> tuple[np.ndarray, np.ndarray]:
    """``Phi = exp(A T)`` and the ``[phi, dv]`` response ``Gamma`` (6, 3) to a constant attitude rate."""
    M = np.zeros((9, 9))
    M[:6, :6] = np.frombuffer(A_bytes).reshape(6, 6)
    M[:3, 6:] = np.eye(3)
    E = expm(M * T)
    return E[:6, :6], E[:6, 6:]


def attitude_feedback(
    noise, residual: np.ndarray, A: np.ndarray, T: np.ndarray, C_mid: np.ndarray
) -> AttitudeFeedback:
    """Feed the smoothed attitude noise back into the reference trajectory.

    The observations are linear in the noise part of the attitude error
    (:mod:`calib.noise`), which a MEMS gyro's noise walks by degrees over a
    run: gravity then leaks through at second order, ``g phi^2 / 2``, tens of
    times the accelerometer-bias resolution, and the fit is biased. The
    smoothed noise ``phi_hat`` given the fit's residuals (:func:`calib.noise.smooth`)
    is taken out of the next navigation by a gyro correction, and its
    first-order effect on the velocity is added back to the observations: to
    first order nothing changes (the same GLS problem), while the neglected
    terms shrink to second order in the smoothing error ``phi - phi_hat``.
    Iterated with Gauss-Newton, this is an iterated extended smoother.
    """
    phi_hat = smooth(list(noise.models), residual)[:, :3]
    key = np.ascontiguousarray(A, dtype=float).tobytes()
    K = len(T)
    m, dv, rate = np.zeros(6), np.zeros((K + 1, 3)), np.empty((K, 3))
    for k in range(K):
        Phi, G = _rate_response(key, round(float(T[k]), 6))
        # The attitude rate u over interval k that brings the correction to -phi_hat at its end.
        u = np.linalg.solve(G[:3], -phi_hat[k + 1] - Phi[:3] @ m)
        m = Phi @ m + G @ u
        dv[k + 1] = m[3:]
        # A gyro error e in the body drives the attitude error by -C_b_n e (calib.jacobian).
        rate[k] = -C_mid[k].T @ u
    return AttitudeFeedback(rate, dv)


def _aitken(delta: np.ndarray, sigma: np.ndarray, last: np.ndarray | None):
    """Aitken's extrapolation of a linearly converging Gauss-Newton step.

    About a held attitude feedback the loop can converge linearly or settle
    in a two-cycle along the barely observable heading (measured: steps of
    0.24 sigma alternating in sign for 30 iterations on one MEMS run in 50):
    the held correction turns with the heading in the body while its
    first-order effect does not. When the step (in sigmas) is a multiple
    ``rho`` of the last, the remaining steps sum to ``delta / (1 - rho)``; it
    is taken only for ``-1.5 < rho < 0.5``, so it damps and never amplifies
    much. The fixed point is the same. Returns the step and the natural step
    in sigmas (the next call's ``last``).
    """
    u = delta / sigma
    if last is not None and np.linalg.norm(last) > 0 and np.linalg.norm(u) > 0:
        rho = float(u @ last / (last @ last))
        cos = float(u @ last / (np.linalg.norm(u) * np.linalg.norm(last)))
        if abs(cos) > 0.9 and -1.5 < rho < 0.5:
            delta = delta / (1.0 - rho)
    return delta, u


@dataclass
class FeedbackSchedule:
    """When the attitude feedback moves and how the steps about it are taken.

    The one schedule of both Gauss-Newton loops (:func:`fit_intervals` and the
    reference loop of ``calibrate(..., renavigate="always")``): the reference
    loop checks the streamed loop's navigation shortcut, not a different
    iteration, so they take the same steps. Without ``wander`` (the attitude
    wander of :func:`attitude_wander_ratio` is harmless) it does nothing.
    """

    wander: bool
    updates: int = 0  # feedback updates so far
    moved: int = 0  # the iteration whose residuals last moved it
    last: np.ndarray | None = None  # the last step in sigmas, for Aitken's rule

    @classmethod
    def for_run(cls, profile: NoiseProfile, duration_s: float, gravity_mps2: float):
        """On exactly when the run's attitude wander leaks gravity (:func:`attitude_wander_ratio`)."""
        return cls(attitude_wander_ratio(profile, duration_s, gravity_mps2) > ATTITUDE_FEEDBACK_RATIO)

    def limit(self, max_iterations: int | None) -> int:
        """Iterations allowed: ``max_iterations`` as given, else the default of the run's kind."""
        return max_iterations or (WANDER_MAX_ITERATIONS if self.wander else MAX_ITERATIONS)

    def pending(self) -> bool:
        """Whether the feedback has still to move: no convergence before it is held."""
        return self.wander and self.updates < FEEDBACK_UPDATES

    def due(self, step: float) -> bool:
        """Whether this step's residuals update the feedback (see FEEDBACK_UPDATES)."""
        return self.pending() and (self.updates > 0 or step < FEEDBACK_START_SIGMA)

    def moved_at(self, it: int) -> None:
        self.updates, self.moved = self.updates + 1, it

    def update(self, it: int, step: float, feedback, noise, z, H, delta, A, T, C_mid):
        """The feedback after iteration ``it``: re-estimated from the fit's residual
        ``z - H delta`` when :meth:`due`, else ``feedback`` unchanged.
        """
        if not self.due(step):
            return feedback
        self.moved_at(it)
        return attitude_feedback(noise, z - np.einsum("kin,n->ki", H, delta), A, T, C_mid)

    def settled(self, it: int) -> bool:
        """Whether iteration ``it`` and the one before it share the same feedback.

        Only then is the step a continuation of the last (geometric
        convergence, Aitken's rule).
        """
        return it > self.moved + 1

    def step(self, Hs, D, zw, sol, cov: np.ndarray, it: int):
        """The Gauss-Newton step (SI) and whitened residual after it; Aitken's once held."""
        delta, resid = _solve_step(Hs, D, zw, sol)
        if self.wander and self.updates == FEEDBACK_UPDATES:
            last = self.last if self.settled(it) else None
            delta, self.last = _aitken(delta, np.sqrt(np.diag(cov)), last)
            resid = zw - Hs @ (delta / D)
        return delta, resid


def check_run(
    dtheta_m: np.ndarray,
    dv_m: np.ndarray,
    dt: np.ndarray,
    latitude_rad: float,
    gravity_mps2: float,
    profile: NoiseProfile,
    moving: np.ndarray | None,
    where: str,
    requirements: Requirements = PAPER,
) -> Segmentation:
    """Refuse a log the fit cannot use, naming why; return where it turns.

    What is plausible follows the unit's class (its profile and requirements):
    a MEMS unit's biases of 1000 deg/h and 20 mg are not a log in wrong units.
    """
    sanity.check_latitude(latitude_rad, where)
    sanity.check_rates(dtheta_m, dt, where)
    seg = detect_motion(dtheta_m, dt, where, arw=profile.arw)
    if moving is not None:
        seg = Segmentation(moving=moving, first_rest_end=int(np.argmax(moving)))
    check_first_rest(dtheta_m, dv_m, dt, slice(0, seg.first_rest_end), gravity_mps2, where, requirements)
    sanity.check_saturation(dtheta_m, dv_m, where)
    sanity.check_rests(dv_m, dt, seg.moving, profile.vrw, where)
    return seg


def check_first_rest(
    dtheta_m: np.ndarray,
    dv_m: np.ndarray,
    dt: np.ndarray,
    rest: slice,
    gravity_mps2: float,
    where: str,
    requirements: Requirements = PAPER,
) -> None:
    """Refuse a first rest (samples ``rest``) too short to align on or that is no rest.

    What is plausible follows the unit's class (its requirements): a MEMS
    unit's biases of 1000 deg/h and 20 mg are not a log in wrong units.
    """
    req = requirements.si
    t_align = float(dt[rest].sum())
    if t_align < MIN_ALIGN_S:
        raise CalibError(
            f"the first rest lasts {t_align:.1f} s, too short to align (needs >= {MIN_ALIGN_S:.0f} s)",
            where,
            "start the run with the IMU at rest",
        )
    sanity.check_rest_rate(dtheta_m, dt, rest, where, float(req[P.GYRO_BIAS].max()))
    accel_class = sanity.CLASS_FACTOR * float(
        req[P.ACCEL_BIAS].max() / gravity_mps2 + req[P.ACCEL_SCALE].max()
    )
    sanity.check_gravity(dv_m, dt, rest, gravity_mps2, where, accel_class)


@dataclass
class _Problem:
    """The fixed data of one fit: the log, its site, the observation grid and the unknowns."""

    time_s: np.ndarray
    dtheta_m: np.ndarray
    dv_m: np.ndarray
    dt: np.ndarray
    latitude_rad: float
    gravity_mps2: float
    profile: NoiseProfile
    extras: Extras
    grid: object
    where: str

    @property
    def t_nav(self) -> np.ndarray:
        return np.concatenate([[self.time_s[0] - self.dt[0]], self.time_s])

    def compensate_and_navigate(self, values, extra_values, C0, turn, feedback=None):
        """Compensate the raw increments with the current estimate (and feedback) and navigate."""
        model = ErrorModel(values)
        dth, dvv = model.compensate(self.dtheta_m, self.dv_m, self.dt)
        if self.extras.n:
            dvv = X.compensate(
                self.extras.unpack(extra_values),
                dth,
                self.dv_m,
                self.dt,
                lambda x: model.compensate(self.dtheta_m, x, self.dt)[1],
                turn,
            )
        if feedback is not None:  # after the extra terms, as calib.stream applies it
            b = self.grid.bounds  # b[0] = 0 and b[-1] = n: every sample is in an interval
            dth = dth + np.repeat(feedback.body_rate, np.diff(b), axis=0) * self.dt[:, None]
        nav = navigate(dth, dvv, self.time_s, C0, self.latitude_rad, self.gravity_mps2, t0=self.t_nav[0])
        return dth, dvv, nav

    def observations(self, nav, Phi_vv, it: int, feedback=None) -> np.ndarray:
        """Velocity changes over the observation intervals, less the noise model's prediction."""
        y = nav.v_n[self.grid.bounds]
        return _observations(y if feedback is None else y - feedback.dv, Phi_vv, it, self.where)


def calibrate(
    time_s: np.ndarray,
    dtheta_m: np.ndarray,
    dv_m: np.ndarray,
    latitude_rad: float,
    gravity_mps2: float,
    profile: NoiseProfile,
    moving: np.ndarray | None = None,
    max_iterations: int | None = None,
    tol_sigma: float = 1e-3,
    where: str = "run",
    extras: Extras = X.NONE,
    partial: bool = False,
    requirements: Requirements = PAPER,
    sequence=None,
    renavigate: str = "when-needed",
) -> Fit:
    """Identify the 21 parameters, the initial attitude and any optional terms from raw increments.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        End time of each sample.
    dtheta_m, dv_m : ndarray, shape (n, 3)
        Raw (uncompensated) increments.
    latitude_rad, gravity_mps2 : float
        The site.
    profile : NoiseProfile
        Weights the observations and scales the covariance.
    moving : ndarray of bool, optional
        Which samples turn (from the sequence); detected from the gyros if None.
    max_iterations : int, optional
        Gauss-Newton iterations at most. Default: :data:`MAX_ITERATIONS`, or
        :data:`WANDER_MAX_ITERATIONS` for a run whose attitude noise needs
        the feedback of :func:`attitude_feedback`.
    tol_sigma : float
        Converged when every correction is below this fraction of its sigma.
    where : str
        Names the log in refusals.
    extras : Extras
        Optional terms (:mod:`calib.extras`) to estimate with the 21.
    partial : bool
        Fit the estimable part of a run that leaves directions unobserved
        instead of refusing it (:func:`solve_information`).
    requirements : Requirements
        Scale the unknowns, and so decide what counts as observed
        (:mod:`calib.information`).
    sequence : Sequence, optional
        The nominal sequence: on a run that leaves directions unobserved it
        decides which parameters are estimable, as the analyser does.
        Default: inferred from the navigation (:mod:`calib.seqinfer`).
    renavigate : {"when-needed", "always"}
        "when-needed" (default): stream the run through :func:`fit_intervals`,
        which navigates only while a step could still move the estimate by
        ``tol_sigma``; "always": the reference loop that re-navigates the
        whole run in memory at every iteration (for tests and benchmarks).

    Returns
    -------
    Fit
    """
    if renavigate not in ("when-needed", "always"):
        raise ValueError(f"renavigate must be 'when-needed' or 'always', not {renavigate!r}")
    dt = sample_intervals(time_s)
    seg = check_run(dtheta_m, dv_m, dt, latitude_rad, gravity_mps2, profile, moving, where, requirements)
    grid = default_grid(seg.moving, 1.0 / np.median(dt))
    first = slice(0, seg.first_rest_end)
    start = start_values(dtheta_m, dt, seg.moving)
    C0 = coarse_alignment(dtheta_m[first] - start[P.GYRO_BIAS] * dt[first, None], dv_m[first], dt[first])
    if np.any(start[P.GYRO_BIAS]):  # a bias beyond the Earth rate: bias and heading from all rests
        start[P.GYRO_BIAS], C0 = rest_gyrocompass(
            dtheta_m, dt, seg.moving, C0, latitude_rad, start[P.GYRO_BIAS]
        )
    judge = _nominal_judge(
        sequence,
        time_s,
        dtheta_m,
        dv_m,
        dt,
        seg.moving,
        C0,
        start,
        (latitude_rad, gravity_mps2, profile, extras, requirements),
    )
    options = dict(
        extras=extras,
        partial=partial,
        requirements=requirements,
        max_iterations=max_iterations,
        tol_sigma=tol_sigma,
        where=where,
        start=start,
        judge=judge,
    )
    if renavigate == "always":
        pb = _Problem(time_s, dtheta_m, dv_m, dt, latitude_rad, gravity_mps2, profile, extras, grid, where)
        return _fit_renavigating(pb, C0, **options)
    site = Site(latitude_rad, gravity_mps2, float(time_s[0] - dt[0]))
    cuts = chunk_cuts(grid)
    del dt, seg  # whole-run temporaries: the passes need one chunk at a time
    return fit_intervals(
        lambda: array_chunks(time_s, dtheta_m, dv_m, site.t0, cuts), grid, site, C0, profile, **options
    )


def _fit_renavigating(
    pb: "_Problem",
    C0: np.ndarray,
    extras: Extras,
    partial: bool,
    requirements: Requirements,
    max_iterations: int | None,
    tol_sigma: float,
    where: str,
    start: np.ndarray | None = None,
    judge=None,
) -> Fit:
    """The reference loop: re-navigate the whole run in memory at every iteration.

    It is the reference for the streamed loop's navigation shortcut (navigate
    only while a step can matter) and its per-interval arithmetic, not for a
    different iteration: the attitude feedback and the steps about it follow
    the same :class:`FeedbackSchedule`.
    """
    latitude_rad, gravity_mps2, profile, grid, dt = (
        pb.latitude_rad,
        pb.gravity_mps2,
        pb.profile,
        pb.grid,
        pb.dt,
    )
    A, T = state_matrix(latitude_rad, gravity_mps2), np.diff(pb.t_nav[grid.bounds])
    mid = (grid.bounds[:-1] + grid.bounds[1:]) // 2
    values = np.zeros(P.N_PARAMS) if start is None else start.copy()
    extra_values = np.zeros(extras.n)
    names = UNKNOWN_NAMES + extras.names
    omega_ie_n = earth.omega_ie_n(latitude_rad)
    # Until the first navigation, the Earth's turn as seen at the start attitude.
    turn = X.earth_turn(np.broadcast_to(C0, (len(dt), 3, 3)), omega_ie_n, dt)
    noise, sol, history, converged, feedback = None, None, [], False, None
    schedule = FeedbackSchedule.for_run(profile, float(T.sum()), gravity_mps2)
    for it in range(1, schedule.limit(max_iterations) + 1):
        dth, dvv, nav = pb.compensate_and_navigate(values, extra_values, C0, turn, feedback)
        if extras.n:  # the Earth's turn in the body, for the next compensation
            turn = X.earth_turn(0.5 * (nav.C_b_n[1:] + nav.C_b_n[:-1]), omega_ie_n, dt)
        if noise is None or (profile.has_gauss_markov and it <= 3):
            # Gauss-Markov bias noise enters through the attitude (C_b_n b): its weights follow
            # the navigated attitude while the Jacobian does. Phi_vv does not depend on it.
            noise = noise_model(A, T, profile, C_b_n=nav.C_b_n[mid])
        z = pb.observations(nav, noise.Phi_vv, it, feedback)
        if _relinearise(it, sol, history):
            # The Jacobian changes little once the big errors are compensated; while steps are
            # still large (a MEMS unit's percent-level errors) it follows them. A partial fit's
            # covariance is sensitive to where its nearly-null directions lie, so it follows
            # the trajectory to the end.
            H = observation_jacobian(
                nav.C_b_n, dth, dvv, nav.time_s, grid, latitude_rad, gravity_mps2, noise.Phi_vv, extras
            )
            Hs, D = scaled_design(whiten(noise.whitener, H), extras, requirements)
            sol = solve_information(Hs.T @ Hs, where, names, partial, judge)
            cov = sol.covariance * np.outer(D, D)
        zw = whiten(noise.whitener, z[:, :, None]).reshape(-1)
        delta, resid = schedule.step(Hs, D, zw, sol, cov, it)
        values, extra_values = _apply(values, extra_values, delta, sol, D)
        C0 = rotvec_to_dcm(delta[PHI0]) @ C0
        history.append(_history_entry(it, delta, cov, resid, sol))
        step = history[-1]["max_step_sigma"]
        if step < tol_sigma and not schedule.pending():
            converged = True
            break
        feedback = schedule.update(it, step, feedback, noise, z, H, delta, A, T, nav.C_b_n[mid])
    return _fit_result(values, extra_values, C0, cov, sol, z, H, delta, history, converged, extras)


def _fit_result(values, extra_values, C0, cov, sol, z, H, delta, history, converged, extras) -> Fit:
    """The :class:`Fit` both loops end with; the residual is after the last correction (m/s)."""
    z_fit = z - np.einsum("kin,n->ki", H, delta)
    return Fit(
        values=values,
        C_b_n0=C0,
        covariance=cov,
        converged=converged,
        iterations=len(history),
        residual_rms_mps=float(np.sqrt(np.mean(z_fit**2))),
        chi2_per_dof=history[-1]["chi2_per_dof"],
        n_observations=int(z.size),
        history=history,
        extras=extras,
        extra_values=extra_values,
        estimable=sol.estimable,
        null_directions=sol.null_directions,
    )


def _history_entry(it: int, delta, cov, resid, sol) -> dict:
    """An iteration's record: its largest step in sigmas and the chi-square after it."""
    n_fitted = sol.covariance.shape[0] - len(sol.null_directions)
    return {
        "iteration": it,
        "max_step_sigma": float(np.max(np.abs(delta) / np.sqrt(np.diag(cov)))),
        "chi2_per_dof": float(resid @ resid / max(1, resid.size - n_fitted)),
    }


def _solve_step(Hs, D, zw, sol):
    """One Gauss-Newton step: the correction (SI) and the whitened residual after it."""
    delta_scaled = sol.covariance @ (Hs.T @ zw)
    return D * delta_scaled, zw - Hs @ delta_scaled


def _relinearise(it: int, sol, history: list) -> bool:
    """Whether this iteration re-evaluates the Jacobian.

    It changes little once the big errors are compensated, so after the third
    iteration only while steps are still large (a MEMS unit's percent-level
    errors); a partial fit's covariance is sensitive to where its nearly-null
    directions lie, so it follows the trajectory to the end.
    """
    return (
        sol is None
        or it <= 3
        or bool(sol.null_directions)
        or bool(history)
        and history[-1]["max_step_sigma"] > RELINEARISE_STEP_SIGMA
    )


def _apply(values, extra_values, delta, sol, D):
    """Add a step; a partial fit keeps the unobserved combinations of the totals at zero.

    Zeroing them only in each step would let them drift as the directions
    turn from one Jacobian to the next, and the drift bends the trajectory.
    """
    values, extra_values = values + delta[: P.N_PARAMS], extra_values + delta[N_UNKNOWN:]
    if sol.null_directions:
        Dp = D[_param_index(len(D))]
        x = sol.project(np.concatenate([values, extra_values]) / Dp) * Dp
        values, extra_values = x[: P.N_PARAMS], x[P.N_PARAMS :]
    return values, extra_values


def _nominal_judge(sequence, time_s, dtheta_m, dv_m, dt, moving, C0, start, model):
    """A callable giving the nominal trajectory's observability decision, computed once.

    Called only when a run's own information leaves directions unobserved:
    the sequence given, else the one read off a navigation of the log
    (:mod:`calib.seqinfer`), decides what is estimable, as the analyser does.
    """
    latitude_rad, gravity_mps2, profile, extras, requirements = model
    memo = {}

    def judge():
        if "inv" not in memo:
            seq = sequence
            if seq is None:
                dth = dtheta_m - start[P.GYRO_BIAS] * dt[:, None]
                nav = navigate(dth, dv_m, time_s, C0, latitude_rad, gravity_mps2)
                seq = infer_sequence(nav.C_b_n, dtheta_m, moving, dt)
            memo["inv"] = (
                None
                if seq is None
                else nominal_decision(
                    seq, latitude_rad, profile, extras, requirements, UNKNOWN_NAMES + extras.names
                )
            )
        return memo["inv"]

    return judge


def fit_intervals(
    chunks,
    grid,
    site: Site,
    C0: np.ndarray,
    profile: NoiseProfile,
    extras: Extras = X.NONE,
    partial: bool = False,
    requirements: Requirements = PAPER,
    max_iterations: int | None = None,
    tol_sigma: float = 1e-3,
    where: str = "run",
    start: np.ndarray | None = None,
    judge=None,
) -> Fit:
    """The Gauss-Newton loop on per-interval quantities, navigating only when it must.

    ``chunks()`` gives the run again, chunk by chunk (:mod:`calib.stream`);
    each navigation is one pass over it (:func:`calib.stream.navigate_pass`)
    that leaves only per-interval quantities. As in the reference loop the
    Jacobian is re-evaluated along the navigations of the first three
    iterations and kept after. The loop stops re-navigating when the next
    step cannot reach ``tol_sigma`` (:func:`_record`): the estimate is then
    converged without another pass (the test suite checks it against the
    reference loop). A run whose gyro noise walks the attitude far enough for
    gravity to leak through at second order gets the attitude feedback on the
    schedule both loops share (:class:`FeedbackSchedule`, docs/grades.md);
    every other run is fitted exactly as without it.
    """
    A, names = state_matrix(site.latitude_rad, site.gravity_mps2), UNKNOWN_NAMES + extras.names
    values = np.zeros(P.N_PARAMS) if start is None else start.copy()
    extra_values = np.zeros(extras.n)
    noise, sol, history, turn, feedback, schedule = None, None, [], None, None, None
    it, limit = 0, max_iterations or MAX_ITERATIONS
    while it < limit:
        it += 1
        want_H = _relinearise(it, sol, history)
        data = navigate_pass(
            chunks(),
            grid,
            site,
            values,
            extra_values,
            C0,
            turn,
            extras,
            with_moments=want_H,
            gyro_correction=None if feedback is None else feedback.body_rate,
        )
        turn, T = data.turn, np.diff(data.t_bounds)
        if schedule is None:  # (the run's length is known after its first pass)
            schedule = FeedbackSchedule.for_run(profile, float(T.sum()), site.gravity_mps2)
            limit = schedule.limit(max_iterations)
        if noise is None or (profile.has_gauss_markov and it <= 3):
            noise = noise_model(A, T, profile, C_b_n=data.C_mid)
        z = _observations(data.y if feedback is None else data.y - feedback.dv, noise.Phi_vv, it, where)
        if want_H:
            H, Hs, D, zw = _pass_design(data, T, site, noise, z, extras, requirements)
            sol = solve_information(Hs.T @ Hs, where, names, partial, judge)
            cov = sol.covariance * np.outer(D, D)
        else:
            zw = whiten(noise.whitener, z[:, :, None]).reshape(-1)
        delta, resid = schedule.step(Hs, D, zw, sol, cov, it)
        values, extra_values = _apply(values, extra_values, delta, sol, D)
        C0 = rotvec_to_dcm(delta[PHI0]) @ C0
        step, bound = _record(history, _history_entry(it, delta, cov, resid, sol), schedule.settled(it))
        if (step < tol_sigma or bound < tol_sigma) and not schedule.pending():
            return _fit_result(values, extra_values, C0, cov, sol, z, H, delta, history, True, extras)
        feedback = schedule.update(it, step, feedback, noise, z, H, delta, A, T, data.C_mid)
    return _fit_result(values, extra_values, C0, cov, sol, z, H, delta, history, False, extras)


def _pass_design(data, T, site: Site, noise, z, extras: Extras, requirements: Requirements):
    """A pass's Jacobian, its whitened and scaled form, and the whitened observations."""
    H = observation_matrix(
        sensitivities(data.moments, T, site.latitude_rad, site.gravity_mps2, data.extra), noise.Phi_vv
    )
    # H and z share the whitening filter: one recursion for both.
    Hz = whiten(noise.whitener, np.concatenate([H, z[:, :, None]], axis=2))
    Hs, D = scaled_design(Hz[:, :, :-1], extras, requirements)
    return H, Hs, D, Hz[:, :, -1].reshape(-1)


def _record(history: list, entry: dict, settled: bool) -> tuple[float, float]:
    """Append an iteration of the streamed loop, with its bound on the next step (sigmas).

    Geometric convergence holds from the step after the feedback was last
    moved: after steps ``s_prev``, ``s`` the next one is at most ``s * (s / s_prev)``.
    """
    step = entry["max_step_sigma"]
    bound = step * step / history[-1]["max_step_sigma"] if history and settled else math.inf
    history.append({**entry, "next_step_bound_sigma": float(bound)})
    return step, bound


def _observations(y: np.ndarray, Phi_vv: np.ndarray, it: int, where: str) -> np.ndarray:
    """Velocity changes over the observation intervals, less the noise model's prediction."""
    z = y[1:] - np.einsum("kij,kj->ki", Phi_vv, y[:-1])
    if not np.all(np.isfinite(z)) or np.abs(y).max() > 1e5:
        raise CalibError(
            f"the fit diverged at iteration {it} (navigation velocity {np.abs(y).max():.3g} m/s)",
            where,
            "check units and that the run is a stationary-base calibration",
        )
    return z


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


def check_sequence_matches(
    seq, detected: np.ndarray, from_sequence: np.ndarray, dt: np.ndarray, where: str
) -> None:
    """Refuse a sequence file whose flips are not where the log turns."""

    def runs(mask):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
        return edges[::2], edges[1::2]

    d0, _ = runs(detected)
    s0, _ = runs(from_sequence)
    if len(d0) != len(s0):
        raise CalibError(
            f"the sequence {seq.name!r} has {len(s0)} flips where the log turns {len(d0)} times",
            where,
            "give the sequence the run was made with, or omit --sequence",
        )
    t = np.cumsum(dt)
    offsets = np.abs(t[d0] - t[s0])
    if offsets.max() > 2.0:
        k = int(np.argmax(offsets))
        raise CalibError(
            f"flip {k + 1} of sequence {seq.name!r} starts at {t[s0[k]]:.2f} s but the "
            f"log turns at {t[d0[k]]:.2f} s",
            where,
            "give the sequence the run was made with, or omit --sequence",
        )
