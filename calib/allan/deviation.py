"""Allan deviation of a static IMU channel and the fit of its noise terms.

Overlapping Allan deviation (``allantools.oadev``, IEEE Std 952 conventions) of
a rate (rad/s or m/s^2) at averaging times ``tau``. The noise terms and the
Allan variance each adds (IEEE Std 952-1997, annex C)::

    quantisation        Q   (rad, m/s)         3 Q^2 / tau^2     slope -1
    angle/velocity RW   N   (rad/sqrt(s), ..)  N^2 / tau         slope -1/2
    bias instability    B   (rad/s, m/s^2)     floor = B sqrt(2 ln 2 / pi) = 0.664 B
    rate random walk    K   (rad/s/sqrt(s))    K^2 tau / 3       slope +1/2
    sinusoid            W0 at f0 (rad/s, Hz)   W0^2 (sin^2(pi f0 tau) / (pi f0 tau))^2

A first-order Gauss-Markov bias (:mod:`calib.noise.gauss_markov`) of steady-state
sigma and correlation time T_c has the Allan variance (its PSD ``2 sigma^2 T_c /
(1 + (2 pi f T_c)^2)`` through the Allan transfer function; e.g. IEEE Std 952,
eq. C.14 with ``q_c^2 = 2 sigma^2 / T_c``)::

    avar = (2 sigma^2 T_c / tau) [1 - (T_c / 2 tau)(3 - 4 e^{-tau/T_c} + e^{-2 tau/T_c})]

which rises like a rate random walk (``2 sigma^2 tau / 3 T_c``) for ``tau << T_c``
and falls like white noise (``2 sigma^2 T_c / tau``) for ``tau >> T_c``. Its
maximum, over ``x = tau / T_c``, is at x = 1.893 and is 0.6174 sigma
(``GM_PEAK_TAU_RATIO``, ``GM_PEAK_ADEV_RATIO``; derived by maximising the bracket
numerically, checked in tests/calib/allan/test_allan.py): the relation between an Allan
floor and the GM sigma and tau of a profile.

A sinusoidal rate of amplitude W0 (a bench's or a building's vibration) peaks at
0.7246 W0 where tan x = 2x, x = pi f0 tau = 1.1656 (``SINUSOID_PEAK_X``,
``SINUSOID_PEAK_ADEV_RATIO``), vanishes at tau = k / f0 and falls as 1/tau between.

Which terms a curve shows, and their fit: :mod:`calib.allan.noise_terms`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.sequence.motion import runs_of

# Flat floor of a flicker (bias-instability) process: sigma_A = B sqrt(2 ln 2 / pi).
FLICKER_FLOOR_RATIO = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.6643
# Maximum of the GM Allan deviation: at tau = 1.893 T_c it is 0.6174 sigma.
GM_PEAK_TAU_RATIO = 1.8926
GM_PEAK_ADEV_RATIO = 0.6174
# Maximum of sin^2(x)/x (tan x = 2x): the sinusoid's peak deviation over its amplitude, and where.
SINUSOID_PEAK_X = 1.16556
SINUSOID_PEAK_ADEV_RATIO = 0.72461

SLOPE_TOLERANCE = 0.15  # a log-log slope within this of -1/2 (or +1/2) is "on the line"
# calib.noise.profiles' lower bound of a GM correlation time: a faster GM is white noise to a
# calibration run's 1 s intervals.
MIN_CORRELATION_S = 1.0
# Two stretches of the white line whose levels differ by less than this are one line.
WHITE_TIE = 0.05


@dataclass(frozen=True)
class AllanCurve:
    """Overlapping Allan deviation of one channel, with its 68.3 % confidence interval.

    Attributes
    ----------
    tau_s : ndarray
        Averaging times, s.
    adev : ndarray
        Allan deviation, the channel's SI unit (rad/s or m/s^2).
    ci_low, ci_high : ndarray
        68.3 % confidence interval of ``adev``: chi-squared with Greenhall's
        degrees of freedom (``allantools.edf_greenhall``) for the noise type
        of the curve's local slope (`noise_alpha`).
    """

    tau_s: np.ndarray
    adev: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray

    @property
    def slope(self) -> np.ndarray:
        """Local log-log slope d log(adev) / d log(tau)."""
        return np.gradient(np.log(self.adev), np.log(self.tau_s))


def octave_taus(n: int, dt: float, per_octave: int = 4) -> np.ndarray:
    """Averaging times ``m dt``, ``per_octave`` per octave, up to a tenth of the record.

    Beyond ``n / 10`` samples an average has fewer than ten independent
    neighbours and the deviation is too uncertain to fit.
    """
    top = math.log2(max(n // 10, 1))
    m = np.unique(np.round(2.0 ** np.arange(0.0, top + 1e-9, 1.0 / per_octave)))
    return m * dt


def noise_alpha(slope: np.ndarray) -> np.ndarray:
    """The power-law noise type (PSD of the rate ~ f^alpha) of each log-log slope.

    An Allan deviation of slope mu/2 comes from alpha = -mu - 1 (white rate 0,
    flicker -1, random walk -2), rounded to the nearest: what the degrees of freedom
    need (they change by a few tens of % from one type to the next). Steeper slopes
    (phase noise, quantisation) are taken as white rate noise, whose interval is the
    wider: they are at the shortest taus, where every interval is under 1 %.
    """
    return np.clip(np.rint(-2.0 * np.asarray(slope) - 1.0), -2, 0).astype(int)


def _smooth_slope(tau: np.ndarray, adev: np.ndarray) -> np.ndarray:
    """Log-log slope over about an octave (two taus either side): the local one wanders
    with the scatter of the long taus and would flip the noise type from tau to tau.
    """
    logt, loga = np.log(tau), np.log(adev)
    i = np.arange(tau.size)
    lo, hi = np.maximum(i - 2, 0), np.minimum(i + 2, tau.size - 1)
    span = np.where(hi > lo, logt[hi] - logt[lo], 1.0)
    return np.where(hi > lo, (loga[hi] - loga[lo]) / span, -0.5)


def allan_deviation(rate: np.ndarray, dt: float, taus: np.ndarray | None = None) -> AllanCurve:
    """Overlapping Allan deviation of a uniformly sampled rate.

    Parameters
    ----------
    rate : ndarray, shape (n,)
        Mean rate over each sample (increment / dt), SI.
    dt : float
        Sample period, s.
    taus : ndarray, optional
        Averaging times, s; default `octave_taus`.

    Returns
    -------
    AllanCurve
    """
    import allantools  # lazy: only profile fitting needs it

    rate = np.asarray(rate, dtype=float)
    taus = octave_taus(rate.size, dt) if taus is None else np.asarray(taus, dtype=float)
    # Removing the mean changes no Allan deviation; it keeps the sums well conditioned.
    tau, adev, _, _ = allantools.oadev(rate - rate.mean(), rate=1.0 / dt, data_type="freq", taus=taus)
    m = np.round(tau / dt).astype(int)
    alphas = noise_alpha(_smooth_slope(tau, adev))
    edf = np.array(
        [
            allantools.edf_greenhall(alpha=int(a), d=2, m=int(k), N=rate.size, overlapping=True)
            for a, k in zip(alphas, m, strict=True)
        ]
    )
    low, high = np.array([allantools.confidence_interval(a, e) for a, e in zip(adev, edf, strict=True)]).T
    return AllanCurve(tau_s=tau, adev=adev, ci_low=low, ci_high=high)


def avar_quantisation(tau, q: float):
    """Allan variance of quantisation noise of coefficient ``q``: ``3 q^2 / tau^2``."""
    return 3.0 * q**2 / np.asarray(tau) ** 2


def avar_white(tau, n: float):
    """Allan variance of white rate noise (angle/velocity random walk ``n``): ``n^2 / tau``."""
    return n**2 / np.asarray(tau)


def avar_rate_random_walk(tau, k: float):
    """Allan variance of a rate random walk of coefficient ``k``: ``k^2 tau / 3``."""
    return k**2 * np.asarray(tau) / 3.0


def avar_sinusoid(tau, amplitude: float, frequency_hz: float):
    """Allan variance of a sinusoidal rate (module docstring)."""
    x = math.pi * frequency_hz * np.asarray(tau, dtype=float)
    return (amplitude * np.sin(x) ** 2 / x) ** 2


def avar_gauss_markov(tau, sigma: float, correlation_s: float):
    """Allan variance of a first-order GM process (module docstring)."""
    tau = np.asarray(tau, dtype=float)
    x = tau / correlation_s
    # 3 - 4 e^-x + e^-2x = 2x - 2x^3/3 + x^4/2 - ...: below x = 1e-3 the series
    # (bracket = x^2/3 - x^3/4) avoids the cancellation of the closed form.
    xs = np.maximum(x, 1e-3)
    closed = 1.0 - (3.0 - 4.0 * np.exp(-xs) + np.exp(-2.0 * xs)) / (2.0 * xs)
    bracket = np.where(x < 1e-3, x**2 / 3.0 - x**3 / 4.0, closed)
    return 2.0 * sigma**2 * correlation_s / tau * bracket


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the consecutive True stretches of ``mask``."""
    return [np.arange(a, b) for a, b in zip(*runs_of(mask), strict=True)]


