"""A noise profile from a static log: the Allan deviation, the noise terms it shows, their plot, the
profile fit and its one Gauss-Markov bias.

Modules:

- :mod:`calib.allan.deviation`: Allan deviation of a static IMU channel and the fit of its noise
  terms
- :mod:`calib.allan.noise_terms`: The noise terms an Allan deviation shows: which, how large, and
  how well they follow it
- :mod:`calib.allan.plot`: The PNG of ``profile fit``: each axis' Allan deviation, its fit, and the
  profile's model
- :mod:`calib.allan.profile_fit`: A noise profile from a static log: Allan deviation per axis,
  fitted terms, the file
- :mod:`calib.allan.profile_gm`: The one Gauss-Markov bias a profile carries for a sensor, and what
  it cannot carry
- :mod:`calib.allan.static`: What a static unit must read, and its biases after removing it
"""

from calib.allan.deviation import (
    AllanCurve,
    allan_deviation,
    avar_gauss_markov,
    avar_quantisation,
    avar_rate_random_walk,
    avar_sinusoid,
    avar_white,
    noise_alpha,
    octave_taus,
    white_region,
)
from calib.allan.noise_terms import NoiseFit, fit_noise, fitted_range, model_avar, trusted_end
from calib.allan.plot import plot_allan
from calib.allan.profile_fit import (
    FittedProfile,
    ProfileFit,
    fit_log,
    fit_profile,
    header,
    per_axis_tables,
    plain,
    profile_doc,
    profile_table,
    profile_text,
    read_static_log,
    save_profile,
)
from calib.allan.profile_gm import ProfileGM, not_modelled, profile_gm
from calib.allan.static import StaticLevel, static_level

__all__ = [
    "AllanCurve",
    "FittedProfile",
    "NoiseFit",
    "ProfileFit",
    "ProfileGM",
    "StaticLevel",
    "allan_deviation",
    "avar_gauss_markov",
    "avar_quantisation",
    "avar_rate_random_walk",
    "avar_sinusoid",
    "avar_white",
    "fit_log",
    "fit_noise",
    "fit_profile",
    "fitted_range",
    "header",
    "model_avar",
    "noise_alpha",
    "not_modelled",
    "octave_taus",
    "per_axis_tables",
    "plain",
    "plot_allan",
    "profile_doc",
    "profile_gm",
    "profile_table",
    "profile_text",
    "read_static_log",
    "save_profile",
    "static_level",
    "trusted_end",
    "white_region",
]
