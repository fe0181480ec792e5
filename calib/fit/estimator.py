"""Iterated least squares for the 21 parameters from a run (the paper's 2.3.1-2.3.5).

Each iteration compensates the raw increments with the current estimate,
navigates on the stationary base, and fits the navigation velocity errors
with the linearised model of :mod:`calib.nav.jacobian` weighted by the exact
noise structure of :mod:`calib.noise.whitening` (a Gauss-Newton step of the GLS
problem). The unknowns are the 21 parameters, the initial attitude error
and any optional terms switched on (:mod:`calib.model.optional_terms`); nothing about the
heading is assumed: the first guess comes from levelling and gyrocompassing
on the first rest. A profile with Gauss-Markov bias instability re-weights
the observations along the navigated attitude.

The run is streamed (:mod:`calib.nav.chunk_pass`): each navigation is one pass over
the samples, a chunk at a time, that leaves only per-interval quantities,
and :func:`fit_intervals` navigates only while a step can still matter.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError
from calib.model import optional_terms as X, params as P
from calib.model.error_model import ErrorModel
from calib.model.information import UNKNOWN_NAMES
from calib.model.optional_terms import OptionalTerms
from calib.model.requirements import Requirements
from calib.nav.chunk_pass import Estimate, Passes, array_chunks, chunk_cuts, navigate_pass
from calib.nav.jacobian import (
    PHI0,
    ObservationGrid,
    Trajectory,
    default_grid,
    observation_jacobian,
    observation_matrix,
    sensitivities,
    state_matrix,
)
from calib.nav.site import Site
from calib.nav.strapdown import navigate, sample_intervals
from calib.nav.transform import rotvec_to_dcm
from calib.noise.frame import model_frame, noise_stale, to_frame
from calib.noise.profiles import NoiseProfile
from calib.noise.wander import check_wander
from calib.noise.whitening import noise_model, whiten
from calib.sequence.inferred import infer_sequence
from calib.sequence.motion import Segmentation, detect_motion

from . import sanity
from .feedback import MAX_ITERATIONS, FeedbackSchedule
from .gyrocompass import rests_in_memory
from .options import FIT, FitOptions
from .solution import (
    Fit,
    apply_step,
    fit_result,
    history_entry,
    nominal_judge,
    scaled_design,
    solve_information,
)
from .start import check_first_rest, mean_rest_rate, start_attitude

# Past the third iteration the Jacobian is rebuilt only while the last step exceeded this many
# sigmas: below it the linearisation error is far below the convergence tolerance.
RELINEARISE_STEP_SIGMA = 0.1


def check_run(
    run,
    dt: np.ndarray,
    site: Site,
    profile: NoiseProfile,
    moving: np.ndarray | None,
    options: FitOptions = FIT,
) -> Segmentation:
    """Refuse a log the fit cannot use, naming why; return where it turns.

    What is plausible follows the unit's class (its profile and ``options.requirements``):
    a MEMS unit's biases of 1000 deg/h and 20 mg are not a log in wrong units.
    ``options.max_rate_rad_s`` is the fastest plausible turn (`calib.fit.sanity.check_rates`):
    a gimbal's by default; a run turned by hand gives its sensor's range, or None.

    Parameters
    ----------
    run : calib.runlog.Run
        The log (its ``dtheta_rad``, ``dv_mps`` and ``source``, which names it in refusals).
    dt : ndarray, shape (n,)
        Its sample intervals.
    site : Site
    profile : NoiseProfile
    moving : ndarray of bool or None
        Which samples turn; detected from the gyros if None.
    options : FitOptions

    Returns
    -------
    Segmentation
    """
    dtheta_m, dv_m, where = run.dtheta_rad, run.dv_mps, run.source
    sanity.check_latitude(site.latitude_rad, where)
    sanity.check_rates(dtheta_m, dt, where, options.max_rate_rad_s)
    seg = detect_motion(dtheta_m, dt, where, arw=profile.arw)
    if moving is not None:
        seg = Segmentation(moving=moving, first_rest_end=int(np.argmax(moving)))
    check_first_rest(
        dtheta_m, dv_m, dt, slice(0, seg.first_rest_end), site.gravity_mps2, where, options.requirements
    )
    sanity.check_saturation(dtheta_m, dv_m, where)
    sanity.check_rests(dv_m, dt, seg.moving, profile.vrw, where)
    return seg


@dataclass
class _Problem:
    """The fixed data of one fit: the log, its site, the observation grid and the unknowns."""

    time_s: np.ndarray
    dtheta_m: np.ndarray
    dv_m: np.ndarray
    dt: np.ndarray
    site: Site
    profile: NoiseProfile
    extras: OptionalTerms
    grid: ObservationGrid
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
        if feedback is not None:  # after the extra terms, as calib.nav.chunk_pass applies it
            b = self.grid.bounds  # b[0] = 0 and b[-1] = n: every sample is in an interval
            dth = dth + np.repeat(feedback.body_rate, np.diff(b), axis=0) * self.dt[:, None]
        site = self.site
        nav = navigate(dth, dvv, self.time_s, C0, site, t0=self.t_nav[0])
        return dth, dvv, nav

    def observations(self, nav, Phi_vv, it: int, feedback_dv=None, hint: str = "") -> np.ndarray:
        """Velocity changes over the observation intervals, less the noise model's prediction."""
        y = nav.v_n[self.grid.bounds]
        return _observations(y if feedback_dv is None else y - feedback_dv, Phi_vv, it, self.where, hint)


