"""The noise terms an Allan deviation shows: which, how large, and how well they follow it.

IEEE Std 952 style: the Allan variance of independent noise terms adds, so a model
is a sum of the terms of :mod:`~calib.allan.deviation` (white noise N always; quantisation Q,
one or two first-order Gauss-Markov biases, a rate random walk K and a sinusoid
where the curve shows them), fitted by weighted least squares in log deviation,
each tau weighted by its 68 % confidence interval widened by `MODEL_FLOOR`.

Which terms: every candidate set is fitted, and the one of least BIC (chi-squared
plus ln(n) per parameter) among those with no correlation time or frequency on
its bound wins. A term on a bound is the fit leaning on the edge of what it may
say (a GM of T_c = 1 s standing in for a 1 Hz disturbance, say), not a fact:
that set is refused and the reason kept in ``notes``. Quantisation and the
sinusoid are candidates only where the curve shows them (`_shows_quantisation`,
`_bump`), so that neither is reported on a curve without it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from calib.sequence.motion import runs_of

from .deviation import (
    FLICKER_FLOOR_RATIO,
    GM_PEAK_ADEV_RATIO,
    MIN_CORRELATION_S,
    SINUSOID_PEAK_ADEV_RATIO,
    SINUSOID_PEAK_X,
    SLOPE_TOLERANCE,
    AllanCurve,
    avar_gauss_markov,
    avar_quantisation,
    avar_rate_random_walk,
    avar_sinusoid,
    avar_white,
    white_region,
)

# No sum of a few terms follows a real curve to better than a few %: without this
# floor the short taus' 0.3 % intervals would own the fit and the long taus, where
# a calibration run lives, would count for nothing.
MODEL_FLOOR = 0.03
# Taus before the white region still count as white when within this of its line;
# further off, shorter taus are the sensor's output filter (below the line) or a
# disturbance near the Nyquist frequency (above it), which no noise term models.
WHITE_AGREEMENT = 0.10
# A bump: at least BUMP_TAUS consecutive taus whose measured deviation exceeds the
# best fit without a sinusoid by BUMP_EXCESS or more.
BUMP_EXCESS = 0.15
BUMP_TAUS = 3
# A point known to no better than this (68 % interval) can neither pin a term nor
# test a fit held to the same: the fitted range ends before the first such tau.
TRUSTED_CI = 0.25
BOUND_MARGIN = 0.01  # log units: a correlation time or frequency within 1 % of its bound is on it
PRUNE_SHARE = 0.01  # a term under this share of the measured variance at every tau is not shown
JAC_STEP = 1e-6  # forward step in a log time or frequency, for the Jacobian
WHITE_FREEDOM = 4.0  # the joint fit's N stays within this factor of the white region's

# Each term: its parameters (SI) and its Allan variance.
TERMS: dict[str, tuple[tuple[str, ...], Callable[..., np.ndarray]]] = {
    "N": (("white",), avar_white),
    "Q": (("quantisation",), avar_quantisation),
    "GM": (("gm_sigma", "gm_correlation_s"), avar_gauss_markov),
    "GM2": (("gm2_sigma", "gm2_correlation_s"), avar_gauss_markov),
    "K": (("rate_random_walk",), avar_rate_random_walk),
    "SIN": (("sinusoid", "sinusoid_hz"), avar_sinusoid),
}
# The sets of slow terms tried; Q and the sinusoid are added to each where the curve shows them.
SLOW_SETS = (("N",), ("N", "K"), ("N", "GM"), ("N", "GM", "K"), ("N", "GM", "GM2"), ("N", "GM", "GM2", "K"))


@dataclass(frozen=True)
class NoiseFit:
    """The noise terms of one channel, SI (units: :mod:`~calib.allan.deviation`); 0 for a term not seen.

    Attributes
    ----------
    white : float
        N: angle (rad/sqrt(s)) or velocity (m/s/sqrt(s)) random walk, fitted with the
        other terms, started from the slope -1/2 region ``white_tau_s``.
    white_tau_s : tuple of float
        First and last tau of that region, s.
    quantisation : float
        Q, rad or m/s.
    bias_instability : float
        B = floor / 0.664 (IEEE flicker convention), rad/s or m/s^2.
    floor_tau_s : float
        Where the floor (the minimum deviation) is, s.
    gm_sigma, gm_correlation_s : float
        The first-order Gauss-Markov bias (the shorter correlation time of two).
    gm2_sigma, gm2_correlation_s : float
        A second, slower one, where the floor is broader than one GM's.
    rate_random_walk : float
        K, rad/s/sqrt(s) or m/s^2/sqrt(s).
    sinusoid, sinusoid_hz : float
        Amplitude (rad/s or m/s^2) and frequency of a periodic disturbance.
    fit_tau_s : tuple of float
        The fitted range, s.
    fit_ratio : tuple of float
        Least and greatest model / measured deviation over the fitted range.
    notes : tuple of str
        What the fit refused or left out, and why.
    """

    white: float
    white_tau_s: tuple[float, float]
    quantisation: float
    bias_instability: float
    floor_tau_s: float
    gm_sigma: float
    gm_correlation_s: float
    rate_random_walk: float
    gm2_sigma: float = 0.0
    gm2_correlation_s: float = 0.0
    sinusoid: float = 0.0
    sinusoid_hz: float = 0.0
    fit_tau_s: tuple[float, float] = (0.0, 0.0)
    fit_ratio: tuple[float, float] = (1.0, 1.0)
    notes: tuple[str, ...] = ()

    def terms(self) -> dict[str, tuple[float, ...]]:
        """The terms present, name: parameters (SI)."""
        out = {}
        for name, (keys, _) in TERMS.items():
            values = tuple(float(getattr(self, k)) for k in keys)
            if values[0] > 0:
                out[name] = values
        return out

    def model_adev(self, tau) -> np.ndarray:
        """Allan deviation of the fitted terms."""
        return np.sqrt(model_avar(tau, self.terms()))


def model_avar(tau, terms: dict[str, tuple[float, ...]]) -> np.ndarray:
    """Allan variance of a sum of terms (``TERMS`` names and their SI parameters)."""
    tau = np.asarray(tau, dtype=float)
    total = np.zeros_like(tau)
    for name, p in terms.items():
        avar: Callable[..., np.ndarray] = TERMS[name][1]
        total = total + avar(tau, *p)
    return total


@dataclass(frozen=True)
class _Candidate:
    terms: dict[str, tuple[float, ...]]
    chi2: float
    on_bound: str  # why the set is refused ("" if it is not)

    @property
    def n_params(self) -> int:
        return sum(len(p) for p in self.terms.values())


def fitted_range(curve: AllanCurve, region: np.ndarray, white: float) -> tuple[slice, bool]:
    """The taus the fit is held to (and reported over), and whether they show quantisation.

    From the white region on, extended to shorter taus while they stay on its line
    (`WHITE_AGREEMENT`), up to the last trusted tau (`trusted_end`). When the
    shorter taus left out rise above the line as 1/tau down to the shortest
    (`_shows_quantisation`), from the shortest tau: those taus are what measure Q.
    The fit itself also takes the untrusted taus beyond, at their weight.
    """
    on_line = np.abs(curve.adev * np.sqrt(curve.tau_s) / white - 1.0) <= WHITE_AGREEMENT
    start = int(region[0])
    while start > 0 and on_line[start - 1]:
        start -= 1
    quantised = _shows_quantisation(curve, start, white)
    return slice(0 if quantised else start, trusted_end(curve)), quantised


def trusted_end(curve: AllanCurve) -> int:
    """One past the last tau before the first whose 68 % interval is wider than `TRUSTED_CI`."""
    wide = np.flatnonzero(curve.ci_high / curve.adev - 1.0 > TRUSTED_CI)
    return int(wide[0]) if wide.size else curve.tau_s.size


def _shows_quantisation(curve: AllanCurve, start: int, white: float) -> bool:
    """Whether the taus before ``start`` rise above the white line, as 1/tau at the shortest.

    Quantisation is 3 Q^2 / tau^2: above the white line and steepest at the
    shortest taus. A flat start (an output filter, a disturbance near the Nyquist
    frequency, as on the ADIS16405's z gyro) or one below the line is not it.
    """
    if start < 2:
        return False
    early = slice(0, start)
    above = curve.adev[early] * np.sqrt(curve.tau_s[early]) > white * (1 + WHITE_AGREEMENT)
    steep = math.log(curve.adev[1] / curve.adev[0]) / math.log(curve.tau_s[1] / curve.tau_s[0])
    return bool(np.all(above) and steep <= -1.0 + 2 * SLOPE_TOLERANCE)


def _bump(tau: np.ndarray, adev: np.ndarray, model_adev: np.ndarray) -> int | None:
    """Index of the peak excess of a bump the model misses, or None."""
    above = adev * (1.0 - BUMP_EXCESS) > model_adev
    best = None
    for a, b in zip(*runs_of(above), strict=True):
        if b - a >= BUMP_TAUS:
            k = int(a + np.argmax(adev[a:b] ** 2 - model_adev[a:b] ** 2))
            if best is None or adev[k] / model_adev[k] > adev[best] / model_adev[best]:
                best = k
    return best


def _log_bounds(name: str, tau: np.ndarray, white: float) -> list[tuple[float, float]]:
    """Bounds of a term's parameters in log units; other amplitudes are free (wide finite bounds)."""
    free = (math.log(1e-30), math.log(1e10))
    if name == "N":
        # Near the white region's level: free, a fast GM and a small N trade places
        # (a GM far shorter than tau is white noise) and the fit wanders off.
        return [(math.log(white / WHITE_FREEDOM), math.log(white * WHITE_FREEDOM))]
    if name in ("GM", "GM2"):
        # From MIN_CORRELATION_S (a faster GM is white noise to a calibration run; what the
        # curve shows there above the white line is a disturbance or the sensor's filter)
        # or the shortest fitted tau, to ten times the longest (a slower GM cannot be
        # told from a rate random walk).
        return [free, (math.log(max(MIN_CORRELATION_S, tau[0])), math.log(10.0 * tau[-1]))]
    if name == "SIN":  # its first peak within the fitted taus
        return [
            free,
            (math.log(SINUSOID_PEAK_X / (math.pi * tau[-1])), math.log(SINUSOID_PEAK_X / (math.pi * tau[0]))),
        ]
    return [free]


def _fit_set(tau, adev, scale, starts: list[dict[str, tuple[float, ...]]], held=None) -> _Candidate:
    """Least squares of one set of terms in log deviation, from several starts; the best.

    ``held`` terms are in the model but not fitted. N is bounded about its first start.
    """
    from scipy.optimize import least_squares  # lazy: scipy.optimize is slow to import

    held = held or {}
    names = tuple(starts[0])
    white = starts[0]["N"][0] if "N" in names else 0.0
    bounds = [b for n in names for b in _log_bounds(n, tau, white)]
    lo, hi = np.array(bounds).T

    def unpack(x) -> dict[str, tuple[float, ...]]:
        out, i = {}, 0
        for n in names:
            k = len(TERMS[n][0])
            out[n] = tuple(float(v) for v in np.exp(x[i : i + k]))
            i += k
        return out

    base = model_avar(tau, held)

    def residual(x):
        return 0.5 * np.log((base + model_avar(tau, unpack(x))) / adev**2) / scale

    def jacobian(x):
        # Every term's variance is its first parameter squared times a shape: the
        # derivative in that log parameter is twice the term; the time or frequency
        # (second parameter) by a forward difference of the term alone.
        terms = unpack(x)
        parts = [TERMS[n][1](tau, *terms[n]) for n in names]
        weight = 0.5 / ((base + sum(parts)) * scale)
        columns = []
        for n, part in zip(names, parts, strict=True):
            columns.append(2.0 * part * weight)
            if len(terms[n]) == 2:
                amp, slow = terms[n]
                shifted = TERMS[n][1](tau, amp, slow * math.exp(JAC_STEP))
                columns.append((shifted - part) / JAC_STEP * weight)
        return np.column_stack(columns)

    best = None
    for start in starts:
        x0 = np.clip(np.log([v for n in names for v in start[n]]), lo + 1e-6, hi - 1e-6)
        fit = least_squares(residual, x0, jac=jacobian, bounds=(lo, hi), ftol=1e-6, xtol=1e-6)
        if best is None or fit.cost < best.cost:
            best = fit
    assert best is not None
    on = [
        f"its {_what(n)} went to its bound ({math.exp(_nearer(best.x[i], a, b)):.3g} {_unit(n)})"
        for n, (i, (a, b)) in zip(names, _slow_parameter_bounds(names, lo, hi), strict=True)
        if i is not None and min(best.x[i] - a, b - best.x[i]) < BOUND_MARGIN
    ]
    return _Candidate(unpack(best.x), float(2.0 * best.cost), "; ".join(on))


def _nearer(x: float, a: float, b: float) -> float:
    return a if x - a < b - x else b


def _what(name: str) -> str:
    return {"GM": "GM's correlation time", "GM2": "second GM's correlation time"}.get(
        name, "sinusoid's frequency"
    )


def _unit(name: str) -> str:
    return "Hz" if name == "SIN" else "s"


def _slow_parameter_bounds(names, lo, hi):
    """For each term, the index of its time or frequency parameter (None for none) and its bounds."""
    out, i = [], 0
    for n in names:
        k = len(TERMS[n][0])
        j = i + 1 if k == 2 else None
        out.append((j, (lo[j], hi[j]) if j is not None else (0.0, 0.0)))
        i += k
    return out


def _starts(names, tau, adev, white, extra, fitted) -> list[dict[str, tuple[float, ...]]]:
    """Starting points of a set: its nested sets' best fits (the new term at a default), and
    for the GM sets a spread of correlation times (the cost has a valley per feature of the curve).
    """
    floor = float(adev.min()) / GM_PEAK_ADEV_RATIO
    k0 = float(adev[-1]) * math.sqrt(3.0 / tau[-1]) * 0.5
    tcs = np.geomspace(max(MIN_CORRELATION_S, tau[0]) * 1.5, 5.0 * tau[-1], 4)
    base = {"N": (white,), "K": (k0,), "GM": (floor, float(tcs[1])), **extra}
    starts = []
    if "GM2" in names:
        starts += [{**base, "GM": (floor, tcs[i]), "GM2": (floor, tcs[i + 2])} for i in (0, 1)]
    elif "GM" in names:
        starts += [{**base, "GM": (floor, tc)} for tc in tcs]
    else:
        starts.append(base)  # first: N's bounds are about its start (_fit_set)
    for prev in fitted:
        if set(prev.terms) < set(names):
            gm = prev.terms.get("GM", base["GM"])
            starts.append({**base, "GM2": (floor, min(gm[1] * 10.0, float(tau[-1]))), **prev.terms})
    return [{n: s[n] for n in names} for s in starts]


def _select(candidates: list[_Candidate], tau: np.ndarray) -> tuple[_Candidate, list[str]]:
    """The least BIC among the sets not on a bound, and a note when a better one was refused.

    Neighbouring taus share most of their data (four per octave, overlapping), so
    their misfits are not independent: chi-squared and the count of points are
    taken per octave, one independent point each. Counted per tau, the scatter of
    a short log's long taus buys a rate random walk or a GM that is not there.
    """
    independent = math.log2(tau[-1] / tau[0]) + 1.0
    shared = max(tau.size / independent, 1.0)

    def bic(c):
        return c.chi2 / shared + math.log(independent) * c.n_params

    valid = [c for c in candidates if not c.on_bound]
    best = min(valid, key=bic)
    notes = []
    better = [c for c in candidates if c.on_bound and bic(c) < bic(best)]
    if better:
        c = min(better, key=bic)
        notes.append(
            f"refused the better-scoring {'+'.join(c.terms)}: {c.on_bound}, "
            "so the curve there is not that term"
        )
    return best, notes


def fit_noise(curve: AllanCurve) -> NoiseFit:
    """The terms the curve shows, fitted (module docstring), with their fit quality.

    Raises
    ------
    ValueError
        When the curve has no slope -1/2 region (`calib.allan.deviation.white_region`).
    """
    region = white_region(curve)
    white0 = float(np.exp(np.mean(np.log(curve.adev[region] * np.sqrt(curve.tau_s[region])))))
    sl, quantised = fitted_range(curve, region, white0)
    if sl.stop - sl.start < 4:
        raise ValueError(
            "fewer than four taus are known to 25 % from the white region on: the log is too short to fit"
        )
    # Fitted to the longest tau: the untrusted taus still carry evidence (a rise that
    # goes on), at the weight of their wide intervals; held to the trusted ones.
    fit = slice(sl.start, curve.tau_s.size)
    tau, adev = curve.tau_s[fit], curve.adev[fit]
    scale = np.hypot(0.5 * np.log(curve.ci_high[fit] / curve.ci_low[fit]), MODEL_FLOOR)
    # Q where the curve shows it, and then only if it earns its parameter (BIC).
    extra_sets: list[dict[str, tuple[float, ...]]] = [{}]
    if quantised:
        extra_sets.append({"Q": (float(adev[0] * tau[0] / math.sqrt(3.0)),)})
    candidates = [c for extras in extra_sets for c in _fit_sets(tau, adev, scale, white0, extras)]
    best, notes = _select(candidates, tau)
    k = _bump(tau, adev, np.sqrt(model_avar(tau, best.terms)))
    if k is not None:  # a periodic disturbance: the sinusoid joins every set
        excess = math.sqrt(max(adev[k] ** 2 - float(model_avar(tau[k], best.terms)), 0.0))
        sine = (excess / SINUSOID_PEAK_ADEV_RATIO, SINUSOID_PEAK_X / (math.pi * tau[k]))
        for extras in extra_sets:
            candidates += _fit_sets(tau, adev, scale, white0, {**extras, "SIN": sine})
        best, notes = _select(candidates, tau)
    terms = _prune(best.terms, tau, adev)
    held_tau, held_adev = curve.tau_s[sl], curve.adev[sl]
    ratio = np.sqrt(model_avar(held_tau, terms)) / held_adev
    return _noise_fit(curve, region, terms, (float(held_tau[0]), float(held_tau[-1])), ratio, notes)


def _prune(terms: dict[str, tuple[float, ...]], tau, adev) -> dict[str, tuple[float, ...]]:
    """The terms without those under 1 % of the measured variance at every fitted tau.

    Such a term is the optimiser parking an amplitude at nothing, not a term the
    curve shows: it would be reported as a value the data cannot tell from 0.
    """
    return {
        name: p
        for name, p in terms.items()
        if name == "N" or np.any(TERMS[name][1](tau, *p) >= PRUNE_SHARE * adev**2)
    }


def _fit_sets(tau, adev, scale, white, extras) -> list[_Candidate]:
    """Every slow set with the given extra terms (Q, sinusoid), nested sets first."""
    fitted: list[_Candidate] = []
    for names in SLOW_SETS:
        full = names[:1] + tuple(extras) + names[1:]
        fitted.append(_fit_set(tau, adev, scale, _starts(full, tau, adev, white, extras, fitted)))
    return fitted


def _noise_fit(curve, region, terms, fit_tau, ratio, notes) -> NoiseFit:
    """The NoiseFit of the chosen terms, the two GMs ordered by correlation time."""
    gms = sorted((terms[g] for g in ("GM", "GM2") if g in terms), key=lambda p: p[1])
    gms += [(0.0, 0.0)] * (2 - len(gms))
    floor = int(np.argmin(curve.adev))
    return NoiseFit(
        white=terms["N"][0],
        white_tau_s=(float(curve.tau_s[region[0]]), float(curve.tau_s[region[-1]])),
        quantisation=terms.get("Q", (0.0,))[0],
        bias_instability=float(curve.adev[floor] / FLICKER_FLOOR_RATIO),
        floor_tau_s=float(curve.tau_s[floor]),
        gm_sigma=gms[0][0],
        gm_correlation_s=gms[0][1],
        gm2_sigma=gms[1][0],
        gm2_correlation_s=gms[1][1],
        rate_random_walk=terms.get("K", (0.0,))[0],
        sinusoid=terms.get("SIN", (0.0, 0.0))[0],
        sinusoid_hz=terms.get("SIN", (0.0, 0.0))[1],
        fit_tau_s=fit_tau,
        fit_ratio=(float(ratio.min()), float(ratio.max())),
        notes=tuple(notes),
    )
