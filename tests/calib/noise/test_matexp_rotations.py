"""The numpy rotations of calib.nav.transform and the matrix exponential of calib.noise.matexp.

Both replace scipy functions on the calibrate path (whose imports cost every
command 0.25 s); scipy is the independent reference here.
"""

import numpy as np
import pytest
from scipy.linalg import expm as scipy_expm
from scipy.spatial.transform import Rotation

from calib.nav.transform import dcm_to_rotvec, rotvec_to_dcm, skew
from calib.noise.matexp import expm

# Rounding of a handful of products of unit-size numbers: a few ulp of 1.
ULP_TOL = 1e-14


def _rotvecs(rng, n, angle):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1)[:, None] * angle


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-3, 0.5, 3.0, np.pi - 1e-6])
def test_rotvec_round_trip_and_scipy(angle):
    rng = np.random.default_rng(3)
    v = _rotvecs(rng, 200, angle)
    C = rotvec_to_dcm(v)
    assert np.abs(C - Rotation.from_rotvec(v).as_matrix()).max() < ULP_TOL
    # A rotation: orthonormal with determinant +1.
    assert np.abs(C @ C.transpose(0, 2, 1) - np.eye(3)).max() < ULP_TOL
    assert np.allclose(np.linalg.det(C), 1.0, atol=ULP_TOL)
    # Inverse within (0, pi): the angle near pi is ill-conditioned in its axis, 1e-6 away it is not.
    assert np.abs(dcm_to_rotvec(C) - v).max() < 1e-9
    assert np.abs(dcm_to_rotvec(C) - Rotation.from_matrix(C).as_rotvec()).max() < 1e-9


def test_rotvec_is_the_exponential_of_its_skew_matrix():
    v = np.array([0.3, -1.1, 0.7])
    assert np.abs(rotvec_to_dcm(v) - expm(skew(v))).max() < ULP_TOL
    assert rotvec_to_dcm(v).shape == (3, 3) and dcm_to_rotvec(rotvec_to_dcm(v)).shape == (3,)


def test_dcm_to_rotvec_projects_and_refuses_reflections():
    C = rotvec_to_dcm(np.array([0.1, 0.2, 0.3]))
    bent = C + 1e-7 * np.random.default_rng(1).normal(size=(3, 3))
    # Not orthonormal: the nearest rotation's vector, as scipy's from_matrix.
    assert np.abs(dcm_to_rotvec(bent) - Rotation.from_matrix(bent).as_rotvec()).max() < 1e-12
    with pytest.raises(ValueError):
        dcm_to_rotvec(np.diag([1.0, 1.0, -1.0]))


@pytest.mark.parametrize("scale", [0.0, 1e-6, 0.3, 3.0, 30.0])
def test_expm_against_scipy_and_identities(scale):
    rng = np.random.default_rng(7)
    M = rng.normal(size=(12, 12)) * scale / 4.0
    E = expm(M)
    # Squaring s times amplifies rounding by about the norm: relative to the result's size.
    assert np.abs(E - scipy_expm(M)).max() <= 1e-13 * max(1.0, np.abs(E).max())
    assert np.allclose(E @ expm(-M), np.eye(12), atol=1e-12 * max(1.0, np.abs(E).max()) ** 2)
    d = rng.normal(size=5) * scale
    # exp(x) has condition number |x|: its relative error is a few ulp times that.
    rel = np.diag(expm(np.diag(d))) / np.exp(d) - 1.0
    assert np.abs(rel).max() <= 1e-14 * (1.0 + np.abs(d).max())
