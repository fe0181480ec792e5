"""Calibrate a run placed by hand: the fit of :mod:`calib.handfit` as a calibration result.

The result carries the 21 (and the gyro g-sensitivity when asked for) with
their sigmas, Birge-checked like a gimbal run's, the first rest's attitude,
and a :class:`calib.handsummary.HandSummary` of the rests and moves used.
"""

from __future__ import annotations

import numpy as np

from . import params as P
from .errors import CalibError
from .extras import Extras
from .handfit import HandFit, fit_by_hand
from .handsummary import HandSummary
from .profiles import NoiseProfile
from .runlog import Run
from .runlog.clipping import describe_clipping
from .site import Site
from .solution import Fit
from .strapdown import sample_intervals


def hand_fit_of(run: Run, site: Site, profile: NoiseProfile, extras: Extras, partial: bool, req) -> HandFit:
    """The fit of a run placed by hand, read as it is."""
    unsupported = [g for g in extras.groups if g != "g-sensitivity"]
    if unsupported:
        raise CalibError(
            f"--with {','.join(unsupported)} is not fitted on a run placed by hand",
            run.source,
            "leave them out (g-sensitivity is the term a hand-placed run can fit)",
        )
    dt = sample_intervals(run.time_s)
    return fit_by_hand(
        run.time_s,
        run.dtheta_rad,
        run.dv_mps,
        dt,
        site.latitude_rad,
        site.gravity_mps2,
        profile,
        g_sensitivity="g-sensitivity" in extras.groups,
        clipped=None if run.clipped is None else run.clipped.any(axis=1),
        requirements=req,
        partial=partial,
        where=run.source,
    )


def as_fit(hand: HandFit, extras: Extras) -> Fit:
    """The estimator's :class:`calib.solution.Fit` of a hand fit (what the result is built from)."""
    lay = hand.layout
    n_keep = lay.gs.stop
    cov = np.zeros((P.N_PARAMS + 3 + extras.n,) * 2)
    keep = np.r_[0 : P.N_PARAMS, lay.gs]
    out = np.r_[0 : P.N_PARAMS, P.N_PARAMS + 3 : P.N_PARAMS + 3 + extras.n]
    cov[np.ix_(out, out)] = hand.covariance[np.ix_(keep, keep)]
    tilt = lay.columns(0)[0]
    cov[P.N_PARAMS : P.N_PARAMS + 2, P.N_PARAMS : P.N_PARAMS + 2] = hand.covariance[np.ix_(tilt, tilt)]
    cov[P.N_PARAMS + 2, P.N_PARAMS + 2] = np.pi**2  # the heading of the first rest: the frame's, not fitted
    estimable = np.ones(P.N_PARAMS + extras.n, dtype=bool)
    estimable[:n_keep] = hand.estimable
    return Fit(
        values=hand.values,
        C_b_n0=hand.C_rest[0],
        covariance=cov,
        converged=hand.converged,
        iterations=hand.iterations,
        residual_rms_mps=hand.residual_rms_mps2,
        chi2_per_dof=hand.chi2_per_dof,
        n_observations=hand.n_observations,
        history=hand.history,
        extras=extras,
        extra_values=hand.g_sensitivity.reshape(9) if hand.g_sensitivity is not None else np.zeros(0),
        estimable=estimable,
        null_directions=hand.null_directions,
    )


def summary_of(hand: HandFit, run: Run) -> HandSummary:
    """Rests and moves in seconds from the log's start."""
    t0 = float(run.time_s[0] - sample_intervals(run.time_s)[0])
    t = np.concatenate([[t0], run.time_s]) - t0  # sample i spans t[i] .. t[i + 1]
    rests = hand.data.rests
    rest_s = np.column_stack([t[rests.start], t[rests.end]])
    move_s = np.column_stack([t[rests.end[:-1]], t[rests.start[1:]]])
    return HandSummary(
        rest_s=rest_s,
        move_s=move_s,
        move_used=hand.data.move_used,
        rest_chi2=hand.rest_chi2,
        move_chi2=hand.move_chi2,
        clipped=tuple(describe_clipping(run)),
        chi2_per_dof=hand.chi2_per_dof,
    )
