"""The closed-form 3 x 3 inverse Cholesky factor of the noise filter (calib.noise.whitening)."""

import numpy as np
import pytest
from scipy.linalg import solve_triangular

from calib.noise.whitening import _cholesky_inverse_3, cholesky_inverse_3

EPS = np.finfo(float).eps


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def _reference(S):
    # A triangular solve, not np.linalg.inv: a general (LU) inverse of a badly scaled
    # L leaves rounding noise above the diagonal and mixes the scales of its columns.
    L = np.linalg.cholesky(S)
    return np.array([solve_triangular(Lk, np.eye(3), lower=True) for Lk in L])


def _scaled_spd(rng, n):
    """Well-conditioned correlation matrices between scales 1e-6 .. 1e6 (``S = D C D``):
    the spread of units in an innovation covariance, condition numbers up to 1e24."""
    C = np.empty((n, 3, 3))
    d = 10.0 ** rng.uniform(-6, 6, size=(n, 3))
    for i in range(n):
        A = rng.normal(size=(3, 6))
        C[i] = A @ A.T
        C[i] /= np.sqrt(np.outer(np.diag(C[i]), np.diag(C[i])))
    return d[:, :, None] * C * d[:, None, :], C, d


def _near_singular(rng, n):
    """Random orientations of eigenvalues 1, 1e-3 .. 1e-10 (condition numbers to 1e10)."""
    S = np.empty((n, 3, 3))
    for i in range(n):
        R = _rotation(rng)
        S[i] = R @ np.diag([1.0, 10.0 ** rng.uniform(-3, 0), 10.0 ** rng.uniform(-10, -3)]) @ R.T
        S[i] = 0.5 * (S[i] + S[i].T)
    return S


def test_scalar_and_batched_forms_are_the_same_arithmetic():
    rng = np.random.default_rng(11)
    S = np.concatenate([_scaled_spd(rng, 200)[0], _near_singular(rng, 200)])
    Li = cholesky_inverse_3(S)
    one = np.array([_cholesky_inverse_3(s)[0] for s in S])
    # Same operations in the same order, each correctly rounded IEEE double (math.sqrt
    # and np.sqrt alike, no fused multiply-add across numpy calls): bit-identical.
    np.testing.assert_array_equal(Li, one)
    # log det L from the scalar form against an independent determinant.
    logdet = np.array([_cholesky_inverse_3(s)[1] for s in S])
    np.testing.assert_allclose(2.0 * logdet, np.linalg.slogdet(S)[1], rtol=0, atol=1e-6)


def test_matches_lapack_across_scales():
    rng = np.random.default_rng(12)
    S, C, d = _scaled_spd(rng, 500)
    # Cholesky is invariant to the diagonal scaling: L^-1 D = L_C^-1, and its error is
    # governed by cond(C), not cond(S). First order: ||dL|| / ||L|| <~ cond(C) eps and
    # inverting L multiplies that by cond(L) = cond(C)^0.5; times 10 for the constant.
    kappa = np.linalg.cond(C)
    got, ref = cholesky_inverse_3(S) * d[:, None, :], _reference(S) * d[:, None, :]
    err = np.linalg.norm(got - ref, axis=(1, 2)) / np.linalg.norm(ref, axis=(1, 2))
    assert np.all(err <= 10.0 * kappa**1.5 * EPS)
    assert kappa.max() > 10.0 and np.linalg.cond(S).max() > 1e12  # really spread


def test_matches_lapack_when_nearly_singular():
    rng = np.random.default_rng(13)
    S = _near_singular(rng, 500)
    kappa = np.linalg.cond(S)
    got, ref = cholesky_inverse_3(S), _reference(S)
    err = np.linalg.norm(got - ref, axis=(1, 2)) / np.linalg.norm(ref, axis=(1, 2))
    # Both algorithms are backward stable; their factors differ by <~ cond(S) eps
    # relative (the eps-sized backward errors seen through the conditioning).
    assert np.all(err <= 10.0 * kappa * EPS)
    assert kappa.max() > 1e9
    # And L^-1 whitens S: L^-1 S L^-T = I, to the same order.
    white = got @ S @ got.transpose(0, 2, 1)
    assert np.all(np.abs(white - np.eye(3)).max(axis=(1, 2)) <= 10.0 * kappa * EPS)


NOT_POSITIVE_DEFINITE = [
    np.zeros((3, 3)),
    np.diag([1.0, -1.0, 1.0]),
    np.diag([1.0, 1.0, -1e-3]),  # only the last pivot fails
    np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),  # indefinite
    np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),  # singular: pivot exactly 0
    np.array([[4.0, 2.0, 2.0], [2.0, 5.0, 3.0], [2.0, 3.0, 2.0]]),  # singular: last pivot 0
    np.diag([np.nan, 1.0, 1.0]),
]


@pytest.mark.parametrize("S", NOT_POSITIVE_DEFINITE)
def test_both_forms_refuse_a_matrix_that_is_not_positive_definite(S):
    with pytest.raises(np.linalg.LinAlgError):
        _cholesky_inverse_3(S)
    good = np.repeat(np.eye(3)[None], 4, axis=0)
    batch = np.concatenate([good, S[None], good])
    # (numpy warns about the square root of a negative pivot before the refusal)
    with np.errstate(invalid="ignore", divide="ignore"), pytest.raises(np.linalg.LinAlgError):
        cholesky_inverse_3(batch)
    if np.isfinite(S).all():  # (LAPACK does not check for NaN)
        with pytest.raises(np.linalg.LinAlgError):
            np.linalg.cholesky(S)  # the reference agrees that these are not SPD
