"""Runs placed by hand: the plan and pose lists, the trajectory and simulator with a hand's troubles,
the rest finder, the joint fit of rests and moves with the weights it earns, its setup checks,
predictions and the calibration result.

Modules:

- :mod:`calib.hand.calibrate`: Calibrate a run placed by hand: the fit of
  :mod:`calib.hand.joint_fit` as a calibration result
- :mod:`calib.hand.data`: What a fit of a run placed by hand reads of it: its rests, their means and
  noise, its moves
- :mod:`calib.hand.drift`: Biases that drift over a run placed by hand: the times they are fitted
  about, and the biases at its end
- :mod:`calib.hand.fit_options`: The hand fit's inputs as values: the samples it reads and the options
  it is fitted with
- :mod:`calib.hand.host_clock`: The time stamps a host writes: reception times of samples the IMU
  spaced evenly on its own clock
- :mod:`calib.hand.joint_fit`: The 21 parameters of a run placed by hand: rests and moves, fitted
  together
- :mod:`calib.hand.moves`: The rotation over a move placed by hand, from the gyro increments, and
  its sensitivity
- :mod:`calib.hand.plan`: The plan of a calibration run placed by hand: rest attitudes, rests, moves
- :mod:`calib.hand.poses`: A pose list for a run placed by hand: which face is up in each pose, how
  long it is held
- :mod:`calib.hand.predict`: The sigmas a pose plan will give, fast: the fit's own rows, without a
  simulated run
- :mod:`calib.hand.rests`: Where a run placed by hand rests: the still stretches between a person's
  moves
- :mod:`calib.hand.rounding`: Readings written coarser than their noise: what a rest's mean can and
  cannot tell
- :mod:`calib.hand.setup`: Before a hand fit: is the log what its labels say? Units, axes and rate,
  checked by physics
- :mod:`calib.hand.simulate`: Simulator of calibration runs placed by hand: exact IMU increments of
  a :class:`HandPlan`
- :mod:`calib.hand.summary`: What a fit of a run placed by hand used: its rests and moves, and the
  worst of them
- :mod:`calib.hand.trajectory`: The continuous truth trajectory of a run placed by hand, in closed
  form
- :mod:`calib.hand.tremor`: Hand tremor: the small wobble and shake of a pose held in the hand
  instead of set on a table
- :mod:`calib.hand.troubles`: What real hand recordings suffer from, for the simulator of runs
  placed by hand
- :mod:`calib.hand.weak`: The directions a hand fit leaves weak, in a user's words: parameters, or
  rests turning together
- :mod:`calib.hand.weights`: Weights that the data earn: variance components of a fit of a run
  placed by hand
"""

from calib.hand.calibrate import TermChoice, as_fit, fit_checked, hand_fit_of, summary_of
from calib.hand.data import HandData, hand_data, rest_noise_factor
from calib.hand.fit_options import HAND_FIT, HAND_REQUIREMENTS, HandFitOptions, HandSamples
from calib.hand.host_clock import epoch_ms, epoch_seconds, host_stamps, write_epoch_ms_csv
from calib.hand.joint_fit import FitState, HandFit, Layout, fit_by_hand, linearise, unknown_scales
from calib.hand.moves import move_rotation, move_sensitivity, right_jacobian, right_jacobian_inverse
from calib.hand.plan import (
    HAND_PLAN,
    HAND_POSES,
    HandPlan,
    PlanShape,
    bump,
    min_jerk,
    peak_factor,
    perpendicular_axes,
    random_hand_plan,
    random_poses,
    random_rotation,
    xsens_like_plan,
)
from calib.hand.poses import PoseList, load_poses, tip_to, tipping_plan
from calib.hand.predict import plan_sigma
from calib.hand.rests import Rests, find_rests, moving_mean, still_samples
from calib.hand.setup import (
    Mistake,
    carried_by_hand,
    carried_misfit,
    check_setup,
    diagnose,
    fixed,
    rate_mistake,
    static_refusal,
    still_stretches,
)
from calib.hand.simulate import (
    FROM_SEED,
    HandStreams,
    HandTruth,
    draw_errors,
    hand_meta,
    hand_truth_to_dict,
    plan_from_table,
    plan_to_table,
    quadrature,
    sample_times,
    simulate_by_hand,
    true_increments,
    write_hand_run,
    write_hand_truth,
)
from calib.hand.summary import HandSummary
from calib.hand.trajectory import HandState, hand_state, segment_of, sensed
from calib.hand.tremor import (
    Tremor,
    TremorState,
    held_at,
    held_rests,
    random_tremor,
    tremor_from_table,
    tremor_state,
    tremor_to_table,
)
from calib.hand.troubles import (
    HandTroubles,
    TroubleSpec,
    apply_g_sensitivity,
    g_sensitivity_from_dphg,
    random_g_sensitivity,
    troubles_from_table,
    troubles_to_table,
)
from calib.hand.weights import Weights, component_sizes, components, redundancy, refuted, reweighted

__all__ = [
    "FROM_SEED",
    "HAND_FIT",
    "HAND_PLAN",
    "HAND_POSES",
    "HAND_REQUIREMENTS",
    "FitState",
    "HandData",
    "HandFit",
    "HandFitOptions",
    "HandPlan",
    "HandSamples",
    "HandState",
    "HandStreams",
    "HandSummary",
    "HandTroubles",
    "HandTruth",
    "Layout",
    "Mistake",
    "PlanShape",
    "PoseList",
    "Rests",
    "TermChoice",
    "Tremor",
    "TremorState",
    "TroubleSpec",
    "Weights",
    "apply_g_sensitivity",
    "as_fit",
    "bump",
    "carried_by_hand",
    "carried_misfit",
    "check_setup",
    "component_sizes",
    "components",
    "diagnose",
    "draw_errors",
    "epoch_ms",
    "epoch_seconds",
    "find_rests",
    "fit_by_hand",
    "fit_checked",
    "fixed",
    "g_sensitivity_from_dphg",
    "hand_data",
    "hand_fit_of",
    "hand_meta",
    "hand_state",
    "hand_truth_to_dict",
    "held_at",
    "held_rests",
    "host_stamps",
    "linearise",
    "load_poses",
    "min_jerk",
    "move_rotation",
    "move_sensitivity",
    "moving_mean",
    "peak_factor",
    "perpendicular_axes",
    "plan_from_table",
    "plan_sigma",
    "plan_to_table",
    "quadrature",
    "random_g_sensitivity",
    "random_hand_plan",
    "random_poses",
    "random_rotation",
    "random_tremor",
    "rate_mistake",
    "redundancy",
    "refuted",
    "rest_noise_factor",
    "reweighted",
    "right_jacobian",
    "right_jacobian_inverse",
    "sample_times",
    "segment_of",
    "sensed",
    "simulate_by_hand",
    "static_refusal",
    "still_samples",
    "still_stretches",
    "summary_of",
    "tip_to",
    "tipping_plan",
    "tremor_from_table",
    "tremor_state",
    "tremor_to_table",
    "troubles_from_table",
    "troubles_to_table",
    "true_increments",
    "unknown_scales",
    "write_epoch_ms_csv",
    "write_hand_run",
    "write_hand_truth",
    "xsens_like_plan",
]
