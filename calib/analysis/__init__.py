"""The analyser: a sequence's information along its nominal trajectory, over every mounting of the
tolerance box (white and Gauss-Markov noise), the worst case, observability, and the bounds no
sequence beats.

Modules:

- :mod:`calib.analysis.bounds`: Bounds no sequence can beat: the accelerometer scale factors,
  excited by gravity alone
- :mod:`calib.analysis.gm_mounting`: The mounting basis under Gauss-Markov bias instability: any
  mounting's exact information fast
- :mod:`calib.analysis.ipopt`: IPOPT over python functions: one casadi Callback with its Jacobian,
  and a box maximiser
- :mod:`calib.analysis.mounting`: The mounting basis: the whitened observation model of a sequence
  for every base mounting
- :mod:`calib.analysis.nominal`: The error-free trajectory of a sequence and the Fisher information
  along it
- :mod:`calib.analysis.observability`: What the Fisher information of a sequence says at one
  mounting: sigma, rank, separability
- :mod:`calib.analysis.worst_case`: The worst case over the mounting box: grid points, then an IPOPT
  search beyond them
"""

from calib.analysis.bounds import (
    Unreachable,
    accel_density_at_rate,
    accel_scale_bound,
    bias_bound_sigma,
    bias_duration_needed,
    format_duration,
    unreachable,
)
from calib.analysis.gm_mounting import (
    GmBasis,
    OptionalTermsBasis,
    box_informations,
    box_points,
    extra_basis,
    extra_chunks,
    extra_columns,
    gm_basis,
    informations,
    nominal_information,
    release_caches,
    whitened_grams,
)
from calib.analysis.ipopt import Function, function, maximize_in_box, options
from calib.analysis.mounting import (
    SequenceModel,
    analyze,
    basis_chunks,
    basis_weights,
    basis_weights_jacobian,
    combination,
    information,
    rotvec_derivatives,
    sequence_model,
)
from calib.analysis.nominal import (
    NominalRun,
    information_along,
    information_along_many,
    information_one,
    mounting_informations,
    noise_along,
    nominal_run,
    nominal_samples,
    same_grid,
)
from calib.analysis.observability import Observability, from_information
from calib.analysis.worst_case import (
    Evaluation,
    OptionalTermsCost,
    Robustness,
    analyze_extras,
    analyze_tolerance,
    box_interpolant_maximum,
    search_worst_direct,
    search_worst_mounting,
)

__all__ = [
    "OptionalTermsBasis",
    "Evaluation",
    "OptionalTermsCost",
    "Function",
    "GmBasis",
    "NominalRun",
    "Observability",
    "Robustness",
    "SequenceModel",
    "Unreachable",
    "accel_density_at_rate",
    "accel_scale_bound",
    "analyze",
    "analyze_extras",
    "analyze_tolerance",
    "basis_chunks",
    "basis_weights",
    "basis_weights_jacobian",
    "bias_bound_sigma",
    "bias_duration_needed",
    "box_informations",
    "box_interpolant_maximum",
    "box_points",
    "combination",
    "extra_basis",
    "extra_chunks",
    "extra_columns",
    "format_duration",
    "from_information",
    "function",
    "gm_basis",
    "information",
    "information_along",
    "information_along_many",
    "information_one",
    "informations",
    "maximize_in_box",
    "mounting_informations",
    "noise_along",
    "nominal_information",
    "nominal_run",
    "nominal_samples",
    "options",
    "release_caches",
    "rotvec_derivatives",
    "same_grid",
    "search_worst_direct",
    "search_worst_mounting",
    "sequence_model",
    "unreachable",
    "whitened_grams",
]
