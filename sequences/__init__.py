"""Sequence files shipped with the tool (data only; see calib.sequence.definition)."""
