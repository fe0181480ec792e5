"""What a gimbal sequence is and how it moves: the sequence file and its time line, rate profiles, the
exact kinematics of its motion, where a logged run turns and the sequence it followed.

Modules:

- :mod:`calib.sequence.definition`: Calibration sequences: an initial attitude, dwells, and flips
  about body axes
- :mod:`calib.sequence.inferred`: The nominal sequence a log followed, read off its navigation: grid
  rests and body-axis flips
- :mod:`calib.sequence.kinematics`: The kinematics of a sequence: exact body-frame integrals of its
  nominal motion, sample by sample
- :mod:`calib.sequence.motion`: Where a run turns: the one motion rule of the estimator, the chunked
  path and the viewer
- :mod:`calib.sequence.rate_profile`: Rate profiles of a move: constant rate, trapezoid, or S-curve
  (jerk-limited)
"""

from calib.sequence.definition import (
    Sequence,
    Step,
    Timeline,
    builtin_sequence_dir,
    load_sequence,
    nominal_attitude,
    resolve_sequence_path,
    save_sequence,
    sequence_from_dict,
    timeline,
)
from calib.sequence.inferred import infer_sequence
from calib.sequence.kinematics import SimConfig, body_integrals, true_increments, uniform_times
from calib.sequence.motion import (
    MotionDiagnosis,
    Segmentation,
    carried_cumsum,
    check_sequence_matches,
    detect_motion,
    diagnose_motion,
    grow,
    log_turns,
    motion_window,
    never_rotates,
    row_norm,
    runs_of,
    sample_motion,
    sequence_mask,
    sequence_motion,
    steady_rate,
    turn_angles,
    window_rate,
    windowed_motion,
)
from calib.sequence.rate_profile import Pieces, RateProfile

__all__ = [
    "MotionDiagnosis",
    "Pieces",
    "RateProfile",
    "Segmentation",
    "Sequence",
    "SimConfig",
    "Step",
    "Timeline",
    "body_integrals",
    "builtin_sequence_dir",
    "carried_cumsum",
    "check_sequence_matches",
    "detect_motion",
    "diagnose_motion",
    "grow",
    "infer_sequence",
    "load_sequence",
    "log_turns",
    "motion_window",
    "never_rotates",
    "nominal_attitude",
    "resolve_sequence_path",
    "row_norm",
    "runs_of",
    "sample_motion",
    "save_sequence",
    "sequence_from_dict",
    "sequence_mask",
    "sequence_motion",
    "steady_rate",
    "timeline",
    "true_increments",
    "turn_angles",
    "uniform_times",
    "window_rate",
    "windowed_motion",
]
