"""Self-calibration of a three-axis hybrid INS (see README)."""
