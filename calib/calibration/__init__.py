"""The one calibrate entry (a run in memory or a file, on a gimbal or by hand), its result object and
the correction a user applies.

Modules:

- :mod:`calib.calibration.correction`: A calibration as the correction a user applies: ``calibrated
  = M (raw - b)`` per sensor
- :mod:`calib.calibration.entry`: Calibrate a logged run: the one library call behind ``seqdesign
  calibrate``
- :mod:`calib.calibration.result`: A calibration result: 21 values with 1-sigma, the initial
  attitude and the fit's health
"""

from calib.calibration.correction import (
    Correction,
    SensorCorrection,
    correction_from_parameters,
    correction_of_result,
    raw_samples,
)
from calib.calibration.entry import (
    CALIBRATE,
    CalibrateOptions,
    calibrate,
    check_streamable,
    rate_limit,
    reads_in_chunks,
    result_from_fit,
    samples_fingerprint,
)
from calib.calibration.result import CalibrationResult

__all__ = [
    "CALIBRATE",
    "CalibrateOptions",
    "CalibrationResult",
    "Correction",
    "SensorCorrection",
    "calibrate",
    "check_streamable",
    "correction_from_parameters",
    "correction_of_result",
    "rate_limit",
    "raw_samples",
    "reads_in_chunks",
    "result_from_fit",
    "samples_fingerprint",
]
