"""Bounds no sequence can beat: the accelerometer scale factors, excited by gravity alone."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.model import params as P
from calib.model.requirements import PAPER, Requirements
from calib.noise.profiles import NoiseProfile


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


def bias_bound_sigma(duration_s: float, white: float, gm_sigma: float = 0.0, gm_tau_s: float = 0.0) -> float:
    """Smallest sigma any run of ``duration_s`` reaches on a sensor bias (SI).

    The bias is read, at best, directly through the sensor's own noise for the
    whole run. White noise alone (density ``white^2``) leaves ``white^2 / T``. A
    stationary Gauss-Markov bias (``gm_sigma``, ``gm_tau_s``) alone, watched
    continuously and without white noise, leaves ``2 sigma^2 tau / (T + 2 tau)``
    of the constant part (the mean of an Ornstein-Uhlenbeck process over ``T``:
    ``sigma^2`` for a run short against ``tau``, ``2 sigma^2 tau / T`` for a long
    one). With both noises the information is less than with either alone, so
    the larger of the two variances is a bound no sequence beats.
    """
    var = white**2 / duration_s
    if gm_sigma > 0 and gm_tau_s > 0:
        var = max(var, 2.0 * gm_sigma**2 * gm_tau_s / (duration_s + 2.0 * gm_tau_s))
    return math.sqrt(var)


def bias_duration_needed(
    target_sigma: float, white: float, gm_sigma: float = 0.0, gm_tau_s: float = 0.0
) -> float:
    """Shortest run whose :func:`bias_bound_sigma` is ``target_sigma`` (s): where the bound allows it."""
    need = white**2 / target_sigma**2
    if gm_sigma > 0 and gm_tau_s > 0:
        need = max(need, 2.0 * gm_tau_s * (gm_sigma**2 / target_sigma**2 - 1.0))
    return need


# The longest sequence a file may describe (calib.sequence.definition refuses more).
MAX_SEQUENCE_S = 6 * 3600.0


@dataclass(frozen=True)
class Unreachable:
    """Requirements no sequence of a given length meets, by a bound of this module.

    Attributes
    ----------
    names : tuple of str
        The parameters (``bgx``, ``bgy``, ``bgz``).
    ratio : float
        The best ``3 sigma / requirement`` a run of that length can reach (> 1).
    needed_s : float
        The shortest run whose bound meets them all, s.
    why : str
        What holds them back, for the user (``"the gyro bias's Gauss-Markov wander ..."``).
    """

    names: tuple[str, ...]
    ratio: float
    needed_s: float
    why: str

    def text(self, duration_s: float) -> str:
        """One line: which, by how much, why, and the length that would do."""
        could = (
            f"a run of at least {format_duration(self.needed_s)} could"
            if self.needed_s <= MAX_SEQUENCE_S
            else f"not even {format_duration(MAX_SEQUENCE_S)}, the longest a sequence may last, could"
        )
        return (
            f"no sequence of {format_duration(duration_s)} meets {', '.join(self.names)}: the best "
            f"possible 3 sigma is {self.ratio:.3g} x the requirement ({self.why}); {could}"
        )


def format_duration(seconds: float) -> str:
    """``'600 s'``, ``'28.2 min'``, ``'4.2 h'``: a length as a user reads it."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def unreachable(
    duration_s: float,
    profile: NoiseProfile,
    gravity_mps2: float,
    requirements: Requirements = PAPER,
    rate_dps: float | None = None,
) -> list[Unreachable]:
    """The requirements no run of ``duration_s`` can meet under ``profile``'s noise.

    Each bound is physical, known before any search: the gyro and accelerometer
    biases (:func:`bias_bound_sigma`) and the accelerometer scale factors
    (:func:`accel_scale_bound`). A requirement a bound allows may still be missed
    by a given sequence; one it forbids is missed by every sequence.
    """
    out = []
    sensors = (
        ("gyro", P.GYRO_BIAS, profile.arw, profile.gyro_gm_sigma, profile.gyro_bias_correlation_s, "deg/h"),
        (
            "accelerometer",
            P.ACCEL_BIAS,
            profile.vrw,
            profile.accel_gm_sigma,
            profile.accel_bias_correlation_s,
            "ug",
        ),
    )
    for sensor, which, white, gm_sigma, gm_tau, unit in sensors:
        req = float(np.min(requirements.si[which]))
        ratio = 3.0 * bias_bound_sigma(duration_s, white, gm_sigma, gm_tau) / req
        if ratio <= 1.0:
            continue
        gm_wins = bias_bound_sigma(duration_s, white) < bias_bound_sigma(duration_s, 0.0, gm_sigma, gm_tau)
        scale = P.SI_PER_UNIT[which.start]
        why = (
            f"the {sensor} bias's Gauss-Markov wander, {gm_sigma / scale:.3g} {unit} over {gm_tau:.0f} s"
            if gm_wins
            else f"the {sensor}s' white noise"
        )
        names = tuple(P.NAMES[which])
        out.append(Unreachable(names, ratio, bias_duration_needed(req / 3.0, white, gm_sigma, gm_tau), why))
    ratio = accel_scale_bound(duration_s, profile, gravity_mps2, requirements, rate_dps)
    if ratio > 1.0:
        # sigma falls as 1 / sqrt(T) (the density at the turning rate does not depend on T)
        out.append(
            Unreachable(
                tuple(P.NAMES[P.ACCEL_SCALE]),
                ratio,
                duration_s * ratio**2,
                "gravity is their only excitation",
            )
        )
    return out
