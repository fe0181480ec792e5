"""Objectives on information matrices (batched): what the search ranks walks by."""

from __future__ import annotations

import numpy as np

from calib.errors import CalibError
from calib.model import params as P
from calib.model.information import inverse_diagonal, marginal
from calib.model.requirements import PAPER, Requirements

PRIOR_RATIO = 1e4  # partial walks: a prior of 1e4 x each requirement keeps them rankable
OBJECTIVES = ("worst", "D", "A", "E")


def scaled_marginal(N: np.ndarray, prior: bool, requirements: Requirements = PAPER) -> np.ndarray:
    """Requirement-scaled information of the 21 after eliminating phi0: ``(..., 21, 21)``."""
    M = marginal(N)
    D = requirements.si
    M = M * np.outer(D, D)
    if prior:
        M = M + np.eye(P.N_PARAMS) * (9.0 / PRIOR_RATIO**2)
    return M


def score(
    N: np.ndarray, objective: str, prior: bool = True, requirements: Requirements = PAPER
) -> np.ndarray:
    """Figure of merit, smaller is better, for ``(..., 24, 24)`` information matrices.

    ``worst``: max 3 sigma / requirement; ``A``: sum of (sigma/requirement)^2;
    ``D``: -log det of the scaled information; ``E``: -smallest eigenvalue.
    """
    M = scaled_marginal(N, prior, requirements)
    M = 0.5 * (M + np.swapaxes(M, -1, -2))
    if objective in ("worst", "A"):
        # With the prior, partial walks must stay rankable and the prior keeps M invertible:
        # a plain batched inverse (3x faster than eigh). Without it, the one observability
        # rule of calib.model.information: inf for a walk that leaves a direction unobserved.
        d = np.einsum("...ii->...i", np.linalg.inv(M)) if prior else inverse_diagonal(M)
        return 3.0 * np.sqrt(d.max(axis=-1)) if objective == "worst" else d.sum(axis=-1)
    ev = np.linalg.eigvalsh(M)
    if objective == "D":
        return np.where(ev[..., 0] > 0, -np.sum(np.log(np.abs(ev)), axis=-1), np.inf)
    if objective == "E":
        return -ev[..., 0]
    raise CalibError(
        f"unknown objective {objective!r}", "objective (the CLI's --objective)", "use worst, D, A or E"
    )
