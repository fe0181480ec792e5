"""What a recording of a run shows that has to be computed: motion, alignment, navigations.

:func:`review_run` does the estimation work behind ``seqdesign view`` --
where the log turns, the coarse alignment on its first rest, the
navigation velocity errors of the raw increments and, with a calibration
result, of the compensated ones -- so that :mod:`viz` only logs arrays.

:func:`velocity_noise_sigma` is what the velocity error after calibration
should look like when the calibration is right: the 1-sigma of the
navigation velocity error that the IMU's own white noise (ARW, VRW) and
Gauss-Markov bias drift build up on a stationary base, propagated with the
exact interval model of :mod:`calib.noise.whitening` (the same ``A`` of
:func:`calib.nav.jacobian.state_matrix` and the same Van Loan discretisation
the fit is weighted with). It starts at zero: the navigation starts from a
known zero velocity, and the attitude it starts from is the fit's own
estimate. What it leaves out (see :func:`velocity_noise_sigma`): the
uncertainty of that initial attitude and of the 21 parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib.errors import CalibError
from calib.model.error_model import ErrorModel
from calib.nav.jacobian import default_grid, state_matrix
from calib.nav.site import Site, site_of
from calib.nav.strapdown import Navigation, navigate, sample_intervals, start_time
from calib.noise.profiles import DEFAULT_PROFILE, NoiseProfile, load_profile
from calib.noise.whitening import interval_models
from calib.sequence.motion import detect_motion

from .start import coarse_alignment

# A picture of the raw errors can align on a shorter first rest than the fit needs
# (calib.sequence.definition.MIN_ALIGN_S): the "before" curve is for looking, not for estimates.
MIN_ALIGN_S = 1.0


@dataclass
class RunReview:
    """A run's time base, motion and navigations (SI), and what could not be computed."""

    t0: float  # when the first sample began
    dt: np.ndarray  # (n,) sample intervals
    latitude_deg: float
    gravity_mps2: float
    moving: np.ndarray  # (n,) bool
    before: Navigation | None  # from the coarse alignment, raw increments
    after: Navigation | None  # from the result's initial attitude, compensated increments
    notes: list = field(default_factory=list)
    # Predicted 1-sigma of the velocity error after calibration (with a result):
    noise_time: np.ndarray | None = None  # (K + 1,) s, on the same time line as t_rel (0 first)
    noise_sigma_v: np.ndarray | None = None  # (K + 1, 3) m/s, E N U
    noise_profile: str = ""  # the profile it was computed with

    @property
    def t_rel(self) -> np.ndarray:
        return np.cumsum(self.dt)


def motion_profile(run, result=None, profile: NoiseProfile | str | None = None) -> NoiseProfile:
    """The noise a run's motion is judged with, as ``calibrate`` judges it (one rule).

    The profile given, else the one the result was fitted with, else the one the run log
    names (a simulated run records it), else the default profile.
    """
    if profile is not None:
        return profile if isinstance(profile, NoiseProfile) else load_profile(profile)
    if result is not None:
        return result_profile(result)[0]
    try:
        return load_profile(run.meta.get("profile") or DEFAULT_PROFILE)
    except CalibError:  # a name only its writer knew: judge as the default profile does
        return load_profile(DEFAULT_PROFILE)


def review_run(
    run,
    result=None,
    latitude_deg: float | None = None,
    gravity_mps2: float | None = None,
    profile: NoiseProfile | str | None = None,
) -> RunReview:
    """Motion, coarse alignment and the navigation velocity errors before/after calibration.

    The motion is judged with the noise of :func:`motion_profile` (``profile``, else the
    result's, else the run's own), as ``calibrate`` judges it.

    With a result, also the predicted 1-sigma of the velocity error after
    calibration (:func:`velocity_noise_sigma`) with the noise profile the
    result names (the default profile, with a note, if it cannot be loaded).
    """
    lat_deg = run.latitude_deg if latitude_deg is None else float(latitude_deg)
    site = site_of(run, gravity_mps2, lat_deg)
    dt = sample_intervals(run.time_s)
    t0 = start_time(run.time_s)
    dtheta, dv = run.dtheta_rad, run.dv_mps
    notes = []
    try:
        seg = detect_motion(dtheta, dt, run.source, arw=motion_profile(run, result, profile).arw)
        moving, first_rest_end = seg.moving, seg.first_rest_end
    except CalibError:
        moving, first_rest_end = np.zeros(run.n_samples, dtype=bool), run.n_samples
        notes.append("no rotation found in the run: everything is one rest")
    before = None
    if dt[:first_rest_end].sum() >= MIN_ALIGN_S:
        first = slice(0, first_rest_end)
        C_align = coarse_alignment(dtheta[first], dv[first], dt[first])
        before = navigate(dtheta, dv, run.time_s, C_align, site, t0=t0)
    else:
        notes.append(
            f"the run does not start with {MIN_ALIGN_S:g} s of rest: no coarse "
            "alignment, no velocity errors before calibration"
        )
    review = RunReview(t0, dt, lat_deg, site.gravity_mps2, moving, before, None, notes)
    if result is not None:
        dth_c, dv_c = ErrorModel(result.values).compensate(dtheta, dv, dt)
        review.after = navigate(dth_c, dv_c, run.time_s, result.C_b_n0, site, t0=t0)
        profile, note = result_profile(result)
        if note:
            notes.append(note)
        review.noise_time, review.noise_sigma_v = _noise_envelope(
            review.after, moving, run.sample_rate_hz, site, profile
        )
        review.noise_profile = profile.name
    return review


