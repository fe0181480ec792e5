"""Navigation on a stationary base: the Earth, the site, rotations, strapdown, the linearised error-to-
observation Jacobian and one navigation pass over a run's chunks.

Modules:

- :mod:`calib.nav.chunk_pass`: One navigation pass over a run, chunk by chunk, reduced at once to
  per-interval quantities (imports the Jacobian (casadi); not re-exported for the same reason)
- :mod:`calib.nav.earth`: Earth model of the conventions: WGS-84 rotation rate and normal gravity,
  ENU
- :mod:`calib.nav.jacobian`: The linearised error-to-observation Jacobian (casadi), shared by the
  estimator and the analyser (imports casadi; not re-exported, so that the command line's start
  (which reads calib.nav.earth) stays light)
- :mod:`calib.nav.site`: The stationary base a run was recorded on: latitude, height and gravity,
  and where the gravity came from
- :mod:`calib.nav.strapdown`: Stationary-base strapdown navigation on IMU increments
- :mod:`calib.nav.transform`: Rotations, direction names and the gimbal decomposition of the
  conventions
"""

from calib.nav.earth import check_site, gravity, omega_ie_n, specific_force_n
from calib.nav.site import Site, ppm_per_mgal, site_of
from calib.nav.strapdown import (
    Navigation,
    coning_rotvec,
    cross3,
    navigate,
    sample_intervals,
    sculling_dv,
    start_time,
)
from calib.nav.transform import (
    attitude_from_directions,
    axis_index,
    dcm_to_rotvec,
    describe_axis,
    direction_vector,
    directions_of,
    gimbal_from_relative,
    gimbal_to_relative,
    is_gimbal_lock,
    nearest_direction,
    on_grid,
    prefix_product,
    quat_mult,
    quat_to_dcm,
    rot_axis,
    rotvec_to_dcm,
    rotvec_to_quat,
    skew,
    unwrap_gimbal,
)

__all__ = [
    "Navigation",
    "Site",
    "attitude_from_directions",
    "axis_index",
    "check_site",
    "coning_rotvec",
    "cross3",
    "dcm_to_rotvec",
    "describe_axis",
    "direction_vector",
    "directions_of",
    "gimbal_from_relative",
    "gimbal_to_relative",
    "gravity",
    "is_gimbal_lock",
    "navigate",
    "nearest_direction",
    "omega_ie_n",
    "on_grid",
    "ppm_per_mgal",
    "prefix_product",
    "quat_mult",
    "quat_to_dcm",
    "rot_axis",
    "rotvec_to_dcm",
    "rotvec_to_quat",
    "sample_intervals",
    "sculling_dv",
    "site_of",
    "skew",
    "specific_force_n",
    "start_time",
    "unwrap_gimbal",
]
