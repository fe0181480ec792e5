"""Gauss-Markov bias instability end to end: simulation, estimator weighting, analyser."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.analysis.worst_case import analyze_tolerance
from calib.fit.estimator import fit_run
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.nav.site import Site
from calib.noise.profiles import NoiseProfile, load_profile
from calib.sequence.definition import load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate

LAT = math.radians(40.0)
WHITE = load_profile("navigation")
GM = load_profile("navigation-gm")


def test_bias_instability_only_removes_information():
    # GM bias adds a positive semi-definite covariance to the observations, so no
    # parameter's predicted sigma may shrink; and it must cost something real.
    seq = load_sequence("paper-9pos")
    white = analyze_tolerance(seq, WHITE, Site.at(LAT), tolerance_deg=0.0).nominal.sigma
    gm = analyze_tolerance(seq, GM, Site.at(LAT), tolerance_deg=0.0).nominal.sigma
    assert np.all(gm >= white * (1 - 1e-9))
    assert np.max(gm / white) > 1.1


def test_simulated_bias_wanders_with_the_profiles_sigma():
    # Noise-free but for a strong, slow accelerometer GM bias: the 10 s means of dv/dt at the
    # first rest wander about the true specific force with the GM sigma (white noise tiny).
    prof = NoiseProfile(
        "gm-only",
        gyro_arw_dph=1e-6,
        accel_vrw_ug=1e-3,
        accel_bias_instability_ug=100.0,
        accel_bias_correlation_s=20.0,
    )
    seq = load_sequence("paper-9pos")
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=20.0)
    ref, _ = simulate(seq, cfg, ErrorModel.zero(), prof, options=SimOptions(noise=False))
    runs = [
        simulate(seq, cfg, ErrorModel.zero(), prof, options=SimOptions(noise=True, seed=s))[0]
        for s in range(20)
    ]
    n = int(170 * cfg.sample_rate_hz)
    d = np.stack([(r.dv_mps[:n] - ref.dv_mps[:n]) * cfg.sample_rate_hz for r in runs])
    # Sample means at t = 0 over 20 runs x 3 axes = 60 values of N(0, sigma^2):
    # their RMS is within 1 +- 4/sqrt(120) of sigma.
    rms = np.sqrt(np.mean(d[:, 0, :] ** 2)) / (100.0 * P.MICRO_G)
    assert 1 - 4 / math.sqrt(120) < rms < 1 + 4 / math.sqrt(120)
    # Correlated over tau: lag-20 s correlation exp(-1) = 0.37 (60 pairs x ~8 windows).
    lag = int(20 * cfg.sample_rate_hz)
    a, b = d[:, :-lag, :].ravel(), d[:, lag:, :].ravel()
    assert 0.2 < np.corrcoef(a, b)[0, 1] < 0.55


def test_noise_free_recovery_under_the_gm_weighting():
    # The weights change, not the fixed point: a noise-free run still comes back exactly.
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=50.0)
    truth = ErrorModel.from_table2()
    run, _ = simulate(load_sequence("paper-9pos"), cfg, truth, GM, options=SimOptions(noise=False))
    fit = fit_run(run, Site(LAT, cfg.gravity), GM)
    assert fit.converged
    assert np.all(np.abs(fit.values - truth.values) < P.REQUIREMENTS_SI / 20.0)


@pytest.mark.slow
def test_gm_weighting_gives_honest_sigmas_and_ignoring_it_does_not():
    # 12 runs with GM bias: weighted with the GM profile the mean NEES of the 21 is
    # 21 +- 4 sqrt(2 * 21 / 12) = [13.5, 28.5]; weighted as white noise the reported
    # sigmas are optimistic (one such run gave NEES 350) and chi2 does not show it.
    seq = load_sequence("paper-9pos")
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=50.0)
    truth = ErrorModel.from_table2()
    nees = {"gm": [], "white": []}
    for seed in range(12):
        run, _ = simulate(seq, cfg, truth, GM, options=SimOptions(noise=True, seed=100 + seed))
        for key, prof in (("gm", GM), ("white", WHITE)):
            fit = fit_run(run, Site(LAT, cfg.gravity), prof)
            e = fit.values - truth.values
            nees[key].append(e @ np.linalg.solve(fit.covariance[:21, :21], e))
    assert 13.5 < np.mean(nees["gm"]) < 28.5, np.mean(nees["gm"])
    assert np.mean(nees["white"]) > 3 * 28.5, np.mean(nees["white"])
