"""The simulator of gimbal runs: exact increments with the 21 errors, the optional terms and noise,
streamed to disk for long runs, truth files, and a log's setup mistakes.

Modules:

- :mod:`calib.sim.gimbal_run`: Run simulator: exact IMU increments of a sequence on a stationary
  base
- :mod:`calib.sim.log_mistakes`: Setup mistakes made in writing a run log, as transformations of a
  correct :class:`~calib.runlog.Run`
- :mod:`calib.sim.to_disk`: Simulate a long run straight to disk, a time window at a time
- :mod:`calib.sim.truth`: Truth files of simulated runs (``run.truth.toml``) and error files
  (``--errors``)
"""

from calib.sim.gimbal_run import SIM, SimOptions, Truth, add_noise, encoder_angles, run_meta, simulate
from calib.sim.log_mistakes import (
    accel_in_g,
    axes_swapped,
    axis_flipped,
    gyro_accel_swapped,
    gyro_in_deg,
    rate_mislabelled,
)
from calib.sim.to_disk import sample_windows, simulate_to_file
from calib.sim.truth import (
    errors_from_table,
    read_errors,
    read_truth,
    truth_path_for,
    truth_to_dict,
    write_truth,
)

__all__ = [
    "SIM",
    "SimOptions",
    "Truth",
    "accel_in_g",
    "add_noise",
    "axes_swapped",
    "axis_flipped",
    "encoder_angles",
    "errors_from_table",
    "gyro_accel_swapped",
    "gyro_in_deg",
    "rate_mislabelled",
    "read_errors",
    "read_truth",
    "run_meta",
    "sample_windows",
    "simulate",
    "simulate_to_file",
    "truth_path_for",
    "truth_to_dict",
    "write_truth",
]
