"""Bounds no sequence can beat: the accelerometer scale factors, excited by gravity alone."""

from __future__ import annotations

import math

from . import params as P
from .profiles import NoiseProfile
from .requirements import PAPER, Requirements


def accel_scale_bound(
    duration_s: float,
    profile: NoiseProfile,
    gravity_mps2: float,
    requirements: Requirements = PAPER,
    rate_dps: float | None = None,
) -> float:
    """Best possible worst ratio of the accelerometer scale factors (conventions.md).

    Gravity is their only excitation and ``sum f_i^2 = g^2``: the three share
    at most ``g^2 T / VRW^2`` of information, so at best each gets a third,
    ``sigma >= VRW sqrt(3 / T) / g``.

    With a Gauss-Markov accelerometer bias and a gimbal turning at most ``rate_dps``
    (docs/design.md, "What bounds the Gauss-Markov front"): the information of a long
    run in stationary noise of two-sided density ``S(f)`` is ``int |F(f)|^2 / S(f) df`` (Whittle). The noise
    density ``VRW^2 + S_gm(f)`` falls with frequency, and the rate limit
    ``|du/dt| <= omega`` on the direction of gravity bounds the regressor's power
    above ``f`` by ``(omega / 2 pi f)^2`` of its total; since ``1 / S`` is concave in
    ``(2 pi f)^2`` the best a sequence can do is put all of it at
    ``f = omega / 2 pi`` (one turn of gravity per ``360 / rate`` s), which
    replaces ``VRW^2`` by :func:`accel_density_at_rate`.
    """
    density = profile.vrw**2 if rate_dps is None else accel_density_at_rate(profile, rate_dps)
    sigma = math.sqrt(density * 3.0 / duration_s) / gravity_mps2
    return 3.0 * sigma / min(requirements.si[P.ACCEL_SCALE])


def accel_density_at_rate(profile: NoiseProfile, rate_dps: float) -> float:
    """Accelerometer noise density, ``(m/s^2)^2/Hz`` two-sided, at the frequency one
    turn takes at ``rate_dps``: white ``VRW^2`` plus the GM bias's
    ``2 sigma^2 tau / (1 + (2 pi f tau)^2)`` (whose integral over all f is ``sigma^2``).
    """
    density = profile.vrw**2
    tau = profile.accel_bias_correlation_s
    if profile.accel_gm_sigma > 0 and tau > 0:
        omega = math.radians(rate_dps)  # 2 pi f
        density += 2.0 * profile.accel_gm_sigma**2 * tau / (1.0 + (omega * tau) ** 2)
    return density
