"""Which noise terms an Allan deviation shows, their values and the fit's quality, on series of known noise.

Each series is simulated with a fixed seed. The tolerances follow from the Allan
deviation's 68 % intervals where each term is seen (stated at each test): a term
read where the deviation is known to 1 % is held to a few %, one read from the
longest taus (intervals of 15-25 %) to tens of %.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from calib.allan.deviation import (
    SINUSOID_PEAK_ADEV_RATIO,
    SINUSOID_PEAK_X,
    allan_deviation,
    avar_gauss_markov,
    avar_rate_random_walk,
    avar_sinusoid,
    avar_white,
)
from calib.allan.noise_terms import TRUSTED_CI, fit_noise
from calib.allan.plot import plot_allan
from calib.allan.profile_gm import not_modelled, profile_gm
from calib.noise.gauss_markov import gauss_markov


def series(n, dt, seed, white=0.0, gm=(0.0, 1.0), rrw=0.0, q=0.0, sine=(0.0, 1.0)) -> np.ndarray:
    """A rate (SI) of white noise, a first-order GM, a rate random walk, quantisation and a sinusoid."""
    rng = np.random.default_rng(seed)
    rate = white / math.sqrt(dt) * rng.standard_normal(n)
    if gm[0] > 0:
        rate += gauss_markov(n, np.full(n, dt), gm[0], gm[1], rng)[:, 0]
    if rrw > 0:
        rate += np.cumsum(rrw * math.sqrt(dt) * rng.standard_normal(n))
    if sine[0] > 0:
        rate += sine[0] * np.sin(2.0 * math.pi * sine[1] * dt * np.arange(n) + 0.3)
    if q > 0:
        # A dithered quantiser: an angle error uniform over one step (q sqrt(12)) and
        # independent from sample to sample, the white angle noise of IEEE Std 952's
        # 3 Q^2 / tau^2.
        error = (rng.uniform(size=n + 1) - 0.5) * q * math.sqrt(12.0)
        rate += np.diff(error) / dt
    return rate


def test_sinusoid_peak_is_where_the_constants_say():
    best = minimize_scalar(lambda x: -(math.sin(x) ** 2) / x, bounds=(0.5, 2.0), method="bounded")
    assert best.x == pytest.approx(SINUSOID_PEAK_X, abs=1e-4)
    assert -best.fun == pytest.approx(SINUSOID_PEAK_ADEV_RATIO, abs=1e-4)
    # and the formula is the deviation of a sampled sine (no noise: to the sampling's 1 %)
    dt, f0, amp = 0.01, 0.5, 2.0
    rate = series(200_000, dt, 0, sine=(amp, f0))
    taus = np.array([0.2, 0.5, 0.74, 1.5, 2.5, 3.3])
    curve = allan_deviation(rate, dt, taus)
    np.testing.assert_allclose(curve.adev, np.sqrt(avar_sinusoid(curve.tau_s, amp, f0)), rtol=0.01, atol=1e-3)


def test_white_gm_and_rate_random_walk_are_recovered():
    # 4e5 samples at 10 Hz (11 h): N is read where the intervals are under 0.5 % (2 %
    # is generous); the GM (peak 3.1e-3 at 57 s, twice the white noise there) where
    # they are 3-8 %, and sigma and T_c trade against each other and against N and K
    # (25 %, 30 %); K from the last octaves, intervals of 15-25 % (40 %).
    white, sigma, tc, k = 0.01, 0.005, 30.0, 1e-4
    curve = allan_deviation(series(400_000, 0.1, 1, white=white, gm=(sigma, tc), rrw=k), 0.1)
    fit = fit_noise(curve)
    assert set(fit.terms()) == {"N", "GM", "K"}, fit
    assert fit.white == pytest.approx(white, rel=0.02)
    assert fit.gm_sigma == pytest.approx(sigma, rel=0.25)
    assert fit.gm_correlation_s == pytest.approx(tc, rel=0.30)
    assert fit.rate_random_walk == pytest.approx(k, rel=0.40)
    # The model follows the truth within the intervals (two of them, and the 3 %
    # model floor), at every fitted tau.
    tau = curve.tau_s[(curve.tau_s >= fit.fit_tau_s[0]) & (curve.tau_s <= fit.fit_tau_s[1])]
    truth = np.sqrt(
        avar_white(tau, white) + avar_gauss_markov(tau, sigma, tc) + avar_rate_random_walk(tau, k)
    )
    half = (curve.ci_high / curve.adev - 1.0)[np.isin(curve.tau_s, tau)]
    assert np.all(np.abs(fit.model_adev(tau) / truth - 1.0) <= 2.0 * half + 0.03)
    # The fit quality is reported over a range that is stated and trusted.
    lo, hi = fit.fit_ratio
    assert 0.8 < lo <= 1.0 <= hi < 1.25
    assert fit.fit_tau_s[0] == pytest.approx(0.1) and fit.fit_tau_s[1] > 1000.0
    last = int(np.flatnonzero(curve.tau_s == fit.fit_tau_s[1])[0])
    assert curve.ci_high[last] / curve.adev[last] - 1.0 <= TRUSTED_CI
    assert fit.notes == ()


def test_quantisation_is_recovered_where_it_is():
    # Q dominates below 0.27 s, where the intervals are 0.1-0.3 %: 3 %.
    q, white = 3e-3, 0.01
    fit = fit_noise(allan_deviation(series(500_000, 0.01, 2, white=white, q=q), 0.01))
    assert fit.quantisation == pytest.approx(q, rel=0.03)
    assert fit.white == pytest.approx(white, rel=0.03)
    assert fit.fit_tau_s[0] == pytest.approx(0.01)  # its slope -1 taus are fitted


@pytest.mark.parametrize(
    "kind, noise",
    [
        ("white and a GM", dict(white=0.01, gm=(0.005, 30.0))),
        # a 20 Hz disturbance: the shortest taus sit above the white line, flat, as on
        # the ADIS16405's z gyro, whose 80 urad quantisation was spurious
        ("a disturbance near the Nyquist frequency", dict(white=0.01, sine=(0.05, 20.0))),
    ],
)
def test_no_quantisation_is_invented(kind, noise):
    fit = fit_noise(allan_deviation(series(300_000, 0.01, 3, **noise), 0.01))
    assert fit.quantisation == 0.0, kind
    assert "Q" not in fit.terms()


def test_a_gm_on_its_bound_is_refused_and_the_fit_says_it_misses():
    # A GM of T_c = 0.3 s: shorter than the 1 s bound, so the better-scoring fit puts
    # its T_c on that bound. It is refused (no GM written) with a note, and the fit
    # quality shows what the remaining terms miss.
    fit = fit_noise(allan_deviation(series(300_000, 0.01, 4, white=0.01, gm=(0.03, 0.3)), 0.01))
    assert any("bound (1 s)" in note for note in fit.notes), fit.notes
    assert fit.gm_correlation_s == 0.0 or fit.gm_correlation_s > 1.05
    lo, hi = fit.fit_ratio
    assert lo < 0.75 or hi > 1.25


def test_the_profile_gm_follows_the_worst_axis():
    # Three axes of one noise; the profile's GM, by minimax over 10 s on, comes back
    # within the GM test's tolerances and follows the worst axis within 15 %.
    curves = tuple(
        allan_deviation(series(300_000, 0.1, s, white=0.01, gm=(0.005, 30.0)), 0.1) for s in (5, 6, 7)
    )
    fits = tuple(fit_noise(c) for c in curves)
    prof = profile_gm(curves, fits)
    assert prof.note == ""
    assert prof.white == max(f.white for f in fits)
    assert prof.sigma == pytest.approx(0.005, rel=0.25)
    assert prof.correlation_s == pytest.approx(30.0, rel=0.4)
    assert prof.tau_s[0] >= 10.0
    assert 0.85 < prof.ratio[0] <= 1.0 <= prof.ratio[1] < 1.15
    assert not_modelled(fits) == []


def test_the_profile_refuses_a_gm_on_its_bound_and_names_what_it_cannot_carry():
    # White noise and a rate random walk: the one GM that follows the rise is a GM of
    # unbounded correlation time (a GM with tau << T_c is a rate random walk); it goes
    # to the profiles' 1e6 s bound and is refused, and the RRW is named as not modelled.
    curves = tuple(allan_deviation(series(300_000, 0.1, s, white=0.01, rrw=2e-4), 0.1) for s in (8, 9, 10))
    fits = tuple(fit_noise(c) for c in curves)
    assert all(f.rate_random_walk > 0 for f in fits)
    prof = profile_gm(curves, fits)
    assert prof.sigma == 0.0 and prof.correlation_s == 0.0
    assert "bound" in prof.note, prof.note
    assert not_modelled(fits) == ["rate random walk on x, y, z"]


def test_the_png_shows_each_fit_and_the_profile(tmp_path):
    curves = (allan_deviation(series(100_000, 0.1, 11, white=0.01, gm=(0.005, 30.0)), 0.1),) * 3
    fits = (fit_noise(curves[0]),) * 3
    prof = profile_gm(curves, fits)
    fit = SimpleNamespace(
        name="synthetic",
        gyro_curves=curves,
        gyro=fits,
        gyro_profile=prof,
        accel_curves=curves,
        accel=fits,
        accel_profile=prof,
    )
    path = tmp_path / "allan.png"
    plot_allan(fit, path)
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    assert (width, height) == (1320, 605)
