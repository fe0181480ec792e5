"""Readings written coarser than their noise: what a rest's mean can and cannot tell.

A logger that prints a gyro in whole deg/s (or an accelerometer to a few digits) rounds
each reading to a step ``q``. Where the sensor's own noise at rest spans several steps,
the rounding is dithered: it adds ``q^2 / 12`` to each sample's variance and averages
down with the rest's length like white noise, already in the rest's scatter. Where the
noise is well below a step, a still unit reads the same value at every sample: the
rest's mean is the true value rounded, off by up to ``q / 2`` however long the rest,
and a bias inside half a step reads as zero.

For Gaussian noise ``sigma`` the mean of the rounded readings errs by the rounding's
sawtooth smoothed by the noise, ``sum_k (-1)^k (q / (pi k)) exp(-2 pi^2 k^2 sigma^2 / q^2)
sin(2 pi k x / q)`` at a true value ``x``; over a value not known within a step its RMS is
``sqrt(sum_k (q / (pi k))^2 exp(-4 pi^2 k^2 sigma^2 / q^2) / 2)``: ``q / sqrt(12)`` with no
noise, 0.0016 ``q`` at ``sigma = q / 2``, nothing at a few steps. A rest's ``sigma`` is
taken from its rounded samples' scatter ``s`` by Sheppard's ``s^2 - q^2 / 12`` where
``s >= 0.6 q`` (``sigma`` from about ``q / 2`` up, where the rounding's share of ``s``
hardly depends on where the true value sits in its step: at ``sigma = 0.3 q`` ``s`` runs
0.26-0.51 ``q`` with the phase, at ``0.4 q`` 0.41-0.55); below, it is not known from the
readings (rounding moves each by up to ``q / 2``), and the error is taken at its largest,
``q / sqrt(12)``.
"""

from __future__ import annotations

import math

import numpy as np

HARMONICS = 200  # of the rounding's sawtooth: at no noise their powers sum to q^2 / 12 within 0.3 %
DITHERED = 0.6  # steps of rounded scatter from which the noise is known to dither the rounding
SAID_FLOOR = 0.01  # of a step: a rounding error on a rest's mean below this goes unsaid


def rounding_floor(samples: np.ndarray, q: float) -> float:
    """The rounding error's size on the mean of one rest's readings ``(m,)`` of step ``q``."""
    if not q > 0.0 or len(samples) < 2:
        return 0.0
    spread = float(np.std(samples))
    if spread >= DITHERED * q:  # the noise spans the step: Sheppard's, whatever the phase
        sigma2 = spread**2 - q * q / 12.0
    else:  # below, where the value sits in its step rules: the noise's lower bound
        sigma2 = 0.0
    k = np.arange(1, HARMONICS + 1)
    power = (q / (math.pi * k)) ** 2 * np.exp(-4.0 * math.pi**2 * k**2 * sigma2 / (q * q)) / 2.0
    return float(math.sqrt(power.sum()))


def rest_rounding(
    readings: np.ndarray, starts: np.ndarray, ends: np.ndarray, steps: np.ndarray
) -> np.ndarray:
    """Each rest's rounding error on each axis' mean, ``(K, 3)``, in the readings' unit (0: dithered).

    ``readings`` ``(n, 3)``, ``steps`` ``(3,)`` each axis' step (0: none).
    """
    out = np.zeros((len(starts), 3))
    for r, (a, b) in enumerate(zip(starts, ends, strict=True)):
        out[r] = [rounding_floor(readings[a:b, i], steps[i]) for i in range(3)]
    return out


def consider_rounding(
    covariance: np.ndarray,
    weighted_jacobian: np.ndarray,
    sigma: np.ndarray,
    labels: list,
    rounding: np.ndarray,
) -> np.ndarray:
    """The covariance, in the fit's scaled unknowns, of estimates whose rests' rates share a rounding.

    At rest a gyro reads its bias and the Earth's rate, the same within a step at every pose:
    each rest's rounding error on an axis is one and the same (a rest's share ``rounding[r, i]``
    of one unknown offset), which no residual shows and more rests do not average. Left out of
    the fit (its estimates lean on the rests as before), it is added to their covariance as
    a considered parameter: ``dx = C Jw^T (d / sigma)`` per axis, ``d`` the rests' shares on
    their rate rows, and ``C + sum dx dx^T``.
    """
    if not np.any(rounding > 0.0):
        return covariance
    rate_rows = [k for k, g in enumerate(labels) if g[0] == "rate"]
    out = covariance.copy()
    for i in range(3):
        d = np.zeros(len(labels))
        for k in rate_rows[i::3]:  # each rest's three rows, in axis order
            d[k] = rounding[labels[k][1], i]
        if not d.any():
            continue
        dx = covariance @ (weighted_jacobian.T @ (d / sigma))
        out += np.outer(dx, dx)
    return out


def rounding_lines(steps: np.ndarray, rest_rate_rounding: np.ndarray) -> list[str]:
    """What ``calibrate --by-hand`` says of a gyro written coarser than its noise at rest.

    ``steps`` ``(2, 3)`` the accelerometer's and the gyro's reading steps (SI), and each rest's
    rounding on its mean rate ``(K, 3)`` rad/s, as :class:`calib.hand.data.HandData` holds them.
    """
    said = rest_rate_rounding > SAID_FLOOR * steps[1]
    coarse = [i for i in range(3) if np.any(said[:, i])]
    if not coarse:
        return []
    rests = int(np.count_nonzero(np.any(said, axis=1)))
    step_dps = ", ".join(f"{math.degrees(steps[1, i]):.3g}" for i in coarse)
    worst_dph = math.degrees(float(rest_rate_rounding.max())) * 3600.0
    return [
        f"gyro {', '.join('xyz'[i] for i in coarse)} written in steps of {step_dps} deg/s, coarser than "
        f"its noise at {rests} of {len(rest_rate_rounding)} rests: a still unit reads its bias rounded "
        f"alike at every rest, so the biases' sigmas carry that rounding (up to {worst_dph:.3g} deg/h "
        "on a rest's mean) and more rests do not shrink them; log the gyro with more digits"
    ]
