"""The attitude feedback of a run whose gyro noise walks the attitude (a MEMS unit's).

The observations are linear in the attitude noise; gravity leaks through a
tilt at second order. When that leak matters (:func:`~calib.noise.wander.attitude_wander_ratio`)
the smoothed attitude noise is fed back into the navigation
(:func:`attitude_feedback`) on the one :class:`FeedbackSchedule` both
Gauss-Newton loops of :mod:`calib.fit.estimator` follow, with Aitken's
extrapolation (:func:`aitken`) once the feedback is held (FEEDBACK_HOLD_SIGMA).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from calib.nav.jacobian import PHI0
from calib.noise.matexp import expm  # not scipy.linalg: its import costs 0.15 s per command
from calib.noise.profiles import NoiseProfile
from calib.noise.smoother import smooth
from calib.noise.wander import attitude_wander_ratio, tilt_variance

from .solution import solve_step

# The observations are linear in the attitude noise; gravity leaks through a tilt phi at second
# order, g phi^2 / 2. When that term, for the attitude wander the gyro noise builds over the run,
# exceeds this fraction of the accelerometer-bias resolution vrw / sqrt(T), the fit re-linearises
# about the smoothed attitude noise (:func:`attitude_feedback`). A MEMS unit's
# 30-min run is at about 40, a tactical unit's at 0.15, a navigation-grade one's at 1e-8.
ATTITUDE_FEEDBACK_RATIO = 0.5
# The feedback moves at every step until two steps in a row (each taken about a just-moved
# feedback) are below FEEDBACK_HOLD_SIGMA, then it is held. Under white MEMS noise that takes
# 4-9 updates (an earlier rule held it after 4 always: on the golden designed-15min run the
# updates were then still moving the estimate by several sigmas, and it ended 0.5 sigma off the
# settled fixed point). A strong Gauss-Markov gyro bias walks the attitude further (39 deg/h,
# 87 s: 3.5 deg RMS tilt over 30 min) and the feedback settles slowly: held after 4 updates the
# accelerometer scale factors came out 5 sigma off (NEES 202); held below FEEDBACK_HOLD_SIGMA
# they are within 2.5 sigma. A fit whose feedback has not settled after MAX_FEEDBACK_UPDATES is
# not converged (docs/grades.md).
FEEDBACK_MIN_UPDATES = 4
FEEDBACK_HOLD_SIGMA = 0.5
MAX_FEEDBACK_UPDATES = 30
# The first update waits for a step below this many sigmas: the residuals of the first step from
# a MEMS unit's 1000 deg/h (hundreds of sigmas) are mostly linearisation error, not noise.
FEEDBACK_START_SIGMA = 100.0
# ... or at this iteration at the latest: a strong Gauss-Markov gyro bias leaks gravity by
# hundreds of sigmas, and without the feedback the steps never fall below FEEDBACK_START_SIGMA
# (measured: 40 iterations between 100 and 40000 sigma on an ADIS16405-profile run).
FEEDBACK_START_ITERATION = 3
MAX_ITERATIONS = 12
# A MEMS gyro cannot gyrocompass: the run leaves the heading known to tens of degrees (the
# horizontal Earth rate, 11 deg/h at 40 deg latitude, against a bias instability of tens of
# deg/h), where the observations are far from linear in it, and full Gauss-Newton steps turn
# the heading by up to 100 deg from one iteration to the next (measured on ADIS16405-profile
# runs), and with it the gyro biases and the tilt path: the fit cycles. A step that would turn
# the heading further than the trust radius is taken as the best step with the heading turned
# only that far (the conditional least-squares step). The radius starts here; a cut step answered
# by one the other way halves it and the most it may grow back to; one answered the same way
# doubles it, up to that most. Measured (paper-9pos, ADIS16405 profile and stronger), where
# Gauss-Newton asks for 20-225 deg either way: a radius doubled back to 15 deg after every
# reversal cycled (+7.5, +15, -7.5, -15 deg) in 6 runs of 50; one that never grows back crawls
# 0.9 deg per iteration towards a heading 53 deg away.
HEADING_STEP_MAX_DEG = 15.0
# A heading whose own sigma exceeds this is beyond what the linearised fit can locate: at 30 deg
# the second-order term the model lacks, Omega_h (1 - cos psi), is 13 % of the first-order one.
# Then Gauss-Newton's target heading jumps with each rebuild of the noise model (measured on
# paper-9pos under the ADIS16405 profile: sigma 78-88 deg, targets -67 to +91 deg, and 3 runs of
# 50 cycled for 45 iterations with the radius halved four times). Once a cut step has been
# answered the other way twice (the radius at a quarter) such a heading is held where it is and
# the rest fitted given it; the covariance keeps the heading's (linearised) uncertainty.
HEADING_UNDETERMINED_DEG = 30.0
# No fit converges on a cut step while the radius is at least this: below it the heading moves
# the 21 by a hundredth of a sigma (measured: 0.1 sigma of a gyro scale factor per 6 deg).
HEADING_SETTLED_DEG = 0.5
WANDER_MAX_ITERATIONS = 45  # measured: 6-15 iterations (white MEMS), up to 35 (ADIS16405 profile)


@dataclass(frozen=True)
class AttitudeFeedback:
    """A gyro correction that takes the estimated attitude noise out of the navigation.

    ``body_rate`` (K, 3), rad/s per interval, is added to the compensated gyro
    increments; the observations add back its first-order effect on the
    navigation velocity along the trajectory of their pass (:meth:`dv_along`).
    """

    body_rate: np.ndarray

    def dv_along(self, C_mid: np.ndarray, A: np.ndarray, T: np.ndarray) -> np.ndarray:
        """The first-order velocity effect (K + 1, 3) of the correction along ``C_mid``.

        The correction is a rate fixed in the body; its effect in the navigation frame turns
        with the navigated heading. Added back as it was along the trajectory it was made on,
        it was wrong by the heading's turn since then: on a MEMS run whose heading the fit
        moves by degrees, metres per second against millimetres of noise (measured: the fit
        then cycled for 30 iterations with the heading, never converging).
        """
        return _velocity_effect(-np.einsum("kij,kj->ki", C_mid, self.body_rate), A, T)


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
    (:mod:`calib.noise.whitening`), which a MEMS gyro's noise walks by degrees over a
    run: gravity then leaks through at second order, ``g phi^2 / 2``, tens of
    times the accelerometer-bias resolution, and the fit is biased. The
    smoothed noise ``phi_hat`` given the fit's residuals (:func:`calib.noise.smoother.smooth`)
    is taken out of the next navigation by a gyro correction, and its
    first-order effect on the velocity is added back to the observations: to
    first order nothing changes (the same GLS problem), while the neglected
    terms shrink to second order in the smoothing error ``phi - phi_hat``.
    Iterated with Gauss-Newton, this is an iterated extended smoother.
    """
    phi_hat = smooth(list(noise.models), residual)[:, :3]
    key = np.ascontiguousarray(A, dtype=float).tobytes()
    K = len(T)
    m, rate = np.zeros(6), np.empty((K, 3))
    for k in range(K):
        Phi, G = _rate_response(key, round(float(T[k]), 6))
        # The attitude rate u over interval k that brings the correction to -phi_hat at its end.
        u = np.linalg.solve(G[:3], -phi_hat[k + 1] - Phi[:3] @ m)
        m = Phi @ m + G @ u
        # A gyro error e in the body drives the attitude error by -C_b_n e (calib.nav.jacobian).
        rate[k] = -C_mid[k].T @ u
    return AttitudeFeedback(rate)


