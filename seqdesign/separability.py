"""What a rank-deficient sequence cannot separate, what it can, and what motion would help.

The analyser finds the unobserved directions of the requirement-scaled
information (:mod:`calib.model.information`). Here they are turned into what an
engineer acts on: for the parameters that cannot be estimated on their own,
the combinations of them that the sequence does determine (in the
parameters' own units), and, per parameter, the motion that excites it.
"""

from __future__ import annotations

import numpy as np

from calib.model import params as P
from calib.model.information import row_echelon

AXES = "XYZ"
INVOLVED = 0.01  # a parameter takes part in a null direction above this scaled component


def involvement(null_basis: np.ndarray) -> list[list[int]]:
    """For each parameter, the indices of the null directions (RREF basis) it takes part in."""
    if null_basis.shape[1] == 0:
        return [[] for _ in range(null_basis.shape[0])]
    rref = row_echelon(null_basis.T)  # the same basis describe_null prints
    k = rref.shape[0]
    out = []
    for i in range(rref.shape[1]):
        dirs = [d for d in range(k) if abs(rref[d, i]) > INVOLVED]
        if not dirs and np.abs(rref[:, i]).max() > 1e-6:  # a small lean still counts
            dirs = [int(np.argmax(np.abs(rref[:, i])))]
        out.append(dirs)
    return out


def separable_combinations(
    null_basis: np.ndarray, estimable: np.ndarray, names=P.NAMES, scales=P.REQUIREMENTS
) -> list[str]:
    """Combinations of the non-estimable parameters that the sequence does determine.

    They are the directions, among the non-estimable parameters, orthogonal
    to every unobserved direction. Written in each parameter's own unit,
    normalised on its largest term (e.g. ``baz + 1.00 saz`` means the sum of
    the z accelerometer's bias in ug and its scale factor in ppm is known).
    """
    idx = np.flatnonzero(~np.asarray(estimable))
    if idx.size == 0:
        return []
    sub = null_basis[idx]  # the null directions restricted to those parameters
    comp = _null_space(sub.T) if sub.size else np.eye(idx.size)  # (m, r), scaled units
    if comp.shape[1] == 0:
        return []
    # Reduced row-echelon form, as the null directions are printed: each combination gets a
    # pivot parameter and as few others as the physics forces.
    out = []
    for row in row_echelon(comp.T):  # (r, m), scaled
        keep = np.abs(row) > 0.01  # as describe_null: terms above 1 % in requirement units
        own = row / np.asarray(scales)[idx]  # coefficient of each parameter in its own unit
        own = own / own[np.argmax(np.abs(row))]
        text = " ".join(
            f"{'+' if own[k] > 0 else '-'} {abs(own[k]):.3g} {names[idx[k]]}" for k in np.flatnonzero(keep)
        ).lstrip("+ ")
        small = np.abs(row[~keep]).max(initial=0.0)
        out.append(text + (f" (+ terms below {small:.0e} of a requirement)" if small > 1e-6 else ""))
    return out


def motion_hint(index: int) -> str:
    """The motion that excites parameter ``index``, from what it multiplies in the sensor model."""
    p = P.PARAMETERS[index]
    i = AXES[p.row]
    if p.sensor == "accel":
        if p.kind == "bias":
            return f"body {i} must see gravity with both signs (point {i} up and down)"
        if p.kind == "scale":
            return f"body {i} must see +g and -g (point {i} up, then down)"
        return (
            f"body {AXES[p.col]} must see gravity while the {i} accelerometer is horizontal, with both signs"
        )
    if p.kind == "bias":
        return f"body {i} must point in different directions relative to the Earth's rotation"
    if p.kind == "scale":
        return f"turn about body {i} (flips about {i}, both directions help)"
    return f"turn about body {AXES[p.col]} (the {i} gyro senses a turn about {AXES[p.col]})"


def _null_space(A: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the null space of ``A``, by SVD, with scipy.linalg.null_space's rank
    rule (singular values below ``eps max(m, n)`` of the largest): that module costs 0.3 s to import.
    """
    _, s, vh = np.linalg.svd(A, full_matrices=True)
    tol = (s.max() if s.size else 0.0) * np.finfo(float).eps * max(A.shape)
    rank = int(np.sum(s > tol))
    return vh[rank:].T.conj()
