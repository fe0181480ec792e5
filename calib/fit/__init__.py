"""The estimator of a run on a gimbal: iterated least squares in memory or chunk by chunk, one Gauss-
Newton step, the MEMS attitude feedback, the start (alignment, gyrocompass), sanity checks, and what
`view` computes.

Modules:

- :mod:`calib.fit.chunked`: Read a run log in chunks, and calibrate it without ever holding it whole
- :mod:`calib.fit.estimator`: Iterated least squares for the 21 parameters from a run (the paper's
  2.3.1-2.3.5)
- :mod:`calib.fit.feedback`: The attitude feedback of a run whose gyro noise walks the attitude (a
  MEMS unit's)
- :mod:`calib.fit.gyrocompass`: Gyro bias and heading together from every rest of a run (a MEMS
  unit's start)
- :mod:`calib.fit.options`: The estimator's options as one value: what is fitted, how far and how it
  iterates
- :mod:`calib.fit.replay`: What a recording of a run shows that has to be computed: motion,
  alignment, navigations
- :mod:`calib.fit.sanity`: Physical sanity checks of a run before calibrating it
- :mod:`calib.fit.solution`: What a Gauss-Newton step solves for, and the fit it ends with
- :mod:`calib.fit.start`: Where Gauss-Newton starts: the one start of the in-memory and the chunked
  paths
"""

from calib.fit.chunked import aligned, file_start, fit_file, run_header, sequence_motion_file, survey
from calib.fit.estimator import check_run, fit_intervals, fit_run
from calib.fit.feedback import (
    AttitudeFeedback,
    FeedbackSchedule,
    aitken,
    attitude_feedback,
    limit_heading_step,
)
from calib.fit.gyrocompass import (
    Rests,
    gyrocompass_rests,
    rest_attitudes,
    rest_gyrocompass,
    rest_rates,
    rests_in_memory,
)
from calib.fit.options import FIT, FitOptions
from calib.fit.replay import RunReview, motion_profile, result_profile, review_run, velocity_noise_sigma
from calib.fit.sanity import (
    GyroUnitError,
    check_gravity,
    check_latitude,
    check_rates,
    check_rest_rate,
    check_rests,
    check_saturation,
    explain_gyro_unit,
)
from calib.fit.solution import (
    Fit,
    Solution,
    apply_step,
    fit_result,
    history_entry,
    nominal_decision,
    nominal_judge,
    param_index,
    scaled_design,
    solve_information,
    solve_step,
    unknown_scale,
)
from calib.fit.start import (
    check_first_rest,
    coarse_alignment,
    mean_rest_rate,
    start_attitude,
    start_from_rests,
    start_values,
)

__all__ = [
    "AttitudeFeedback",
    "FeedbackSchedule",
    "FIT",
    "Fit",
    "FitOptions",
    "GyroUnitError",
    "Rests",
    "RunReview",
    "Solution",
    "aitken",
    "aligned",
    "apply_step",
    "attitude_feedback",
    "check_first_rest",
    "check_gravity",
    "check_latitude",
    "check_rates",
    "check_rest_rate",
    "check_rests",
    "check_run",
    "check_saturation",
    "coarse_alignment",
    "explain_gyro_unit",
    "file_start",
    "fit_file",
    "fit_intervals",
    "fit_result",
    "fit_run",
    "gyrocompass_rests",
    "history_entry",
    "limit_heading_step",
    "mean_rest_rate",
    "motion_profile",
    "nominal_decision",
    "nominal_judge",
    "param_index",
    "rest_attitudes",
    "rest_gyrocompass",
    "rest_rates",
    "rests_in_memory",
    "result_profile",
    "review_run",
    "run_header",
    "scaled_design",
    "sequence_motion_file",
    "solve_information",
    "solve_step",
    "start_attitude",
    "start_from_rests",
    "start_values",
    "survey",
    "unknown_scale",
    "velocity_noise_sigma",
]