def fit_run(
    run,
    site: Site,
    profile: NoiseProfile,
    *,
    moving: np.ndarray | None = None,
    sequence=None,
    options: FitOptions = FIT,
) -> Fit:
    """Identify the 21 parameters, the initial attitude and any optional terms from raw increments.

    Parameters
    ----------
    run : calib.runlog.Run
        The log in memory: its ``time_s`` (end time of each sample), raw
        (uncompensated) ``dtheta_rad`` and ``dv_mps``, and ``source``, which
        names it in refusals.
    site : Site
        Its latitude and gravity.
    profile : NoiseProfile
        Weights the observations and scales the covariance.
    moving : ndarray of bool, optional
        Which samples turn (from the sequence); detected from the gyros if None.
    sequence : Sequence, optional
        The nominal sequence: on a run that leaves directions unobserved it
        decides which parameters are estimable, as the analyser does.
        Default: inferred from the navigation (:mod:`calib.sequence.inferred`).
    options : FitOptions
        What is fitted and how (:class:`calib.fit.options.FitOptions`): ``renavigate``
        "when-needed" streams the run through :func:`fit_intervals`, "always" runs the
        reference loop that re-navigates the whole run in memory at every iteration.

    Returns
    -------
    Fit
    """
    time_s, dtheta_m, dv_m, where = run.time_s, run.dtheta_rad, run.dv_mps, run.source
    dt = sample_intervals(time_s)
    seg = check_run(run, dt, site, profile, moving, options)
    grid = default_grid(seg.moving, 1.0 / np.median(dt))
    first = slice(0, seg.first_rest_end)
    start = start_attitude(
        (dtheta_m[first], dv_m[first], dt[first]),
        mean_rest_rate(dtheta_m, dt, seg.moving),
        functools.partial(rests_in_memory, dtheta_m, dt, seg.moving),
        site,
    )
    judge = nominal_judge(
        functools.partial(_run_sequence, sequence, run, dt, seg.moving, start, site),
        site,
        profile,
        options.extras,
        options.requirements,
    )
    if options.renavigate == "always":
        pb = _Problem(time_s, dtheta_m, dv_m, dt, site, profile, options.extras, grid, where)
        return _fit_renavigating(pb, start, options, judge)
    t0 = float(time_s[0] - dt[0])
    cuts = chunk_cuts(grid)
    del dt, seg  # whole-run temporaries: the passes need one chunk at a time
    passes = Passes(lambda: array_chunks(time_s, dtheta_m, dv_m, t0, cuts), grid, t0)
    return fit_intervals(passes, site, profile, start, options, where=where, judge=judge)


