"""Allan deviation and the noise fit: formulas derived, then checked on simulated noise."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from calib.allan.deviation import GM_PEAK_ADEV_RATIO, GM_PEAK_TAU_RATIO, allan_deviation, avar_gauss_markov
from calib.allan.noise_terms import fit_noise
from calib.noise.gauss_markov import gauss_markov


def test_gm_peak_is_where_the_constants_say():
    # Maximise the closed form over x = tau / T_c: the constants must be its maximum.
    best = minimize_scalar(
        lambda x: -avar_gauss_markov(x, 1.0, 1.0),
        bounds=(0.5, 5.0),
        method="bounded",
        options={"xatol": 1e-9},
    )
    assert best.x == pytest.approx(GM_PEAK_TAU_RATIO, abs=1e-3)
    assert math.sqrt(-best.fun) == pytest.approx(GM_PEAK_ADEV_RATIO, abs=1e-4)


def test_gm_limits():
    # tau << T_c: a rate random walk of K^2 = 2 sigma^2 / T_c; tau >> T_c: white noise
    # of N^2 = 2 sigma^2 T_c (the integral of the autocorrelation). Series terms are
    # O(x) and O(1/x) relative, hence the tolerances.
    sigma, tc = 2.0, 50.0
    assert avar_gauss_markov(0.005, sigma, tc) == pytest.approx(2 * sigma**2 * 0.005 / (3 * tc), rel=1e-3)
    assert avar_gauss_markov(5e5, sigma, tc) == pytest.approx(2 * sigma**2 * tc / 5e5, rel=2e-4)
    # Continuous across the switch to the series at x = 1e-3.
    x = np.array([0.999e-3, 1.001e-3]) * tc
    a = avar_gauss_markov(x, sigma, tc) / x
    assert a[0] == pytest.approx(a[1], rel=1e-5)


def test_gm_formula_matches_a_simulated_gm_process():
    # 2000 s of a GM with T_c = 1 s at 100 Hz: near the peak each deviation averages
    # ~1000 independent tau-blocks, a ~3 % (1-sigma) scatter; 10 % is over 3 sigma.
    rng = np.random.default_rng(11)
    n, dt, sigma, tc = 200_000, 0.01, 1.0, 1.0
    b = gauss_markov(n, np.full(n, dt), sigma, tc, rng)[:, 0]
    taus = np.array([0.5, 1.0, 2.0, 4.0, 8.0])
    curve = allan_deviation(b, dt, taus)
    expected = np.sqrt(avar_gauss_markov(curve.tau_s, sigma, tc))
    np.testing.assert_allclose(curve.adev, expected, rtol=0.10)
    assert curve.adev.max() == pytest.approx(GM_PEAK_ADEV_RATIO * sigma, rel=0.10)


def test_white_noise_and_its_confidence_interval():
    # White rate noise of N = 0.01 /sqrt(s): adev = N / sqrt(tau). N is read off the
    # slope -1/2 region; 1e6 samples average it to ~1 %, so 5 % is generous. The 68 %
    # interval must cover the truth at about 68 % of the taus (>= 40 % of 30).
    rng = np.random.default_rng(5)
    n, dt, white = 1_000_000, 0.01, 0.01
    rate = white / math.sqrt(dt) * rng.standard_normal(n)
    curve = allan_deviation(rate, dt)
    truth = white / np.sqrt(curve.tau_s)
    covered = np.mean((curve.ci_low <= truth) & (truth <= curve.ci_high))
    assert covered >= 0.4
    fit = fit_noise(curve)
    assert fit.white == pytest.approx(white, rel=0.05)
    assert fit.quantisation == 0.0
