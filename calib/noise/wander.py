"""How far a gyro's noise walks the attitude over a run, and the longest run a linearised fit follows.

The analyser, the design search and the estimator ask the same question of a noise profile before
they trust a linear model: does the attitude wander of a run of this length stay within what the
fit, linearised about the navigated attitude, was proven to follow (:data:`MAX_WANDER_DEG`)?
"""

from __future__ import annotations

import math

from calib.errors import CalibError

from .profiles import NoiseProfile

# The most attitude wander (1 sigma, from the run's start to its end) the linearised fit follows,
# deg. Measured (docs/grades.md, MEMS errors, +-3 deg mounting, 100 Hz), with the observations in
# the noise model's frame and the heading's trust region: 6.0 deg (ADIS16405 profile, 8-min
# design) 50 of 50 converge, NEES in band; 13.5 deg (the same profile, paper-9pos) 12 of 12, NEES
# 8-28; at 20 and 26 deg (a stronger gyro GM) 5 of 6 converge, NEES 7-25, one cycles in heading.
# Beyond what was proven at 96 % convergence the run is refused.
MAX_WANDER_DEG = 15.0


def tilt_variance(profile: NoiseProfile, duration_s: float) -> float:
    """Variance of the attitude the gyro noise builds over ``duration_s``, rad^2 per axis.

    White noise walks it as ``arw^2 T``; a first-order Gauss-Markov bias of
    steady-state sigma ``s`` and correlation time ``tau`` integrates to
    ``2 s^2 tau (T - tau (1 - exp(-T / tau)))``, which dominates for a MEMS gyro's
    bias instability (39 deg/h, 87 s: 6 deg over 30 min against 1.8 deg from its ARW).
    """
    T = duration_s
    variance = profile.arw**2 * T
    s, tau = profile.gyro_gm_sigma, profile.gyro_bias_correlation_s
    if s > 0.0 and tau > 0.0:
        variance += 2.0 * s**2 * tau * (T - tau * -math.expm1(-T / tau))
    return variance


def longest_run_s(profile: NoiseProfile, wander_deg: float = MAX_WANDER_DEG) -> float:
    """The run length over which the profile's gyro noise walks the attitude by ``wander_deg`` (s)."""
    target = math.radians(wander_deg) ** 2
    lo, hi = 0.0, 1.0
    while tilt_variance(profile, hi) < target:
        if hi > 1e9:
            return math.inf
        lo, hi = hi, 2.0 * hi
    for _ in range(60):  # tilt_variance grows with T: bisection to well below a second
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if tilt_variance(profile, mid) < target else (lo, mid)
    return lo


def check_wander(profile: NoiseProfile, duration_s: float, where: str) -> None:
    """Refuse a run whose attitude wander the linearised fit cannot follow (MAX_WANDER_DEG).

    Its sigmas would not be what the estimator achieves: beyond it the fit diverges, stalls or
    (measured once) converges 4 sigma off.
    """
    wander = math.degrees(math.sqrt(tilt_variance(profile, duration_s)))
    if wander <= MAX_WANDER_DEG:
        return
    longest = longest_run_s(profile)
    raise CalibError(
        f"the {profile.name} profile's gyro noise walks the attitude by {wander:.1f} deg (1 sigma) "
        f"over this {duration_s / 60.0:.1f}-min run; the fit, linearised about the navigated "
        f"attitude, follows at most {MAX_WANDER_DEG:g} deg",
        where,
        f"use a sequence of at most {longest / 60.0:.1f} min for this unit (its wander reaches "
        f"{MAX_WANDER_DEG:g} deg then), or a gyro with less bias instability",
    )


def attitude_wander_ratio(profile: NoiseProfile, duration_s: float, gravity_mps2: float) -> float:
    """Second-order gravity through the run's attitude wander over the accelerometer-bias resolution.

    Gravity leaks through the tilt the gyro noise builds (:func:`tilt_variance`)
    as ``g phi^2 / 2``, which the linear model does not have. The bias
    resolution of a run of length ``T`` is ``vrw / sqrt(T)``.
    """
    if profile.vrw <= 0.0:
        return math.inf
    return 0.5 * gravity_mps2 * tilt_variance(profile, duration_s) * math.sqrt(duration_s) / profile.vrw
