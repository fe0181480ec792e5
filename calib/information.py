"""Fisher information helpers shared by the estimator and the analyser."""
from __future__ import annotations

import numpy as np
from scipy.linalg import qr

from . import params as P

UNKNOWN_NAMES = tuple(P.NAMES) + ("phi0_E", "phi0_N", "phi0_U")


def marginal(info: np.ndarray) -> np.ndarray:
    """Information of the 21 parameters after eliminating the initial attitude (Schur complement).

    Works on ``(24, 24)`` or stacks ``(..., 24, 24)``.
    """
    n = P.N_PARAMS
    a, b, c = info[..., :n, :n], info[..., :n, n:], info[..., n:, n:]
    return a - b @ np.linalg.solve(c, np.swapaxes(b, -1, -2))


def null_directions(evecs: np.ndarray, weak: np.ndarray, names=UNKNOWN_NAMES) -> list[str]:
    """Weak or null eigen-directions as sparse combinations of names.

    The subspace has no preferred basis, so it is put in reduced row-echelon
    form: each direction gets one pivot and as few other names as the physics
    forces (e.g. ``+1.00*saz -0.02*baz``: the z accelerometer only ever saw +g).
    Coefficients are in the scaling of the matrix (units of each requirement).
    """
    null = evecs[:, weak].T  # (k, n)
    _, _, piv = qr(null, pivoting=True)
    k = null.shape[0]
    basis = np.linalg.solve(null[:, piv[:k]], null)
    out = []
    for row in basis:
        idx = [i for i in np.argsort(-np.abs(row)) if abs(row[i]) > 0.01][:6]
        out.append(" ".join(f"{row[i]:+.2f}*{names[i]}" for i in idx))
    return out
