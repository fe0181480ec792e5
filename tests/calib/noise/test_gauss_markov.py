"""Gauss-Markov bias instability: the sampled process, the profile keys, the exact whitening.

The whitening is checked against first principles built here, not with the
module's own code: interval models from ``expm`` and Gauss-Legendre
quadrature of the 12-state body-frame model (the module uses Van Loan in the
navigation frame and a rotation), the dense covariance of all observations,
and a Monte Carlo of the exact discrete-time error model.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from conftest import rodrigues
from scipy.linalg import block_diag, expm

from calib.errors import CalibError
from calib.model.params import MICRO_G
from calib.nav.jacobian import state_matrix
from calib.nav.site import Site
from calib.noise.gauss_markov import gauss_markov
from calib.noise.profiles import NoiseProfile, builtin_profiles, load_profile
from calib.noise.whitening import noise_model, whiten

LAT = math.radians(40.0)
G = 9.80
A6 = state_matrix(Site(LAT, G))


# ---------------------------------------------------------------------------
# The sampled process


def _reference_gm(n, dt, sigma, tau, rng):
    """The recursion of the docstring, one sample at a time (same draws, same order)."""
    w = rng.standard_normal((n, 3))
    b = np.empty((n, 3))
    b[0] = sigma * w[0]
    for k in range(1, n):
        a = math.exp(-dt[k] / tau)
        b[k] = a * b[k - 1] + sigma * math.sqrt(1.0 - a * a) * w[k]
    return b


@pytest.mark.parametrize("uniform", [True, False])
@pytest.mark.parametrize("tau", [0.02, 1.0, 1e4])
def test_gm_matches_the_recursion(uniform, tau):
    # Both vectorised paths (lfilter; blocks of the closed form, several blocks at
    # tau = 0.02 s) against the plain loop. Rounding grows like n * eps of the values.
    n = 5000
    dt = np.full(n, 0.01) if uniform else 0.01 * (1.0 + 0.3 * np.random.default_rng(1).random(n))
    got = gauss_markov(n, dt, 2.0, tau, np.random.default_rng(7))
    want = _reference_gm(n, dt, 2.0, tau, np.random.default_rng(7))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-10)


def test_gm_statistics_variance_and_autocorrelation():
    # 340000 samples, dt/tau = 0.1: AR(1) with rho = exp(-0.1). Known zero mean, so no
    # mean is removed. Large-sample standard errors of a Gaussian AR(1) (Bartlett):
    #   sample variance / sigma^2:  sqrt(2 (1 + rho^2) / (1 - rho^2) / n)      (~0.0077)
    #   lag-l autocorrelation:      sqrt(((1 + rho^2)(1 - rho^2l) / (1 - rho^2) - 2 l rho^2l) / n)
    # per axis; the three axes are independent, so the pooled error is / sqrt(3).
    # Tolerance: 5 standard errors (a false alarm ~ 1e-6 per check).
    n, dt, tau, sigma = 340_000, 0.01, 0.1, 3e-7
    b = gauss_markov(n, np.full(n, dt), sigma, tau, np.random.default_rng(11))
    rho = math.exp(-dt / tau)
    se_var = math.sqrt(2 * (1 + rho**2) / (1 - rho**2) / n) / math.sqrt(3)
    assert abs(np.mean(b**2) / sigma**2 - 1.0) < 5 * se_var
    power = np.sum(b**2, axis=0)
    for lag in (1, 5, 10, 30):
        r = np.mean(np.sum(b[lag:] * b[:-lag], axis=0) / power)
        r2l = rho ** (2 * lag)
        se = math.sqrt(((1 + rho**2) * (1 - r2l) / (1 - rho**2) - 2 * lag * r2l) / n) / math.sqrt(3)
        assert abs(r - math.exp(-lag * dt / tau)) < 5 * se, lag


def test_gm_starts_stationary():
    # The first samples already have variance sigma^2 and covariance sigma^2 a (a process
    # started at zero would show a variance of 0, then 1 - a^2). 3 x 4000 values per
    # moment: standard error sqrt(2 / 12000) = 0.013 for the variance, ~0.009 for the
    # covariance; 5 standard errors.
    rng = np.random.default_rng(3)
    dt, tau = 0.5, 1.0
    b = np.array([gauss_markov(2, np.full(2, dt), 1.0, tau, rng) for _ in range(4000)])
    assert abs(np.mean(b[:, 0] ** 2) - 1.0) < 0.065
    assert abs(np.mean(b[:, 1] ** 2) - 1.0) < 0.065
    assert abs(np.mean(b[:, 0] * b[:, 1]) - math.exp(-dt / tau)) < 0.05


def test_gm_zero_sigma_and_speed():
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    assert not np.any(gauss_markov(10, np.full(10, 0.01), 0.0, 0.0, rng))
    assert rng.bit_generator.state == state  # GM off draws nothing: the caller's stream is intact
    n = 340_000  # a paper run at 200 Hz; the requirement is well under 0.5 s (measured ~30 ms)
    for dt in (np.full(n, 0.005), 0.005 * (1 + 1e-3 * rng.random(n))):
        t0 = time.perf_counter()
        b = gauss_markov(n, dt, 1e-8, 600.0, rng)
        assert time.perf_counter() - t0 < 0.5
        assert b.shape == (n, 3) and np.all(np.isfinite(b))


def test_gm_refuses_bad_arguments():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError):
        gauss_markov(5, np.full(4, 0.01), 1.0, 1.0, rng)
    with pytest.raises(ValueError):
        gauss_markov(5, np.full(5, 0.01), 1.0, 0.0, rng)
    with pytest.raises(ValueError):
        gauss_markov(5, np.full(5, 0.01), -1.0, 1.0, rng)


# ---------------------------------------------------------------------------
# Profiles


def _write(tmp_path, body: str):
    path = tmp_path / "p.toml"
    path.write_text("gyro_arw_dph = 0.001\naccel_vrw_ug = 10.0\n" + body)
    return path


def test_profile_gm_keys():
    assert "navigation-gm" in builtin_profiles()
    p = load_profile("navigation-gm")
    assert (p.gyro_arw_dph, p.accel_vrw_ug) == (0.001, 10.0)
    assert p.has_gauss_markov
    assert p.gyro_gm_sigma == pytest.approx(0.003 * math.pi / 180 / 3600, rel=1e-12)
    assert p.accel_gm_sigma == pytest.approx(5.0 * 9.80665e-6, rel=1e-12)
    assert (p.gyro_bias_correlation_s, p.accel_bias_correlation_s) == (600.0, 600.0)
    plain = load_profile("navigation")
    assert not plain.has_gauss_markov and plain.gyro_gm_sigma == 0.0 == plain.accel_gm_sigma
    assert len({p, plain, load_profile("navigation-gm")}) == 2  # hashable: an lru_cache key


def test_profile_gm_one_sensor_and_explicit_zero(tmp_path):
    p = load_profile(_write(tmp_path, "accel_bias_instability_ug = 3\naccel_bias_correlation_s = 100\n"))
    assert p.has_gauss_markov and p.gyro_gm_sigma == 0.0 and p.accel_gm_sigma == 3 * MICRO_G
    p = load_profile(_write(tmp_path, "gyro_bias_instability_dph = 0\n"))  # 0 = off, no tau needed
    assert not p.has_gauss_markov


@pytest.mark.parametrize(
    "body, key",
    [
        ("gyro_bias_instability_dph = 0.01\n", "gyro_bias_correlation_s"),  # tau missing
        ("gyro_bias_instability_dph = 0.01\ngyro_bias_correlation_s = 0\n", "gyro_bias_correlation_s"),
        ("accel_bias_instability_ug = 5\n", "accel_bias_correlation_s"),
        ("gyro_bias_instability_dph = -0.01\ngyro_bias_correlation_s = 60\n", "gyro_bias_instability_dph"),
        ("accel_bias_instability_ug = 'five'\naccel_bias_correlation_s = 60\n", "accel_bias_instability_ug"),
        ("accel_bias_instability_ug = true\naccel_bias_correlation_s = 60\n", "accel_bias_instability_ug"),
        ("accel_bias_instability_ug = nan\naccel_bias_correlation_s = 60\n", "accel_bias_instability_ug"),
        ("gyro_bias_instability_dph = inf\ngyro_bias_correlation_s = 60\n", "gyro_bias_instability_dph"),
        ("gyro_bias_instability_dph = 101\ngyro_bias_correlation_s = 60\n", "gyro_bias_instability_dph"),
        ("accel_bias_instability_ug = 2e5\naccel_bias_correlation_s = 60\n", "accel_bias_instability_ug"),
        ("gyro_bias_instability_dph = 0.01\ngyro_bias_correlation_s = 0.5\n", "gyro_bias_correlation_s"),
        ("gyro_bias_instability_dph = 0.01\ngyro_bias_correlation_s = 2e6\n", "gyro_bias_correlation_s"),
        ("accel_bias_correlation_s = -3\n", "accel_bias_correlation_s"),
    ],
)
def test_profile_gm_bad_values(tmp_path, body, key):
    path = _write(tmp_path, body)
    with pytest.raises(CalibError) as err:
        load_profile(path)
    # where names the file (and, through the shared validator, the key)
    assert key in err.value.what and err.value.where.startswith(str(path))


# ---------------------------------------------------------------------------
# The whitening filter against first principles


def _profile(gyro_dph=0.0, accel_ug=0.0, tau=60.0, arw=0.001, vrw=10.0):
    return NoiseProfile("t", arw, vrw, gyro_dph, tau if gyro_dph else 0.0, accel_ug, tau if accel_ug else 0.0)


def _exact_model(T, C, prof):
    """Discrete ``[phi, dv(, b_g, b_a)]`` model of one interval at attitude ``C``, body-frame
    biases: ``expm`` and 24-point Gauss-Legendre quadrature of ``int e^As Qc e^A's ds`` (the
    integrand is a low-degree polynomial times slow exponentials: the rule is exact to rounding)."""
    gm = prof.has_gauss_markov
    n = 12 if gm else 6
    A = np.zeros((n, n))
    A[:6, :6] = A6
    qc = [prof.arw**2] * 3 + [prof.vrw**2] * 3
    if gm:
        A[:3, 6:9], A[3:6, 9:] = -C, C
        for i, (s, tau) in enumerate(
            [
                (prof.gyro_gm_sigma, prof.gyro_bias_correlation_s),
                (prof.accel_gm_sigma, prof.accel_bias_correlation_s),
            ]
        ):
            A[6 + 3 * i : 9 + 3 * i, 6 + 3 * i : 9 + 3 * i] = -np.eye(3) / tau if s else 0.0
            qc += [2 * s**2 / tau if s else 0.0] * 3
    x, wts = np.polynomial.legendre.leggauss(24)
    Q = sum(
        0.5 * T * wi * (E := expm(A * 0.5 * T * (xi + 1))) @ np.diag(qc) @ E.T
        for xi, wi in zip(x, wts, strict=True)
    )
    return expm(A * T), 0.5 * (Q + Q.T)


def _P0(prof):
    if not prof.has_gauss_markov:
        return np.zeros((6, 6))
    return block_diag(np.zeros((6, 6)), prof.gyro_gm_sigma**2 * np.eye(3), prof.accel_gm_sigma**2 * np.eye(3))


def _random_rotations(rng, K):
    return np.array([rodrigues(rng.normal(size=3) * 2.0) for _ in range(K)])


@pytest.mark.parametrize(
    "prof",
    [_profile(), _profile(0.05, 50.0), _profile(0.0, 30.0, tau=5.0)],
    ids=["white", "gm", "accel-gm-only"],
)
def test_whitener_is_the_exact_gls_weight(prof):
    # Dense covariance of all observations z_1..z_K from the exact discrete model, with a
    # different attitude in every interval and mixed lengths. The module's whitening W
    # (applied to the identity columns) must satisfy W Cov(z) W' = I and be causal
    # (lower triangular): then it is the inverse Cholesky factor, the exact GLS weight.
    # Cov(z) ~ 1e-10 with condition ~1e6: rounding leaves ~1e-9 in W Cov W'.
    rng = np.random.default_rng(5)
    K = 40
    T = rng.choice([1.0, 0.1, 0.37], size=K)
    C = _random_rotations(rng, K)
    models = [_exact_model(t, c, prof) for t, c in zip(T, C, strict=True)]
    n = models[0][0].shape[0]
    P0 = _P0(prof)
    P0[:3, :3] = (2e-7) ** 2 * np.eye(3)  # and a non-zero start for phi, given to the module
    # x_k = Phi_k x_{k-1} + w_k, stacked: x = L w with Cov(w) = diag(P0, Q_1, ..., Q_K).
    L = np.zeros((K + 1, n, K + 1, n))
    for k in range(K + 1):
        L[k, :, k] = np.eye(n)
        for j in range(k):
            L[k, :, j] = models[k - 1][0] @ L[k - 1, :, j]
    L = L.reshape((K + 1) * n, (K + 1) * n)
    Cx = L @ block_diag(P0, *[q for _, q in models]) @ L.T
    D = np.zeros((K, 3, K + 1, n))  # z_k = dv_k - Phi_vv dv_{k-1}
    for k in range(1, K + 1):
        D[k - 1, :, k, 3:6] = np.eye(3)
        D[k - 1, :, k - 1, 3:6] = -models[k - 1][0][3:6, 3:6]
    D = D.reshape(3 * K, -1)
    Cz = D @ Cx @ D.T

    P0_filter = P0[np.r_[0:3, 6:n]][:, np.r_[0:3, 6:n]]
    noise = noise_model(A6, T, prof, P0_filter, C_b_n=C if prof.has_gauss_markov else None)
    assert noise.whitener.state_size == n - 3
    W = whiten(noise.whitener, np.eye(3 * K).reshape(K, 3, 3 * K)).reshape(3 * K, 3 * K)
    assert np.max(np.abs(W @ Cz @ W.T - np.eye(3 * K))) < 1e-7
    assert np.max(np.abs(np.triu(W, 1))) < 1e-10 * np.max(np.abs(W))
    # log det of the innovation covariances = log det Cov(z).
    assert noise.whitener.logdet_S == pytest.approx(np.linalg.slogdet(Cz)[1], abs=1e-6)
    np.testing.assert_allclose(noise.Phi_vv, [m[0][3:6, 3:6] for m in models], rtol=0, atol=1e-12)


def test_whitener_without_gm_is_unchanged():
    # A profile whose GM sigmas are 0 is the white-noise profile: same 3-state filter,
    # bit for bit, and the attitudes are not needed (ignored if given).
    rng = np.random.default_rng(2)
    T = rng.choice([1.0, 0.1], size=300)
    X = rng.normal(size=(300, 3, 4)) * 1e-5
    plain = noise_model(A6, T, _profile())
    zero_gm = noise_model(
        A6, T, NoiseProfile("z", 0.001, 10.0, 0.0, 600.0, 0.0, 600.0), C_b_n=_random_rotations(rng, 300)
    )
    assert plain.whitener.state_size == zero_gm.whitener.state_size == 3
    assert np.array_equal(whiten(plain.whitener, X), whiten(zero_gm.whitener, X))
    assert np.array_equal(plain.Phi_vv, zero_gm.Phi_vv)
    # A vanishing GM bias runs the 9-state filter, which must reduce to the 3-state one.
    tiny = noise_model(A6, T, _profile(1e-9, 1e-6), C_b_n=_random_rotations(rng, 300))
    assert tiny.whitener.state_size == 9
    np.testing.assert_allclose(whiten(tiny.whitener, X), whiten(plain.whitener, X), rtol=0, atol=1e-8)
    assert np.array_equal(tiny.Phi_vv, plain.Phi_vv)  # z does not depend on the profile


def test_noise_model_needs_attitudes_with_gm():
    T = np.ones(5)
    with pytest.raises(ValueError, match="C_b_n"):
        noise_model(A6, T, load_profile("navigation-gm"))
    with pytest.raises(ValueError, match="C_b_n"):
        noise_model(A6, T, load_profile("navigation-gm"), C_b_n=np.tile(np.eye(3), (4, 1, 1)))
    with pytest.raises(ValueError, match="P0"):
        noise_model(
            A6, T, load_profile("navigation-gm"), P0=np.zeros((3, 3)), C_b_n=np.tile(np.eye(3), (5, 1, 1))
        )


def _monte_carlo(prof, n_trials, seed):
    """Noise-only velocity errors of 200 rest intervals of 1 s, the attitude switching between
    two rests every 10 intervals, simulated exactly in discrete time (12-state model);
    returns ``z`` (K, 3, n_trials) and the attitudes."""
    rng = np.random.default_rng(seed)
    K = 200
    C1, C2 = rodrigues([0.3, 0.5, 0.8]), rodrigues([-2.0, 1.0, 0.5])
    C = np.array([C1 if (k // 10) % 2 == 0 else C2 for k in range(K)])
    models = {id_: _exact_model(1.0, c, prof) for id_, c in ((0, C1), (1, C2))}
    chol = {}
    for id_, (_, Q) in models.items():
        d = np.sqrt(np.diag(Q))  # scaled Cholesky: the diagonal spans ~1e-20 to 1e-9
        chol[id_] = d[:, None] * np.linalg.cholesky(Q / np.outer(d, d))
    x = np.zeros((12, n_trials))
    x[6:9] = prof.gyro_gm_sigma * rng.standard_normal((3, n_trials))  # stationary biases
    x[9:] = prof.accel_gm_sigma * rng.standard_normal((3, n_trials))
    z = np.empty((K, 3, n_trials))
    for k in range(K):
        Phi, _ = models[(k // 10) % 2]
        v_prev = x[3:6]
        x = Phi @ x + chol[(k // 10) % 2] @ rng.standard_normal((12, n_trials))
        z[k] = x[3:6] - Phi[3:6, 3:6] @ v_prev
    return z, C


def test_whitened_innovations_are_white_monte_carlo():
    # A strong GM (50 ug, 0.05 deg/h, tau 60 s) against 10 ug/sqrt(Hz), 0.001 deg/sqrt(h):
    # ignoring it would be obvious. 2000 trials x 200 intervals x 3 axes.
    # If the whitened e are iid N(0, 1):
    #   mean of e^2 over all 1.2e6 values: standard error sqrt(2 / 1.2e6) = 0.0013 -> tol 0.0065
    #   per interval (6000 values): s.e. sqrt(2 / 6000) = 0.018; over 200 intervals a 4.5 s.e.
    #     bound (0.082) is exceeded by chance with probability ~1e-3. This catches a wrong P0
    #     (first interval) or a wrong frame change of the biases (every 10th interval).
    #   lag-l cross products, mean over trials and intervals: s.e. 1/sqrt(2000 (200 - l))
    #     <= 0.0016; 5 s.e. = 0.008 over 51 statistics.
    prof = _profile(0.05, 50.0)
    z, C = _monte_carlo(prof, 2000, seed=8)
    T = np.ones(len(z))
    e = whiten(noise_model(A6, T, prof, C_b_n=C).whitener, z)
    assert abs(np.mean(e**2) - 1.0) < 0.0065
    assert np.max(np.abs(np.mean(e**2, axis=(1, 2)) - 1.0)) < 0.082
    for lag in range(0, 6):
        r = np.einsum("kin,kjn->ij", e[lag:], e[: len(e) - lag]) / (e.shape[2] * (len(e) - lag))
        if lag == 0:
            r -= np.diag(np.diag(r))  # the variances are checked above
        assert np.max(np.abs(r)) < 0.008, lag

    # The white-noise-only filter on the same data: the GM bias is left in the innovations.
    # (Measured ~15x the unit variance; 2 is far above any sampling error.)
    e_white = whiten(noise_model(A6, T, _profile()).whitener, z)
    assert np.mean(e_white**2) > 2.0
    r1 = np.einsum("kin,kin->", e_white[1:], e_white[:-1]) / e_white[1:].size
    assert r1 > 0.1
