"""Re-exports of the analyser core, which moved to calib (to be deleted).

Kept only so that modules not yet updated (``seqdesign/design.py``) still
import; new code imports :mod:`calib.observability`, :mod:`calib.mounting`,
:mod:`calib.worstcase`, :mod:`calib.bounds` and :mod:`calib.nominal`.
"""

from calib.bounds import accel_density_at_rate, accel_scale_bound  # noqa: F401
from calib.mounting import SequenceModel, analyze, information, sequence_model  # noqa: F401
from calib.nominal import information_along, nominal_run  # noqa: F401
from calib.observability import CORRELATION_LIMIT, Observability, from_information  # noqa: F401
from calib.worstcase import (  # noqa: F401
    ExtrasCost,
    Robustness,
    analyze_extras,
    analyze_tolerance,
    search_worst_direct,
    search_worst_mounting,
)
