"""The run-log format ``imu-run/1``: its name, required metadata and column names.

One definition of each, for the readers and writers of :mod:`calib.runlog`
and everything that writes a run (the simulators). The formats are specified
in docs/formats.md ("Run log, CSV" and "Run log, NPZ").
"""

from __future__ import annotations

FORMAT = "imu-run/1"
REQUIRED_META = ("format", "latitude_deg", "height_m", "sample_rate_hz")

TIME_COLUMN = "time_s"
DTHETA_COLUMNS = ("dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad")
DV_COLUMNS = ("dv_x_mps", "dv_y_mps", "dv_z_mps")
GIMBAL_COLUMNS = ("outer_deg", "middle_deg", "inner_deg")
REQUIRED_COLUMNS = (TIME_COLUMN, *DTHETA_COLUMNS, *DV_COLUMNS)

# CSV column names of each Run array, by component; the keys are the NPZ member names.
ARRAY_COLUMNS = {
    "time_s": (TIME_COLUMN,),
    "dtheta_rad": DTHETA_COLUMNS,
    "dv_mps": DV_COLUMNS,
    "gimbal_deg": GIMBAL_COLUMNS,
}
NPZ_ARRAYS = ("time_s", "dtheta_rad", "dv_mps")  # the members an NPZ run log must have
