"""Calibrate a logged run: the library call behind ``seqdesign calibrate``.

:func:`calibrate_run` takes a :class:`calib.runlog.Run` and returns a
:class:`calib.result.CalibrationResult` that already carries the policy a
user relies on: the site gravity and where it came from, the convergence
verdict, the Birge check (sigmas inflated by ``sqrt(chi2/dof)`` when the
residuals are larger than the noise profile says), and, for a run that
leaves directions unobserved, which parameters are not estimable. A
notebook, the Monte Carlo and the CLI get the same sigmas from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import earth
from . import params as P
from .errors import CalibError
from .estimator import Fit, calibrate, check_sequence_matches, detect_motion, sequence_motion
from .extras import Extras, as_extras
from .profiles import NoiseProfile, as_profile
from .requirements import PAPER, Requirements, load_requirements
from .result import CalibrationResult
from .strapdown import sample_intervals

# chi2/dof above this says the profile understates the noise: sigmas are inflated by
# sqrt(chi2/dof). 1.2 is far outside the spread of chi2/dof for the thousands of degrees
# of freedom of a calibration run (its standard deviation is sqrt(2/dof) < 0.05).
BIRGE_LIMIT = 1.2

# 1 mGal = 1e-5 m/s^2 of gravity error is a common accelerometer scale-factor error of
# 1e-5 / g: about 1.02 ppm at the Earth's surface.
MGAL = 1e-5


@dataclass(frozen=True)
class SiteGravity:
    """The gravity a fit assumes, and where it came from."""

    value_mps2: float
    source: str  # "measured" (the log's gravity_mps2 or the user's) or "normal" (WGS-84 model)

    @property
    def ppm_per_mgal(self) -> float:
        """How far 1 mGal of gravity error moves every accelerometer scale factor, ppm."""
        return MGAL / self.value_mps2 * 1e6

    def describe(self) -> str:
        if self.source == "measured":
            return f"{self.value_mps2:.7f} m/s^2 (measured, from the log's gravity_mps2)"
        return (
            f"{self.value_mps2:.7f} m/s^2 (WGS-84 normal gravity at the log's latitude and "
            "height; local anomalies of tens of mGal are not in it)"
        )


def site_gravity(run, gravity_mps2: float | None = None) -> SiteGravity:
    """Gravity given by the user, else the log's measured one, else normal gravity at its site."""
    if gravity_mps2 is not None:
        return SiteGravity(float(gravity_mps2), "measured")
    if run.gravity_mps2 is not None:
        return SiteGravity(float(run.gravity_mps2), "measured")
    return SiteGravity(earth.gravity(math.radians(run.latitude_deg), run.height_m), "normal")


def calibrate_run(
    run,
    profile: NoiseProfile | str = "navigation",
    *,
    sequence=None,
    extras: Extras | str | None = None,
    partial: bool = False,
    require_convergence: bool = True,
    requirements=None,
    gravity_mps2: float | None = None,
    provenance: dict | None = None,
) -> CalibrationResult:
    """Fit the 21 parameters (and any optional terms) of a run log.

    Parameters
    ----------
    run : calib.runlog.Run
        The log (:func:`calib.runlog.read_run`, or :func:`calib.sim.simulate`).
    profile : NoiseProfile or str
        Weights the fit and scales the sigmas.
    sequence : calib.sequence.Sequence, optional
        The sequence the run followed: its flips mark where the log turns
        (refused if they are not where the gyros turn). Default: detected.
    extras : Extras or str, optional
        Optional terms to fit beside the 21 (``"lever-arm,k2"``, ``"all"``).
    partial : bool
        Fit the estimable part of a run that leaves directions unobserved,
        reporting the rest as not estimable, instead of refusing it.
    require_convergence : bool
        Refuse a fit that did not converge (the CLI writes no result then).
    requirements : Requirements or str, optional
        What the ratios are judged against (default: the paper's).
    gravity_mps2 : float, optional
        Surveyed gravity at the site; wins over the log's and over the
        normal-gravity model (a gravity error of dg/g is a common
        accelerometer scale-factor error no sequence can separate).
    provenance : dict, optional
        Stored in the result as it is.

    Returns
    -------
    CalibrationResult
        With the Birge-checked sigmas, the correlation of the 21, the site
        gravity and the fit's health.
    """
    prof, extras = as_profile(profile), as_extras(extras)
    req = load_requirements(requirements)
    lat = math.radians(run.latitude_deg)
    gravity = site_gravity(run, gravity_mps2)
    moving = None
    if sequence is not None:
        dt = sample_intervals(run.time_s)
        moving = sequence_motion(sequence, run.time_s, dt)
        check_sequence_matches(
            sequence, detect_motion(run.dtheta_rad, dt, run.source).moving, moving, dt, run.source
        )
    fit = calibrate(
        run.time_s,
        run.dtheta_rad,
        run.dv_mps,
        lat,
        gravity.value_mps2,
        prof,
        moving=moving,
        where=run.source,
        extras=extras,
        partial=partial,
        requirements=req,
        sequence=sequence,
    )
    if require_convergence and not fit.converged:
        raise CalibError(
            f"the fit did not converge in {fit.iterations} iterations (last step "
            f"{fit.history[-1]['max_step_sigma']:.3g} sigma)",
            run.source,
            "no result written; check the run and the noise profile",
        )
    return result_from_fit(fit, prof, gravity, provenance or {}, req)


def result_from_fit(
    fit: Fit,
    profile: NoiseProfile,
    gravity: SiteGravity,
    provenance: dict,
    requirements: Requirements = PAPER,
) -> CalibrationResult:
    """The result a user sees: sigmas Birge-checked, the 21's correlation, what is estimable."""
    scale = math.sqrt(fit.chi2_per_dof) if fit.chi2_per_dof > BIRGE_LIMIT else 1.0
    estimable = fit.estimable if fit.estimable is not None else np.ones(P.N_PARAMS + fit.extras.n, dtype=bool)
    names = P.NAMES + fit.extras.names
    return CalibrationResult(
        values=fit.values,
        sigma=fit.sigma * scale,
        C_b_n0=fit.C_b_n0,
        converged=fit.converged,
        iterations=fit.iterations,
        residual_rms_mps=fit.residual_rms_mps,
        profile=profile.name,
        chi2_per_dof=fit.chi2_per_dof,
        correlation=fit.correlation[: P.N_PARAMS, : P.N_PARAMS],
        provenance=dict(provenance),
        extras=fit.extras,
        extra_values=fit.extra_values,
        extra_sigma=fit.extra_sigma * scale,
        sigma_scale=scale,
        not_estimable=tuple(n for n, e in zip(names, estimable) if not e),
        null_directions=tuple(fit.null_directions),
        n_observations=fit.n_observations,
        gravity_mps2=gravity.value_mps2,
        gravity_source=gravity.source,
        requirements=requirements,
    )
