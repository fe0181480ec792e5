"""The one Gauss-Markov bias a profile carries for a sensor, and what it cannot carry.

The analyser, the design search, the simulator and the estimator model white noise
and one first-order GM bias per sensor (:mod:`calib.noise.profiles`). A static log shows
more (:mod:`calib.allan.noise_terms`: a rate random walk, a second GM, a sinusoid, per
axis); `profile_gm` is the rule that picks the single GM standing for all of it
over the taus a calibration run lives at, and `not_modelled` names the rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.model.params import DEG_PER_HOUR, MICRO_G
from calib.noise.profiles import _GM_KEYS, _TAU_RANGE

from .deviation import GM_PEAK_ADEV_RATIO, AllanCurve, avar_white
from .noise_terms import BOUND_MARGIN, MODEL_FLOOR, NoiseFit, model_avar, trusted_end

# What matters to a calibration run: its intervals and rests (tens of seconds) up to
# its length (about an hour).
CALIBRATION_TAU_S = (10.0, 3600.0)
PROFILE_TAU_RANGE = _TAU_RANGE  # calib.noise.profiles' bounds of a GM correlation time, s
# The largest GM sigma a profile carries, SI (calib.noise.profiles' bounds).
PROFILE_SIGMA_MAX = {
    "gyro": _GM_KEYS["gyro_bias_instability_dph"][1] * DEG_PER_HOUR,
    "accel": _GM_KEYS["accel_bias_instability_ug"][1] * MICRO_G,
}
# A GM shows as one only when its correlation time is within this factor of the taus fitted:
# far beyond the longest its deviation rises as a rate random walk, and only sigma^2 / tau
# shows; far below the shortest it falls as white noise, and only sigma^2 tau shows. Either
# way sigma and tau are not determined apart (measured: a 20-min white-noise log, fitted over
# 10-97 s, gave a gyro "GM" of 1142 deg/h over 769,000 s from the scatter of its last taus).
IDENTIFIED_TAU_FACTOR = 10.0
# White noise alone is kept when it lies within this many 68 % intervals of the measured
# deviation at every tau fitted: the curve then shows no GM (about 95 % at each tau). Without
# it a 20-min white-noise log got a gyro GM of 9-48 deg/h in 33 fits of 60, the minimax
# following the scatter of its long taus; with it 15 of 60 (22-48 deg/h): such a log is short.
WHITE_WITHIN_INTERVALS = 2.0


@dataclass(frozen=True)
class ProfileGM:
    """The one GM bias a profile carries for a sensor (`profile_gm`), SI.

    Attributes
    ----------
    white : float
        The profile's N: the largest of the axes'.
    sigma, correlation_s : float
        The GM; both 0 when refused (``note`` says why).
    tau_s : tuple of float
        The range it was fitted over, s.
    ratio : tuple of float
        Least and greatest (white + GM) / worst axis' deviation over that range.
    note : str
    """

    white: float
    sigma: float
    correlation_s: float
    tau_s: tuple[float, float]
    ratio: tuple[float, float]
    note: str = ""


def profile_gm(
    curves: tuple[AllanCurve, ...], fits: tuple[NoiseFit, ...], sigma_max: float = math.inf
) -> ProfileGM:
    """The single GM that, with the largest white noise held, follows the worst axis over a run's taus.

    The rule: at each tau from `CALIBRATION_TAU_S` on (up to the last trusted tau of
    every axis) take the largest of the axes' measured deviations; with the
    profile's N (the largest axis') held, the GM sigma and correlation time whose
    worst ratio to it over that range is closest to 1 (minimax in log, `_minimax_gm`).
    A GM on a correlation-time bound of the profiles is refused (sigma 0), and so is one
    whose correlation time is not within `IDENTIFIED_TAU_FACTOR` of the taus fitted, one
    above ``sigma_max`` (what a profile carries, `PROFILE_SIGMA_MAX`), and one that brings
    the worst ratio closer to 1 by less than `MODEL_FLOOR` than white noise alone (the
    curve shows none). What the axes show beyond white noise and
    one GM (a rate random walk, a second GM, a sinusoid) is carried only as far as
    this GM follows the curve; `not_modelled` names it.
    """
    tau = curves[0].tau_s
    adevs = np.array([c.adev for c in curves])
    pick = (np.argmax(adevs, axis=0), np.arange(tau.size))  # the worst axis at each tau
    adev = adevs[pick]
    up = np.log(np.array([c.ci_high for c in curves])[pick] / adev)
    down = np.log(adev / np.array([c.ci_low for c in curves])[pick])
    end = min(trusted_end(c) for c in curves)
    keep = np.flatnonzero((tau >= CALIBRATION_TAU_S[0]) & (tau <= CALIBRATION_TAU_S[1]))
    keep = keep[keep < end]
    white = max(f.white for f in fits)
    if keep.size < 3:
        return ProfileGM(white, 0.0, 0.0, (0.0, 0.0), (1.0, 1.0), "the log is too short for a GM")
    tau, adev, up, down = tau[keep], adev[keep], up[keep], down[keep]  # log half-widths
    span = (float(tau[0]), float(tau[-1]))
    sigma, tc, worst = _minimax_gm(tau, adev, white)
    white_only = np.sqrt(avar_white(tau, white)) / adev
    bound = min(abs(math.log(tc / PROFILE_TAU_RANGE[0])), abs(math.log(tc / PROFILE_TAU_RANGE[1])))
    note = ""
    if bound < BOUND_MARGIN:
        note = (
            f"no GM: its correlation time went to its bound ({tc:.3g} s), so no single GM "
            f"follows the curve over {span[0]:.3g}-{span[1]:.3g} s"
        )
    elif not span[0] / IDENTIFIED_TAU_FACTOR <= tc <= span[1] * IDENTIFIED_TAU_FACTOR:
        shows = "rate random walk" if tc > span[1] else "white noise"
        note = (
            f"no GM: its correlation time ({tc:.3g} s) is far outside the taus fitted "
            f"({span[0]:.3g}-{span[1]:.3g} s), where a GM shows only as a {shows}: its sigma "
            "and correlation time are not determined apart"
        )
    elif sigma > sigma_max:
        note = f"no GM: its sigma ({sigma:.3g}, SI) is beyond what a profile carries ({sigma_max:.3g})"
    elif np.all(np.abs(np.log(white_only)) <= WHITE_WITHIN_INTERVALS * np.where(white_only > 1, up, down)):
        note = (
            f"no GM: white noise alone lies within {WHITE_WITHIN_INTERVALS:g} times the measured "
            f"deviation's 68 % interval at every tau of {span[0]:.3g}-{span[1]:.3g} s"
        )
    elif np.max(np.abs(np.log(white_only))) - worst < MODEL_FLOOR:
        note = f"no GM: white noise alone follows the curve over {span[0]:.3g}-{span[1]:.3g} s as well"
    if note:
        return ProfileGM(white, 0.0, 0.0, span, (float(white_only.min()), float(white_only.max())), note)
    ratio = np.sqrt(model_avar(tau, {"N": (white,), "GM": (sigma, tc)})) / adev
    return ProfileGM(white, sigma, tc, span, (float(ratio.min()), float(ratio.max())))


def _minimax_gm(tau, adev, white) -> tuple[float, float, float]:
    """The GM sigma and correlation time whose worst |log(model / measured)| is least, and that worst.

    Minimax rather than least squares: the profile is held to a stated +-% over the
    whole range, and no single GM can follow a floor and a rise alike, so the
    least-squares compromise would put its whole error at one end.
    """
    from scipy.optimize import minimize  # lazy: scipy.optimize is slow to import

    def worst(x):
        sigma, tc = np.exp(x)
        return float(
            np.max(np.abs(0.5 * np.log(model_avar(tau, {"N": (white,), "GM": (sigma, tc)}) / adev**2)))
        )

    bounds = [(math.log(adev.min() * 1e-3), math.log(adev.max() * 1e3)), tuple(np.log(PROFILE_TAU_RANGE))]
    best = None
    for tc in np.geomspace(2.0 * PROFILE_TAU_RANGE[0], 20.0 * tau[-1], 5):
        x0 = [math.log(float(adev.min()) / GM_PEAK_ADEV_RATIO), math.log(tc)]
        fit = minimize(worst, x0, method="Nelder-Mead", bounds=bounds, options={"xatol": 1e-4, "fatol": 1e-5})
        if best is None or fit.fun < best.fun:
            best = fit
    assert best is not None
    sigma, tc = np.exp(best.x)
    return float(sigma), float(tc), float(best.fun)


def not_modelled(fits: tuple[NoiseFit, ...]) -> list[str]:
    """The terms the axes show that a profile (white noise and one GM) cannot carry, with their axes."""
    labels = {
        "K": "rate random walk",
        "GM2": "a second GM",
        "SIN": "a sinusoid",
        "Q": "quantisation",
    }
    out = []
    for name, label in labels.items():
        axes = [a for a, f in zip("xyz", fits, strict=True) if name in f.terms()]
        if axes:
            if name == "SIN":
                hz = ", ".join(f"{f.sinusoid_hz:.3g}" for f in fits if f.sinusoid > 0)
                label += f" ({hz} Hz)"
            out.append(f"{label} on {', '.join(axes)}")
    return out