def _fit_renavigating(pb: _Problem, start: tuple, options: FitOptions, judge=None) -> Fit:
    """The reference loop: re-navigate the whole run in memory at every iteration.

    It is the reference for the streamed loop's navigation shortcut (navigate
    only while a step can matter) and its per-interval arithmetic, not for a
    different iteration: the attitude feedback and the steps about it follow
    the same :class:`FeedbackSchedule`.
    """
    site = pb.site
    profile, grid, dt, where = pb.profile, pb.grid, pb.dt, pb.where
    extras, requirements, partial = options.extras, options.requirements, options.partial
    first, C0 = start
    A, T = state_matrix(site), np.diff(pb.t_nav[grid.bounds])
    mid = (grid.bounds[:-1] + grid.bounds[1:]) // 2
    values = np.zeros(P.N_PARAMS) if first is None else first.copy()
    extra_values = np.zeros(extras.n)
    names = UNKNOWN_NAMES + extras.names
    omega_ie_n = site.omega_ie_n
    # Until the first navigation, the Earth's turn as seen at the start attitude.
    turn = X.earth_turn(np.broadcast_to(C0, (len(dt), 3, 3)), omega_ie_n, dt)
    history: list[dict] = []
    noise, sol, converged, feedback, noise_C = None, None, False, None, None
    check_wander(profile, float(T.sum()), where)
    schedule = FeedbackSchedule.for_run(profile, float(T.sum()), site.gravity_mps2)
    for it in range(1, schedule.limit(options.max_iterations) + 1):
        dth, dvv, nav = pb.compensate_and_navigate(values, extra_values, C0, turn, feedback)
        if extras.n:  # the Earth's turn in the body, for the next compensation
            turn = X.earth_turn(0.5 * (nav.C_b_n[1:] + nav.C_b_n[:-1]), omega_ie_n, dt)
        rebuild = (
            noise is None
            or (profile.has_gauss_markov and it <= 3)
            or noise_stale(profile, noise_C, nav.C_b_n[mid])
        )
        if rebuild:
            # Gauss-Markov bias noise enters through the attitude (C_b_n b): its weights follow
            # the navigated attitude (calib.noise.frame), and the Jacobian with them.
            # Phi_vv does not depend on it.
            noise_C = nav.C_b_n[mid]
            noise = noise_model(A, T, profile, C_b_n=noise_C)
        assert noise is not None  # built on the first pass (rebuild is true while it is None)
        fb_dv: np.ndarray | None = None if feedback is None else feedback.dv_along(nav.C_b_n[mid], A, T)
        # Observations and Jacobian in the frame the noise model was built in (heading_turn).
        R, C_model = model_frame(profile, noise_C, nav.C_b_n[mid])
        z = to_frame(R, pb.observations(nav, noise.Phi_vv, it, fb_dv, schedule.divergence_hint()))
        if rebuild or _relinearise(it, sol, history):
            # The Jacobian changes little once the big errors are compensated; while steps are
            # still large (a MEMS unit's percent-level errors) it follows them. A partial fit's
            # covariance is sensitive to where its nearly-null directions lie, so it follows
            # the trajectory to the end.
            H = observation_jacobian(
                Trajectory(nav.time_s, nav.C_b_n, dth, dvv, grid), site, noise.Phi_vv, extras
            )
            H = to_frame(R, H)
            Hs, D = scaled_design(whiten(noise.whitener, H), extras, requirements)
            sol = solve_information(Hs.T @ Hs, where, names, partial, judge)
            cov = sol.covariance * np.outer(D, D)
        zw = whiten(noise.whitener, z[:, :, None]).reshape(-1)
        delta, resid = schedule.step(Hs, D, zw, sol, cov, it)
        values, extra_values = apply_step(values, extra_values, delta, sol, D)
        C0 = rotvec_to_dcm(delta[PHI0]) @ C0
        history.append(history_entry(it, delta, cov, resid, sol) | schedule.record())
        step = history[-1]["max_step_sigma"]
        if step < options.tol_sigma and not schedule.pending():
            converged = True
            break
        feedback = schedule.update(it, step, feedback, noise, (z, H, delta), A, T, C_model)
    if not converged and (why := schedule.why_not_converged()):
        history[-1]["why_not_converged"] = why
    z, H = to_frame(R.T, z), to_frame(R.T, H)  # back in the navigation frame
    return fit_result((values, extra_values, C0), cov, sol, (z, H, delta), history, converged, extras)