def white_region(curve: AllanCurve) -> np.ndarray:
    """Indices of the slope -1/2 region that gives N.

    Candidates: stretches of at least three taus, before the floor, whose local
    slope is within ``SLOPE_TOLERANCE`` of -1/2. Of several, the one with the
    lowest ``adev sqrt(tau)`` wins: a disturbance (a vibration bump, a filter
    resonance) adds variance and never removes it, so the lowest stretch is the
    sensor's own white noise. Levels within `WHITE_TIE` and the lowest stretch's own
    68 % interval of it are the same line broken by the scatter of the long taus: of
    those, the longest stretch.
    """
    floor = int(np.argmin(curve.adev))
    on_line = np.abs(curve.slope + 0.5) <= SLOPE_TOLERANCE
    on_line[floor:] = False
    runs = [r for r in _runs(on_line) if r.size >= 3] or _runs(on_line)
    if not runs:
        raise ValueError(
            "no slope -1/2 region before the floor: the log is too short "
            "or too coarsely sampled to show white noise"
        )
    level = np.array([np.median(curve.adev[r] * np.sqrt(curve.tau_s[r])) for r in runs])
    low = int(np.argmin(level))
    spread = float(np.median(curve.ci_high[runs[low]] / curve.adev[runs[low]])) - 1.0
    ties = np.flatnonzero(level <= level[low] * (1.0 + WHITE_TIE + spread))
    return runs[int(max(ties, key=lambda i: runs[i].size))]
