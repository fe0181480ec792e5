"""Allan deviation of a static IMU channel and the fit of its noise terms.

Overlapping Allan deviation (``allantools.oadev``, IEEE Std 952 conventions) of
a rate (rad/s or m/s^2) at averaging times ``tau``. The noise terms and the
Allan variance each adds (IEEE Std 952-1997, annex C)::

    quantisation        Q   (rad, m/s)         3 Q^2 / tau^2     slope -1
    angle/velocity RW   N   (rad/sqrt(s), ..)  N^2 / tau         slope -1/2
    bias instability    B   (rad/s, m/s^2)     floor = B sqrt(2 ln 2 / pi) = 0.664 B
    rate random walk    K   (rad/s/sqrt(s))    K^2 tau / 3       slope +1/2

A first-order Gauss-Markov bias (:mod:`calib.gaussmarkov`) of steady-state
sigma and correlation time T_c has the Allan variance (its PSD ``2 sigma^2 T_c /
(1 + (2 pi f T_c)^2)`` through the Allan transfer function; e.g. IEEE Std 952,
eq. C.14 with ``q_c^2 = 2 sigma^2 / T_c``)::

    avar = (2 sigma^2 T_c / tau) [1 - (T_c / 2 tau)(3 - 4 e^{-tau/T_c} + e^{-2 tau/T_c})]

which rises like a rate random walk (``2 sigma^2 tau / 3 T_c``) for ``tau << T_c``
and falls like white noise (``2 sigma^2 T_c / tau``) for ``tau >> T_c``. Its
maximum, over ``x = tau / T_c``, is at x = 1.893 and is 0.6174 sigma
(``GM_PEAK_TAU_RATIO``, ``GM_PEAK_ADEV_RATIO``; derived by maximising the bracket
numerically, checked in tests/test_allan.py): the relation between an Allan
floor and the GM sigma and tau of a profile.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .motion import runs_of

# Flat floor of a flicker (bias-instability) process: sigma_A = B sqrt(2 ln 2 / pi).
FLICKER_FLOOR_RATIO = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.6643
# Maximum of the GM Allan deviation: at tau = 1.893 T_c it is 0.6174 sigma.
GM_PEAK_TAU_RATIO = 1.8926
GM_PEAK_ADEV_RATIO = 0.6174

SLOPE_TOLERANCE = 0.15  # a log-log slope within this of -1/2 (or +1/2) is "on the line"
MIN_CORRELATION_S = 1.0  # calib.profiles' lower bound of a GM correlation time


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
        68.3 % confidence interval of ``adev`` (chi-squared with the degrees
        of freedom of ``allantools.edf_simple`` for white rate noise).
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
    edf = np.array([allantools.edf_simple(rate.size, int(k), 0) for k in m])
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


@dataclass(frozen=True)
class NoiseFit:
    """The noise terms of one channel, SI (see the module docstring for units).

    Attributes
    ----------
    white : float
        N: angle (rad/sqrt(s)) or velocity (m/s/sqrt(s)) random walk, from the
        slope -1/2 region ``white_tau_s``.
    white_tau_s : tuple of float
        First and last tau of that region, s.
    quantisation : float
        Q from the slope -1 region at the shortest taus; 0 when there is none.
    bias_instability : float
        B = floor / 0.664 (IEEE flicker convention), rad/s or m/s^2.
    floor_tau_s : float
        Where the floor (the minimum deviation) is, s.
    gm_sigma, gm_correlation_s : float
        The first-order Gauss-Markov bias that, with N and K, fits the curve
        from the white region on (weighted least squares in log deviation).
    rate_random_walk : float
        K, fitted with the GM bias; 0 when the curve shows none.
    """

    white: float
    white_tau_s: tuple[float, float]
    quantisation: float
    bias_instability: float
    floor_tau_s: float
    gm_sigma: float
    gm_correlation_s: float
    rate_random_walk: float

    def model_adev(self, tau) -> np.ndarray:
        """Allan deviation of the fitted terms (quantisation, white, GM, RRW)."""
        return np.sqrt(
            avar_quantisation(tau, self.quantisation)
            + avar_white(tau, self.white)
            + avar_gauss_markov(tau, self.gm_sigma, self.gm_correlation_s)
            + avar_rate_random_walk(tau, self.rate_random_walk)
        )


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the consecutive True stretches of ``mask``."""
    return [np.arange(a, b) for a, b in zip(*runs_of(mask), strict=True)]


