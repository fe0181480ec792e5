"""The three-axis gimbal: its description and files, the rule that picks the gimbal playing each flip
(and gimbal lock), the encoder angles along a run.

Modules:

- :mod:`calib.gimbal.description`: A gimbal description: its three axes' limits, the lock margin,
  and the gimbal files
- :mod:`calib.gimbal.encoders`: Where the gimbals stand: encoder angles and rates along a run, and
  at each rest position
- :mod:`calib.gimbal.rule`: The gimbal: its limits, which gimbal plays each flip, gimbal lock, and
  the encoder angles
"""

from calib.gimbal.description import Gimbal, GimbalAxis, builtin_gimbal_dir, gimbal_from_dict, load_gimbal
from calib.gimbal.encoders import RestPosition, encoder_track, rest_positions
from calib.gimbal.rule import (
    GimbalPlan,
    Move,
    Violation,
    check_playable,
    combined_path,
    gimbal_axes_in_body,
    in_lock,
    lock_distance,
    plan_move,
    plan_sequence,
    unlock_profile,
)

__all__ = [
    "Gimbal",
    "GimbalAxis",
    "GimbalPlan",
    "Move",
    "RestPosition",
    "Violation",
    "builtin_gimbal_dir",
    "check_playable",
    "combined_path",
    "encoder_track",
    "gimbal_axes_in_body",
    "gimbal_from_dict",
    "in_lock",
    "load_gimbal",
    "lock_distance",
    "plan_move",
    "plan_sequence",
    "rest_positions",
    "unlock_profile",
]
