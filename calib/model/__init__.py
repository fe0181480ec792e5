"""What is estimated and how well it must be: the 21 parameters, the error model, the optional terms,
the requirements, the Fisher information's rules, the per-parameter report.

Modules:

- :mod:`calib.model.error_model`: The 21-parameter IMU error model of ``conventions.md``
- :mod:`calib.model.information`: Fisher information: marginals, the scaled inverse, rank and
  estimability under one rule
- :mod:`calib.model.optional_terms`: Errors of a real unit beyond the paper's 21: the optional terms
- :mod:`calib.model.params`: The 21 IMU error parameters: order, names, units, requirements
- :mod:`calib.model.report`: Per-parameter reports (table and ``--json``) shared by calibrate and
  analyze
- :mod:`calib.model.requirements`: Accuracy requirements on the 21 calibration errors: the paper's,
  a shipped class, or a file
"""

from calib.model.error_model import ErrorModel, error_matrix_jacobian, paper_table
from calib.model.information import (
    ScaledInverse,
    describe_null,
    eliminate,
    inverse_diagonal,
    marginal,
    projected_covariance,
    row_echelon,
    scaled_inverse,
    weak_mask,
    weak_mask_batched,
)
from calib.model.optional_terms import (
    OptionalParameter,
    OptionalTerms,
    OptionalTermValues,
    apply,
    compensate,
    dv_sensitivity,
    earth_turn,
    lever,
    lever_matrix,
    load_optional_terms,
    parse_groups,
    parse_values,
    sample_rates,
)
from calib.model.params import Parameter, from_si, ratio, to_si
from calib.model.report import extra_entries, format_table, parameter_entries, worst
from calib.model.requirements import (
    Requirements,
    builtin_dir,
    default_for,
    grade_of,
    load_requirements,
    requirements_from_dict,
)

__all__ = [
    "ErrorModel",
    "OptionalParameter",
    "OptionalTermValues",
    "OptionalTerms",
    "Parameter",
    "Requirements",
    "ScaledInverse",
    "apply",
    "load_optional_terms",
    "builtin_dir",
    "compensate",
    "default_for",
    "describe_null",
    "dv_sensitivity",
    "earth_turn",
    "eliminate",
    "error_matrix_jacobian",
    "extra_entries",
    "format_table",
    "from_si",
    "grade_of",
    "inverse_diagonal",
    "lever",
    "lever_matrix",
    "load_requirements",
    "marginal",
    "paper_table",
    "parameter_entries",
    "parse_groups",
    "parse_values",
    "projected_covariance",
    "ratio",
    "requirements_from_dict",
    "row_echelon",
    "sample_rates",
    "scaled_inverse",
    "to_si",
    "weak_mask",
    "weak_mask_batched",
    "worst",
]
