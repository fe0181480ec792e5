"""The attitude feedback of a run whose gyro noise walks the attitude (a MEMS unit's).

The observations are linear in the attitude noise; gravity leaks through a
tilt at second order. When that leak matters (:func:`attitude_wander_ratio`)
the smoothed attitude noise is fed back into the navigation
(:func:`attitude_feedback`) on the one :class:`FeedbackSchedule` both
Gauss-Newton loops of :mod:`calib.estimator` follow, with Aitken's
extrapolation (:func:`aitken`) once the feedback is held.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .matexp import expm  # not scipy.linalg: its import costs 0.15 s per command
from .profiles import NoiseProfile
from .smoother import smooth
from .solution import solve_step

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


def aitken(delta: np.ndarray, sigma: np.ndarray, last: np.ndarray | None):
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
        delta, resid = solve_step(Hs, D, zw, sol)
        if self.wander and self.updates == FEEDBACK_UPDATES:
            last = self.last if self.settled(it) else None
            delta, self.last = aitken(delta, np.sqrt(np.diag(cov)), last)
            resid = zw - Hs @ (delta / D)
        return delta, resid