def fit_intervals(
    passes: Passes,
    site: Site,
    profile: NoiseProfile,
    start: tuple,
    options: FitOptions = FIT,
    *,
    where: str = "run",
    judge=None,
) -> Fit:
    """The Gauss-Newton loop on per-interval quantities, navigating only when it must.

    ``passes.chunks()`` gives the run again, chunk by chunk (:mod:`calib.nav.chunk_pass`);
    each navigation is one pass over it (:func:`calib.nav.chunk_pass.navigate_pass`)
    that leaves only per-interval quantities. As in the reference loop the
    Jacobian is re-evaluated along the navigations of the first three
    iterations and kept after. The loop stops re-navigating when the next
    step cannot reach ``tol_sigma`` (:func:`_record`): the estimate is then
    converged without another pass (the test suite checks it against the
    reference loop). A run whose gyro noise walks the attitude far enough for
    gravity to leak through at second order gets the attitude feedback on the
    schedule both loops share (:class:`FeedbackSchedule`, docs/grades.md);
    every other run is fitted exactly as without it.

    Parameters
    ----------
    passes : calib.nav.chunk_pass.Passes
        The run, read again at every navigation.
    site : Site
    profile : NoiseProfile
    start : tuple of ndarray
        Where Gauss-Newton starts: the 21's first values (None: zeros) and the attitude
        when the run began (:func:`calib.fit.start.start_attitude`).
    options : FitOptions
        What is fitted and how (``renavigate`` and ``max_rate_rad_s`` are not used here).
    where : str
        Names the log in refusals.
    judge : callable, optional
        Decides what is estimable on a run that leaves directions unobserved
        (:func:`calib.fit.solution.nominal_judge`).

    Returns
    -------
    Fit
    """
    extras, requirements, partial = options.extras, options.requirements, options.partial
    max_iterations, tol_sigma = options.max_iterations, options.tol_sigma
    first, C0 = start
    A, names = state_matrix(site), UNKNOWN_NAMES + extras.names
    values = np.zeros(P.N_PARAMS) if first is None else first.copy()
    extra_values = np.zeros(extras.n)
    history: list[dict] = []
    noise, sol, turn, feedback, schedule, noise_C = None, None, None, None, None, None
    it, limit, stale, rebuilt = 0, max_iterations or MAX_ITERATIONS, False, 0
    while it < limit:
        it += 1
        # A noise model found stale on a pass without the Jacobian is rebuilt on the next, with it.
        want_H = _relinearise(it, sol, history) or stale
        gyro_correction: np.ndarray | None = None if feedback is None else feedback.body_rate
        estimate = Estimate(values, C0, extras, extra_values, turn, gyro_correction)
        data = navigate_pass(passes, site, estimate, with_moments=want_H)
        turn, T = data.turn, np.diff(data.t_bounds)
        if schedule is None:  # (the run's length is known after its first pass)
            check_wander(profile, float(T.sum()), where)
            schedule = FeedbackSchedule.for_run(profile, float(T.sum()), site.gravity_mps2)
            limit = schedule.limit(max_iterations)
        stale = noise_stale(profile, noise_C, data.C_mid)
        if noise is None or (profile.has_gauss_markov and it <= 3) or (stale and want_H):
            noise_C, stale, rebuilt = data.C_mid, False, it
            noise = noise_model(A, T, profile, C_b_n=noise_C)
        y = data.y if feedback is None else data.y - feedback.dv_along(data.C_mid, A, T)
        R, C_model = model_frame(profile, noise_C, data.C_mid)
        z = to_frame(R, _observations(y, noise.Phi_vv, it, where, schedule.divergence_hint()))
        if want_H:
            H, Hs, D, zw = _pass_design(data, T, site, noise, z, extras, requirements, R)
            sol = solve_information(Hs.T @ Hs, where, names, partial, judge)
            cov = sol.covariance * np.outer(D, D)
        else:
            zw = whiten(noise.whitener, z[:, :, None]).reshape(-1)
        delta, resid = schedule.step(Hs, D, zw, sol, cov, it)
        values, extra_values = apply_step(values, extra_values, delta, sol, D)
        C0 = rotvec_to_dcm(delta[PHI0]) @ C0
        # The weights changed with a rebuilt noise model: no geometric bound across it.
        settled = schedule.settled(it) and it > rebuilt + 1
        step, bound = _record(history, history_entry(it, delta, cov, resid, sol) | schedule.record(), settled)
        if (step < tol_sigma or bound < tol_sigma) and not schedule.pending() and not stale:
            z, H = to_frame(R.T, z), to_frame(R.T, H)
            return fit_result((values, extra_values, C0), cov, sol, (z, H, delta), history, True, extras)
        feedback = schedule.update(it, step, feedback, noise, (z, H, delta), A, T, C_model)
    if schedule is not None and (why := schedule.why_not_converged()):
        history[-1]["why_not_converged"] = why
    z, H = to_frame(R.T, z), to_frame(R.T, H)
    return fit_result((values, extra_values, C0), cov, sol, (z, H, delta), history, False, extras)


def _pass_design(data, T, site: Site, noise, z, extras: OptionalTerms, requirements: Requirements, R):
    """A pass's Jacobian (in the frame ``R`` turns to), its whitened and scaled form, and the
    whitened observations.
    """
    H = observation_matrix(sensitivities(data.moments, T, site, data.extra), noise.Phi_vv)
    H = to_frame(R, H)
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


def _observations(y: np.ndarray, Phi_vv: np.ndarray, it: int, where: str, hint: str) -> np.ndarray:
    """Velocity changes over the observation intervals, less the noise model's prediction."""
    z = y[1:] - np.einsum("kij,kj->ki", Phi_vv, y[:-1])
    if not np.all(np.isfinite(z)) or np.abs(y).max() > 1e5:
        raise CalibError(
            f"the fit diverged at iteration {it} (navigation velocity {np.abs(y).max():.3g} m/s)",
            where,
            hint,
        )
    return z


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


def _run_sequence(sequence, run, dt, moving, start: tuple, site: Site):
    """The sequence given, else the one read off a navigation of the log (:mod:`calib.sequence.inferred`)."""
    if sequence is not None:
        return sequence
    values, C0 = start
    dth = run.dtheta_rad - values[P.GYRO_BIAS] * dt[:, None]
    nav = navigate(dth, run.dv_mps, run.time_s, C0, site)
    return infer_sequence(nav.C_b_n, run.dtheta_rad, moving, dt)
