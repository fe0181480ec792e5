"""How noisy the IMU is and how the fit weights it: noise profiles, the whitening filter, the Gauss-
Markov filter and smoother, the attitude wander a profile builds.

Modules:

- :mod:`calib.noise.frame`: The frame a Gauss-Markov noise model is built in, and when it must be
  built anew
- :mod:`calib.noise.gauss_markov`: First-order Gauss-Markov (GM) bias instability: exact sampled
  simulation
- :mod:`calib.noise.gm_filter`: The Gauss-Markov noise filter of many mountings at once, in
  navigation-frame bias coordinates
- :mod:`calib.noise.kernels`: The compiled recursions: what runs interval by interval over small
  matrices (the compiled recursions (numba); imported by the Gauss-Markov paths alone, so not re-
  exported)
- :mod:`calib.noise.matexp`: The matrix exponential, for the noise model's Van Loan integrals
- :mod:`calib.noise.profiles`: Noise profiles: the IMU's white noise (ARW, VRW), per
  ``docs/conventions.md``, and
- :mod:`calib.noise.smoother`: The fixed-interval smoother of the noise states (Rauch-Tung-Striebel)
  over the whitener's model
- :mod:`calib.noise.wander`: How far a gyro's noise walks the attitude over a run, and the longest
  run a linearised fit follows
- :mod:`calib.noise.whitening`: Noise structure of the observations and the whitening filter (exact
  GLS)
"""

from calib.noise.frame import attitude_moved_deg, heading_turn, model_frame, noise_stale, to_frame
from calib.noise.gauss_markov import gauss_markov
from calib.noise.gm_filter import (
    NavTable,
    bias_turns,
    gm_start_covariance,
    gram_one,
    gram_pass,
    mounted_turns,
    nav_table,
)
from calib.noise.matexp import expm
from calib.noise.profiles import NoiseProfile, builtin_profiles, load_profile, white_part
from calib.noise.smoother import smooth
from calib.noise.wander import attitude_wander_ratio, check_wander, longest_run_s, tilt_variance
from calib.noise.whitening import (
    IntervalModel,
    NoiseModel,
    Whitener,
    cholesky_inverse_3,
    filter_blocks,
    filter_order,
    gm_bias_covariance,
    gm_interval_arrays,
    gm_interval_nav,
    interval_models,
    noise_model,
    rotations,
    velocity_transitions,
    whiten,
    whiten_batch,
    whitener,
)

__all__ = [
    "NavTable",
    "IntervalModel",
    "NoiseModel",
    "NoiseProfile",
    "Whitener",
    "attitude_moved_deg",
    "attitude_wander_ratio",
    "bias_turns",
    "builtin_profiles",
    "check_wander",
    "cholesky_inverse_3",
    "expm",
    "filter_blocks",
    "filter_order",
    "gauss_markov",
    "gm_bias_covariance",
    "gm_interval_arrays",
    "gm_interval_nav",
    "gm_start_covariance",
    "gram_one",
    "gram_pass",
    "heading_turn",
    "interval_models",
    "load_profile",
    "longest_run_s",
    "model_frame",
    "mounted_turns",
    "nav_table",
    "noise_model",
    "noise_stale",
    "rotations",
    "smooth",
    "tilt_variance",
    "to_frame",
    "velocity_transitions",
    "white_part",
    "whiten",
    "whiten_batch",
    "whitener",
]