def white_region(curve: AllanCurve) -> np.ndarray:
    """Indices of the slope -1/2 region that gives N.

    Candidates: stretches of at least three taus, before the floor, whose local
    slope is within ``SLOPE_TOLERANCE`` of -1/2. Of several, the one with the
    lowest ``adev sqrt(tau)`` wins: a disturbance (a vibration bump, a filter
    resonance) adds variance and never removes it, so the lowest stretch is the
    sensor's own white noise.
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
    level = [np.median(curve.adev[r] * np.sqrt(curve.tau_s[r])) for r in runs]
    return runs[int(np.argmin(level))]


def fit_noise(curve: AllanCurve) -> NoiseFit:
    """Fit quantisation, white noise, bias instability (floor and GM) and RRW.

    N is read off the slope -1/2 region (`white_region`), Q off the slope -1
    taus before it, B off the minimum. The GM sigma and correlation time and
    K are then fitted, with N and Q held, to the curve from the white region
    on (`_fit_gm`).
    """
    region = white_region(curve)
    tau, adev = curve.tau_s, curve.adev
    white = float(np.exp(np.mean(np.log(adev[region] * np.sqrt(tau[region])))))
    early = np.arange(region[0])
    steep = early[curve.slope[early] <= -1.0 + SLOPE_TOLERANCE]
    quantisation = float(np.median(adev[steep] * tau[steep] / math.sqrt(3.0))) if steep.size else 0.0
    floor = int(np.argmin(adev))
    sigma, correlation, k = _fit_gm(curve, region[0], white, quantisation)
    return NoiseFit(
        white=white,
        white_tau_s=(float(tau[region[0]]), float(tau[region[-1]])),
        quantisation=quantisation,
        bias_instability=float(adev[floor] / FLICKER_FLOOR_RATIO),
        floor_tau_s=float(tau[floor]),
        gm_sigma=sigma,
        gm_correlation_s=correlation,
        rate_random_walk=k,
    )


def _fit_gm(curve: AllanCurve, start: int, white: float, quantisation: float) -> tuple[float, float, float]:
    """GM sigma, correlation time and K by weighted least squares in log(adev).

    Each tau is weighted by the width of its confidence interval in log units
    (the deviation's relative uncertainty), and a soft-L1 loss keeps a local
    disturbance from dragging the fit. Started from the floor: a GM peak of
    0.617 sigma at 1.89 T_c placed on the minimum.
    """
    from scipy.optimize import least_squares  # lazy: scipy.optimize is slow to import

    tau, adev = curve.tau_s[start:], curve.adev[start:]
    scale = 0.5 * np.log(curve.ci_high[start:] / curve.ci_low[start:])
    fixed = avar_white(tau, white) + avar_quantisation(tau, quantisation)

    def residual(x):
        sigma, correlation, k = np.exp(x)
        model = fixed + avar_gauss_markov(tau, sigma, correlation) + avar_rate_random_walk(tau, k)
        return 0.5 * np.log(model / adev**2) / scale

    # Correlation times from MIN_CORRELATION_S (the profiles' lower bound: shorter
    # is white noise to a calibration run, and it keeps a short-tau disturbance such
    # as the ADIS accelerometers' 0.5-1 s bump from being taken for the GM) to ten
    # times the longest tau (longer cannot be told from a rate random walk).
    low, high = math.log(MIN_CORRELATION_S), math.log(10.0 * tau[-1])
    bounds = ([-np.inf, low, -np.inf], [np.inf, high, np.inf])
    best = None
    for log_tc in np.linspace(low, high, 6):  # multi-start: the cost has several valleys
        peak = np.clip(math.exp(log_tc) * GM_PEAK_TAU_RATIO, tau[0], tau[-1])
        level = np.interp(math.log(peak), np.log(tau), adev)
        x0 = np.array([math.log(level / GM_PEAK_ADEV_RATIO), log_tc, math.log(adev[-1] / math.sqrt(tau[-1]))])
        fit = least_squares(residual, x0, bounds=bounds, loss="soft_l1", f_scale=2.0)
        if best is None or fit.cost < best.cost:
            best = fit
    assert best is not None  # six starts
    fit = best
    sigma, correlation, k = np.exp(fit.x)
    # A K whose ramp stays below a tenth of the curve everywhere is not in the data.
    if np.all(avar_rate_random_walk(tau, k) < 0.01 * adev**2):
        k = 0.0
    return float(sigma), float(correlation), float(k)
