"""Fisher information: marginals, the scaled inverse, rank and estimability under one rule.

The estimator, the analyser and the design search all ask the same
questions of an information matrix: which directions of the unknowns does
it not observe, which parameters can be estimated on their own, and what is
their covariance. They ask them here, in units of each unknown's
requirement (or typical size), so that "observable" means the same thing in
``analyze``, ``design`` and ``calibrate``.

The rule: an eigen-direction of the scaled information is **weak** when its
eigenvalue is below ``max(WEAK_INFORMATION, RELATIVE_RANK_TOL * largest)``,
i.e. its sigma would exceed 1000 requirements, or it is numerically null.
A parameter is **estimable** when its unit vector lies in the span of the
observed directions: its component along the weak subspace is below
``ESTIMABLE_TOL``. An estimable parameter's variance is then the
pseudo-inverse's (the variance of the best linear unbiased estimate of that
parameter when the weak combinations are left unfitted).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import params as P

UNKNOWN_NAMES = tuple(P.NAMES) + ("phi0_E", "phi0_N", "phi0_U")

WEAK_INFORMATION = 1e-6  # requirement-scaled: sigma > 1000 x requirement
RELATIVE_RANK_TOL = 1e-12  # below this fraction of the largest eigenvalue: numerically null
# A parameter's unit vector may lean this much into the weak subspace and still count as
# estimable. A weak direction is one known no better than 1000 requirements, so a lean of
# 3e-5 lets even a combination that large bias the parameter by at most 3 % of its
# requirement; eigenvectors of these well-scaled matrices are accurate to ~1e-10, far below.
ESTIMABLE_TOL = 3e-5


def marginal(info: np.ndarray, n_keep: int = P.N_PARAMS) -> np.ndarray:
    """Information of the first ``n_keep`` unknowns after eliminating the rest (Schur complement).

    Works on ``(n, n)`` or stacks ``(..., n, n)``; the eliminated block
    (the initial attitude) must be invertible, which levelling and
    gyrocompassing on the first rest guarantee.
    """
    a, b, c = info[..., :n_keep, :n_keep], info[..., :n_keep, n_keep:], info[..., n_keep:, n_keep:]
    return a - b @ np.linalg.solve(c, np.swapaxes(b, -1, -2))


def eliminate(info: np.ndarray, nuisance: slice) -> np.ndarray:
    """Information of every unknown but ``nuisance`` (a contiguous block), by Schur complement."""
    n = info.shape[-1]
    keep = np.r_[0 : nuisance.start, nuisance.stop : n]
    a = info[np.ix_(keep, keep)]
    b = info[keep, nuisance]
    c = info[nuisance, nuisance]
    return a - b @ np.linalg.solve(c, b.T)


def weak_mask(evals: np.ndarray) -> np.ndarray:
    """Which eigenvalues of a scaled information are weak or null (the module's one rule)."""
    top = max(float(np.max(evals, initial=0.0)), 0.0)
    return evals < max(WEAK_INFORMATION, RELATIVE_RANK_TOL * top)


@dataclass(frozen=True)
class ScaledInverse:
    """What a requirement-scaled information matrix says about its unknowns.

    Attributes
    ----------
    covariance : ndarray (n, n)
        Pseudo-inverse on the observed subspace (scaled units). Its diagonal is
        the variance of each estimable unknown; rows of non-estimable ones
        are meaningless and set to inf on the diagonal.
    rank : int
        Number of observed directions.
    null_basis : ndarray (n, k)
        Orthonormal basis of the weak subspace.
    estimable : ndarray (n,) of bool
    names : tuple of str
    """

    covariance: np.ndarray
    rank: int
    null_basis: np.ndarray
    estimable: np.ndarray
    names: tuple

    @property
    def full_rank(self) -> bool:
        return self.null_basis.shape[1] == 0

    @property
    def variance(self) -> np.ndarray:
        """Scaled variance of each unknown; inf where it is not estimable."""
        d = np.diag(self.covariance).copy()
        d[~self.estimable] = np.inf
        return d

    def null_directions(self) -> list[str]:
        """The weak subspace as sparse combinations of names (see :func:`describe_null`)."""
        return describe_null(self.null_basis, self.names)

    def not_estimable(self) -> list[str]:
        return [n for n, e in zip(self.names, self.estimable, strict=True) if not e]


def scaled_inverse(M: np.ndarray, names=UNKNOWN_NAMES, n_weak: int | None = None) -> ScaledInverse:
    """Inverse, rank and estimability of a scaled information matrix under the module's rule.

    ``n_weak`` overrides the rule's count of weak directions (the ``n_weak``
    smallest are taken): the estimator uses it to keep the rank the nominal
    trajectory shows while its own trajectory is still bent by errors.
    """
    M = 0.5 * (M + M.T)
    evals, evecs = np.linalg.eigh(M)
    weak = weak_mask(evals) if n_weak is None else np.arange(len(evals)) < n_weak
    good = ~weak
    cov = (evecs[:, good] / evals[good]) @ evecs[:, good].T
    null = evecs[:, weak]
    lean = np.sqrt(np.sum(null**2, axis=1))  # each unit vector's component along the null space
    return ScaledInverse(
        covariance=cov,
        rank=int(good.sum()),
        null_basis=null,
        estimable=lean < ESTIMABLE_TOL,
        names=tuple(names[: M.shape[0]]),
    )


def projected_covariance(M: np.ndarray, null_basis: np.ndarray) -> np.ndarray:
    """Scaled covariance of ``M`` with the directions of ``null_basis`` left unfitted.

    Used at tilted mountings to judge a sequence by the subspace it observes
    at the nominal one: a tilt must not make a parameter count as observed.
    The result is ``Q (Q^T M Q)^-1 Q^T`` with ``Q`` spanning the complement
    of ``null_basis``; all inf where ``Q^T M Q`` is itself weak.
    """
    n = M.shape[0]
    if null_basis.shape[1] == 0:
        Q = np.eye(n)
    else:
        u, _, _ = np.linalg.svd(null_basis, full_matrices=True)
        Q = u[:, null_basis.shape[1] :]
    R = Q.T @ M @ Q
    evals, evecs = np.linalg.eigh(0.5 * (R + R.T))
    if np.any(weak_mask(evals)):
        return np.full((n, n), np.inf)
    V = Q @ evecs
    return (V / evals) @ V.T


def inverse_diagonal(M: np.ndarray) -> np.ndarray:
    """Diagonal of the inverse of a stack ``(..., n, n)`` of scaled information matrices.

    For the design search's batches. A matrix with a weak direction (same
    rule) gets inf everywhere: a candidate that leaves a parameter
    unobserved is never preferred.
    """
    M = 0.5 * (M + np.swapaxes(M, -1, -2))
    evals, evecs = np.linalg.eigh(M)
    weak = np.any(weak_mask_batched(evals), axis=-1)
    safe = np.where(weak[..., None], 1.0, evals)
    d = np.einsum("...ij,...j,...ij->...i", evecs, 1.0 / safe, evecs)
    return np.where(weak[..., None], np.inf, d)


def weak_mask_batched(evals: np.ndarray) -> np.ndarray:
    """:func:`weak_mask` for a stack of eigenvalue vectors ``(..., n)``."""
    top = np.maximum(evals.max(axis=-1, keepdims=True), 0.0)
    return evals < np.maximum(WEAK_INFORMATION, RELATIVE_RANK_TOL * top)


def describe_null(null_basis: np.ndarray, names=UNKNOWN_NAMES) -> list[str]:
    """Weak or null directions as sparse combinations of names.

    The subspace has no preferred basis, so it is put in reduced row-echelon
    form: each direction gets one pivot and as few other names as the physics
    forces (e.g. ``+1.00*saz -0.02*baz``: the z accelerometer only ever saw +g).
    Coefficients are in the scaling of the matrix (units of each requirement).
    """
    if null_basis.shape[1] == 0:
        return []
    out = []
    for row in row_echelon(null_basis.T):
        idx = [i for i in np.argsort(-np.abs(row)) if abs(row[i]) > 0.01][:6]
        out.append(" ".join(f"{row[i]:+.2f}*{names[i]}" for i in idx))
    return out


def row_echelon(rows: np.ndarray) -> np.ndarray:
    """Reduced row-echelon form of the span of ``rows`` (k, n), k independent rows.

    Pivots are chosen by column-pivoted QR: each row gets one pivot column (a
    unit there, zero in the others' pivots) and as few other terms as the span
    forces, which is how weak directions and separable combinations are written.
    """
    from scipy.linalg import qr  # only for a run that leaves directions unobserved

    k = rows.shape[0]
    _, _, piv = qr(rows, pivoting=True)
    return np.linalg.solve(rows[:, piv[:k]], rows)
