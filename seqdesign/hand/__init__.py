"""Runs placed by hand, as a user plans them: the prediction of a pose list, its design, its protocol.

Modules: :mod:`.prediction` (the predicted sigma of a pose list or of a recording, under a
placement tolerance, and the cure of its weakest parameter), :mod:`.pose_search` (the poses,
their order and hold times for a time budget) and :mod:`.protocol` (the pose list as a TOML
file and a printable protocol). The physics (the fit, its information, the simulator of a hand
run) lives in :mod:`calib.hand`; this folder is what ``analyze``, ``design`` and ``verify`` do
with it under ``--by-hand``.
"""

from .pose_search import HandDesign, HandDesignOptions, candidate_ups, design_hand
from .prediction import HandAnalysis, HandPrediction, Placement, analyze_hand, analyze_recording, predict
from .protocol import pose_toml, protocol_markdown, write_protocol

__all__ = [
    "HandAnalysis",
    "HandDesign",
    "HandDesignOptions",
    "HandPrediction",
    "Placement",
    "analyze_hand",
    "analyze_recording",
    "candidate_ups",
    "design_hand",
    "pose_toml",
    "predict",
    "protocol_markdown",
    "write_protocol",
]
