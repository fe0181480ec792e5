"""The rotation over a move placed by hand, from the gyro increments, and its sensitivity.

The integration rule: each sample is the gyro's **increment over its interval**
(what the run format stores; a logger's rate is its filter's mean over the
interval, turned into an increment by the rectangular rule), compensated by the
current gyro errors, then turned into a rotation vector with the two-sample
coning correction ``phi_k = dtheta_k + dtheta_{k-1} x dtheta_k / 12`` and
chained as quaternions. For a rate that changes linearly over two samples the
rule is exact to third order in the angle per sample; a hand turn at 1000 deg/s
and 100 Hz (0.17 rad per sample) leaves errors near 1e-5 rad per move,
checked against a truth integrated ten times finer (``tests/test_handfit.py``).

The sensitivity of a move's rotation to the gyro parameters is exact to first
order: a change ``d phi_i`` of sample ``i`` turns the move's end by
``R^T Q_i J_r(phi_i) d phi_i`` (``Q_i`` the rotation through sample ``i``,
``R`` the whole move's, ``J_r`` the right Jacobian of SO(3)).
"""

from __future__ import annotations

import math

import numpy as np

from calib.nav.strapdown import coning_rotvec
from calib.nav.transform import prefix_product, quat_to_dcm, rotvec_to_quat, skew


def right_jacobian(phi: np.ndarray) -> np.ndarray:
    """``J_r(phi)`` of SO(3) for ``(n, 3)`` rotation vectors: ``exp(phi + d) ~ exp(phi) exp(J_r d)``."""
    a = np.linalg.norm(phi, axis=1)
    a2 = a * a
    small = a < 1e-4
    safe = np.where(small, 1.0, a)
    # Taylor series near 0, where the quotients lose digits.
    c1 = np.where(small, 0.5 - a2 / 24.0, (1.0 - np.cos(safe)) / np.where(small, 1.0, a2))
    c2 = np.where(small, 1.0 / 6.0 - a2 / 120.0, (safe - np.sin(safe)) / (safe * safe * safe))
    K = skew(phi)
    return np.eye(3) - c1[:, None, None] * K + c2[:, None, None] * (K @ K)


def right_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """``J_r(phi)^-1`` of one rotation vector: ``Log(exp(phi) exp(d)) ~ phi + J_r^-1 d``."""
    a = float(np.linalg.norm(phi))
    K = skew(phi)
    # Taylor series near 0, where the quotient loses digits.
    c = (
        1.0 / 12.0 + a * a / 720.0
        if a < 1e-4
        else 1.0 / (a * a) - (1.0 + math.cos(a)) / (2.0 * a * math.sin(a))
    )
    return np.eye(3) + 0.5 * K + c * (K @ K)


def move_rotation(dtheta_c: np.ndarray, previous: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotation of the body over a move, from its compensated increments.

    Parameters
    ----------
    dtheta_c : ndarray, shape (m, 3)
        Compensated gyro increments of the move's samples, rad.
    previous : ndarray, shape (3,)
        The compensated increment of the sample before the move (its coning partner).

    Returns
    -------
    R : ndarray, shape (3, 3)
        Body at the move's start to body at its end (``C_b_n(end) = C_b_n(start) R`` in an
        inertial frame).
    Q : ndarray, shape (m, 3, 3)
        The rotation through each sample.
    phi : ndarray, shape (m, 3)
        Each sample's rotation vector.
    """
    phi = coning_rotvec(np.vstack([previous, dtheta_c]))[1:]
    Q = quat_to_dcm(prefix_product(rotvec_to_quat(phi)))
    return Q[-1], Q, phi


def move_sensitivity(
    dtheta_c: np.ndarray,
    dt: np.ndarray,
    A_inv: np.ndarray,
    R: np.ndarray,
    Q: np.ndarray,
    phi: np.ndarray,
    dv: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How the move's end attitude turns with the gyro bias, matrix and g-sensitivity.

    With ``dtheta_c = A^-1 (dtheta - b dt - G dv)``, the end turns (body frame at
    the end, right perturbation ``R exp(eps)``) by ``eps = -G_b db - G_A dA - G_G dG``.

    Returns
    -------
    G_b : ndarray, shape (3, 3)
        ``sum_i W_i dt_i`` with ``W_i = R^T Q_i J_r(phi_i) A^-1``.
    G_A : ndarray, shape (3, 3, 3)
        ``G_A[:, j, k] = sum_i W_i[:, j] dtheta_c[i, k]``: the column of ``d eps / d A[j, k]``.
    G_G : ndarray, shape (3, 3, 3)
        The same with the specific-force increments ``dv``: the column of ``d eps / d G[j, k]``.
    """
    W = np.einsum("ba,ibc,icd,de->iae", R, Q, right_jacobian(phi), A_inv)
    G_b = np.einsum("iae,i->ae", W, dt)
    G_A = np.einsum("iaj,ik->ajk", W, dtheta_c)
    G_G = np.einsum("iaj,ik->ajk", W, dv)
    return G_b, G_A, G_G