def velocity_noise_sigma(
    T: np.ndarray,
    site: Site,
    profile: NoiseProfile,
    C_b_n: np.ndarray | None = None,
) -> np.ndarray:
    """1-sigma of the navigation velocity error driven by the IMU's noise, from zero.

    The error state ``[phi, dv]`` (and ``[b_g, b_a]`` with Gauss-Markov
    bias) of a stationary IMU is propagated interval by interval,
    ``P_k = Phi_k P_{k-1} Phi_k' + Q_k``, with the exact discretisation of
    :func:`calib.noise.whitening.interval_models`.

    Parameters
    ----------
    T : ndarray, shape (K,)
        Interval lengths, s.
    site : Site
        Latitude and gravity of the stationary base.
    profile : NoiseProfile
        ARW and VRW, and the GM bias instability if it has one.
    C_b_n : ndarray, shape (K, 3, 3), optional
        Mid-interval attitude; needed only with GM bias (a body-frame bias
        turns with the IMU), ignored without.

    Returns
    -------
    ndarray, shape (K + 1, 3)
        ``sqrt(diag P_vv)`` at the start (zeros) and at every interval end, m/s.

    Notes
    -----
    Everything starts at zero covariance. Velocity: the navigation starts at
    a known zero velocity. Attitude: the after-calibration navigation starts
    from the fit's estimate of the initial attitude, whose own uncertainty
    (a ``g phi0 t`` ramp) is not included -- a result does not carry phi0's
    covariance. GM biases: the fit takes out the bias's value, so what is
    left is its drift, ``2 sigma^2 t / tau`` at first, which is what a GM
    state started at zero grows by. The uncertainty of the 21 parameters is
    not included either. Both omissions are partly made up by the fit
    itself, which absorbs the part of the noise that looks like its unknowns.
    """
    T = np.asarray(T, dtype=float)
    models = interval_models(state_matrix(site), T, profile, C_b_n)
    n = models[0].Phi.shape[0] if models else 6
    P = np.zeros((n, n))
    out = np.zeros((len(T) + 1, 3))
    for k, m in enumerate(models):
        P = m.Phi @ P @ m.Phi.T + m.Q
        out[k + 1] = np.sqrt(np.clip(np.diag(P)[3:6], 0.0, None))
    return out


def result_profile(result) -> tuple[NoiseProfile, str | None]:
    """The noise profile a result names, else the default one with a note saying so."""
    try:
        return load_profile(result.profile or DEFAULT_PROFILE), None
    except CalibError as exc:
        return load_profile(DEFAULT_PROFILE), (
            f"the result's profile {result.profile!r} could not be loaded ({exc.message}); "
            f"the noise envelope uses {DEFAULT_PROFILE!r}"
        )


def _noise_envelope(
    nav: Navigation, moving: np.ndarray, sample_rate_hz: float, site: Site, profile: NoiseProfile
) -> tuple[np.ndarray, np.ndarray]:
    """Times (s since the start) and 1-sigma of :func:`velocity_noise_sigma` on the fit's grid."""
    b = default_grid(moving, sample_rate_hz).bounds
    t = nav.time_s - nav.time_s[0]
    C_mid = 0.5 * (nav.C_b_n[b[:-1]] + nav.C_b_n[b[1:]]) if profile.has_gauss_markov else None
    return t[b], velocity_noise_sigma(np.diff(t[b]), site, profile, C_mid)
