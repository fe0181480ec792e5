"""Other tools as peers: imu_tk's method re-implemented, other tools' published results read as
corrections, and scores free of any tool's convention.

Modules:

- :mod:`calib.peers.imutk_method`: imu_tk's multi-position method (Tedaldi, Pretto, Menegatti, ICRA
  2014), written here from its description
- :mod:`calib.peers.published`: Other tools' calibrations read as a
  :class:`~calib.calibration.correction.Correction` (``M (raw - b)``)
- :mod:`calib.peers.scores`: Scores of any calibration on a recording placed by hand, free of any
  tool's convention
"""

from calib.peers.imutk_method import (
    IMUTK,
    ImuTkFit,
    ImuTkOptions,
    carried_rotations,
    ellipsoid_start,
    fit_accel,
    fit_gyro,
    imutk_calibrate,
    static_intervals,
    window_variance_norm,
)
from calib.peers.published import imu_tk_triad, imucal_correction, parse_imu_tk, read_imu_tk, read_imucal
from calib.peers.scores import (
    Axes,
    ForceSpread,
    HandScore,
    PoseToPose,
    RestSpans,
    angle_between,
    axes_of,
    force_spread,
    pose_to_pose,
    rest_means,
    score,
    sensing_axes,
)

__all__ = [
    "Axes",
    "ForceSpread",
    "HandScore",
    "IMUTK",
    "ImuTkFit",
    "ImuTkOptions",
    "PoseToPose",
    "RestSpans",
    "angle_between",
    "axes_of",
    "carried_rotations",
    "ellipsoid_start",
    "fit_accel",
    "fit_gyro",
    "force_spread",
    "imu_tk_triad",
    "imucal_correction",
    "imutk_calibrate",
    "parse_imu_tk",
    "pose_to_pose",
    "read_imu_tk",
    "read_imucal",
    "rest_means",
    "score",
    "sensing_axes",
    "static_intervals",
    "window_variance_norm",
]