def _velocity_effect(u: np.ndarray, A: np.ndarray, T: np.ndarray) -> np.ndarray:
    """The ``dv`` (K + 1, 3) of a navigation-frame attitude rate ``u`` (K, 3), constant per interval."""
    key = np.ascontiguousarray(A, dtype=float).tobytes()
    m, dv = np.zeros(6), np.zeros((len(T) + 1, 3))
    for k in range(len(T)):
        Phi, G = _rate_response(key, round(float(T[k]), 6))
        m = Phi @ m + G @ u[k]
        dv[k + 1] = m[3:]
    return dv


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
    quiet: int = 0  # steps in a row below FEEDBACK_HOLD_SIGMA about a just-moved feedback
    held: bool = False
    wander_deg: float = 0.0  # the 1-sigma tilt the gyro noise builds over the run
    heading_limited: bool = False  # the last step's heading turn was cut to the trust radius
    heading_limit_deg: float = HEADING_STEP_MAX_DEG  # the heading's trust radius
    heading_cap_deg: float = HEADING_STEP_MAX_DEG  # the most it may grow back to
    heading_last_cut: float = 0.0  # the sign of the last cut heading step (0: not cut)
    heading_held: bool = False  # the heading is undetermined and held (HEADING_UNDETERMINED_DEG)
    heading_sigma_deg: float = 0.0  # the heading's sigma at the last step

    @classmethod
    def for_run(cls, profile: NoiseProfile, duration_s: float, gravity_mps2: float):
        """On when the wander leaks gravity (:func:`calib.noise.wander.attitude_wander_ratio`)."""
        wander = attitude_wander_ratio(profile, duration_s, gravity_mps2) > ATTITUDE_FEEDBACK_RATIO
        return cls(wander, wander_deg=math.degrees(math.sqrt(tilt_variance(profile, duration_s))))

    def record(self) -> dict:
        """What an iteration's history entry adds: the held heading's sigma, once held."""
        return {"heading_held_sigma_deg": self.heading_sigma_deg} if self.heading_held else {}

    def why_not_converged(self) -> str | None:
        """The cause of a fit that ran out of iterations, when it is the feedback's."""
        if not self.wander or self.held:
            return None
        return (
            f"the attitude feedback did not settle in {self.updates} updates: the profile's gyro "
            f"noise walks the attitude by about {self.wander_deg:.1f} deg (1 sigma) over the run, "
            "too far for the linearised fit"
        )

    def divergence_hint(self) -> str:
        """How to fix a fit that diverged: for a wandering attitude, name the wander."""
        if not self.wander:
            return "check units and that the run is a stationary-base calibration"
        return (
            f"the profile's gyro noise walks the attitude by about {self.wander_deg:.1f} deg (1 sigma) "
            "over the run, too far for the linearised fit here: check units and the profile "
            "(its gyro bias instability), or calibrate shorter runs (each a full sequence)"
        )

    def limit(self, max_iterations: int | None) -> int:
        """Iterations allowed: ``max_iterations`` as given, else the default of the run's kind."""
        return max_iterations or (WANDER_MAX_ITERATIONS if self.wander else MAX_ITERATIONS)

    def pending(self) -> bool:
        """Whether the feedback has still to move or the heading was cut: no convergence then."""
        heading_moving = self.heading_limited and self.heading_limit_deg >= HEADING_SETTLED_DEG
        return self.wander and (not self.held or heading_moving)

    @property
    def unsettled(self) -> bool:
        """Whether the feedback was given up on: MAX_FEEDBACK_UPDATES and still moving the estimate."""
        return self.wander and not self.held and self.updates >= MAX_FEEDBACK_UPDATES

    def due(self, step: float, it: int = 0) -> bool:
        """Whether this step's residuals update the feedback (see FEEDBACK_HOLD_SIGMA)."""
        if not self.pending() or self.updates >= MAX_FEEDBACK_UPDATES:
            return False
        if self.updates == 0:
            return step < FEEDBACK_START_SIGMA or it >= FEEDBACK_START_ITERATION
        # A step whose heading turn was cut at the full radius is not quiet: the heading is still
        # marching and the feedback made at one heading holds its second-order terms only about
        # it (measured: held while the heading still turned 60 deg, a white-`mems` run ended
        # with sax 5.4 sigma off, NEES 54). Once the radius has shrunk the heading is cycling
        # within it, and waiting for it left 6 runs in 50 of paper-9pos under the ADIS16405
        # profile unconverged (1 in 50 when cut steps counted as quiet).
        marching = self.heading_limited and self.heading_limit_deg >= HEADING_STEP_MAX_DEG
        quiet = step < FEEDBACK_HOLD_SIGMA and not marching
        self.quiet = self.quiet + 1 if quiet else 0
        if self.updates >= FEEDBACK_MIN_UPDATES and self.quiet >= 2:
            self.held = True
            return False
        return True

    def moved_at(self, it: int) -> None:
        self.updates, self.moved = self.updates + 1, it

    def update(self, it: int, step: float, feedback, noise, last: tuple, A, T, C_mid):
        """The feedback after iteration ``it``: re-estimated from the fit's residual
        ``z - H delta`` (``last = (z, H, delta)``) when :meth:`due`, else ``feedback`` unchanged.
        """
        if not self.due(step, it):
            return feedback
        self.moved_at(it)
        z, H, delta = last
        return attitude_feedback(noise, z - np.einsum("kin,n->ki", H, delta), A, T, C_mid)

    def settled(self, it: int) -> bool:
        """Whether iteration ``it`` and the one before it share the same feedback.

        Only then is the step a continuation of the last (geometric
        convergence, Aitken's rule).
        """
        return it > self.moved + 1

    def heading_trust(self, heading: float, heading_sigma_deg: float) -> None:
        """Move the heading's trust radius after a cut step, given this step's heading (rad) and
        the heading's sigma; hold an undetermined heading once it cycles (HEADING_UNDETERMINED_DEG).
        """
        if self.heading_last_cut * heading < 0.0:
            self.heading_limit_deg *= 0.5
            self.heading_cap_deg = self.heading_limit_deg
            cycling = self.heading_limit_deg <= 0.25 * HEADING_STEP_MAX_DEG
            if cycling and heading_sigma_deg > HEADING_UNDETERMINED_DEG:
                self.heading_held = True
                self.heading_limit_deg = self.heading_cap_deg = 0.0
        elif self.heading_last_cut * heading > 0.0:
            self.heading_limit_deg = min(2.0 * self.heading_limit_deg, self.heading_cap_deg)

    def step(self, Hs, D, zw, sol, cov: np.ndarray, it: int):
        """The Gauss-Newton step (SI) and whitened residual after it; Aitken's once held."""
        delta, resid = solve_step(Hs, D, zw, sol)
        if self.held:
            last = self.last if self.settled(it) else None
            delta, self.last = aitken(delta, np.sqrt(np.diag(cov)), last)
            resid = zw - Hs @ (delta / D)
        if self.wander:
            u = PHI0.start + 2
            heading = delta[u]
            self.heading_sigma_deg = math.degrees(math.sqrt(sol.covariance[u, u]) * D[u])
            self.heading_trust(heading, self.heading_sigma_deg)
            delta, self.heading_limited = limit_heading_step(delta, sol.covariance, D, self.heading_limit_deg)
            self.heading_last_cut = math.copysign(1.0, heading) if self.heading_limited else 0.0
            if self.heading_limited:
                resid = zw - Hs @ (delta / D)
        return delta, resid


def limit_heading_step(delta: np.ndarray, covariance: np.ndarray, D: np.ndarray, limit_deg: float):
    """The step with its heading turn cut to ``limit_deg``, and whether it was cut.

    The least-squares step given the heading's (the Gaussian conditional): the other unknowns
    move as they would had the heading moved only that far.
    """
    u = PHI0.start + 2  # the heading (up) component of the initial attitude
    limit = math.radians(limit_deg)
    if abs(delta[u]) <= limit:
        return delta, False
    x = delta / D
    target = math.copysign(limit, delta[u]) / D[u]
    x = x + covariance[:, u] * (target - x[u]) / covariance[u, u]
    return D * x, True
