"""What a recording of a run shows that has to be computed: motion, alignment, navigations.

:func:`review_run` does the estimation work behind ``seqdesign view`` --
where the log turns, the coarse alignment on its first rest, the
navigation velocity errors of the raw increments and, with a calibration
result, of the compensated ones -- so that :mod:`viz` only logs arrays.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import earth
from .errormodel import ErrorModel
from .errors import CalibError
from .estimator import coarse_alignment, detect_motion
from .strapdown import Navigation, navigate, sample_intervals, start_time

# A picture of the raw errors can align on a shorter first rest than the fit needs
# (calib.estimator.MIN_ALIGN_S): the "before" curve is for looking, not for estimates.
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

    @property
    def t_rel(self) -> np.ndarray:
        return np.cumsum(self.dt)


def review_run(run, result=None, latitude_deg: float | None = None,
               gravity_mps2: float | None = None) -> RunReview:
    """Motion, coarse alignment and the navigation velocity errors before/after calibration."""
    lat_deg = run.latitude_deg if latitude_deg is None else float(latitude_deg)
    lat = math.radians(lat_deg)
    g = gravity_mps2 if gravity_mps2 is not None else (
        run.gravity_mps2 if run.gravity_mps2 is not None else earth.gravity(lat, run.height_m))
    dt = sample_intervals(run.time_s)
    t0 = start_time(run.time_s)
    dtheta, dv = run.dtheta_rad, run.dv_mps
    notes = []
    try:
        seg = detect_motion(dtheta, dt, run.source)
        moving, first_rest_end = seg.moving, seg.first_rest_end
    except CalibError:
        moving, first_rest_end = np.zeros(run.n_samples, dtype=bool), run.n_samples
        notes.append("no rotation found in the run: everything is one rest")
    before = None
    if dt[:first_rest_end].sum() >= MIN_ALIGN_S:
        first = slice(0, first_rest_end)
        C_align = coarse_alignment(dtheta[first], dv[first], dt[first])
        before = navigate(dtheta, dv, run.time_s, C_align, lat, g, t0=t0)
    else:
        notes.append(f"the run does not start with {MIN_ALIGN_S:g} s of rest: no coarse "
                     "alignment, no velocity errors before calibration")
    after = None
    if result is not None:
        dth_c, dv_c = ErrorModel(result.values).compensate(dtheta, dv, dt)
        after = navigate(dth_c, dv_c, run.time_s, result.C_b_n0, lat, g, t0=t0)
    return RunReview(t0, dt, lat_deg, g, moving, before, after, notes)
