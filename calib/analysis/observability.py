"""What the Fisher information of a sequence says at one mounting: sigma, rank, separability.

The information is the one the estimator would gather: the same linear
model (:func:`calib.nav.jacobian.observation_jacobian`) evaluated along the
nominal trajectory of the sequence, the same observation intervals and the
same noise whitening (:mod:`calib.analysis.mounting` builds it for any mounting,
:mod:`calib.analysis.nominal` along one trajectory). Its inverse is the covariance
the calibration will reach with that noise profile; the Monte Carlo tests
check that it does.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from calib.model import params as P
from calib.model.information import ScaledInverse, marginal, projected_covariance, scaled_inverse
from calib.model.requirements import PAPER, Requirements

CORRELATION_LIMIT = 0.9


@dataclass(frozen=True)
class Observability:
    """Predicted accuracy and separability of the 21 parameters at one mounting.

    Attributes
    ----------
    information : ndarray (24, 24)
        Fisher information of [21 parameters, phi0] in SI.
    covariance : ndarray (21, 21)
        Marginal covariance of the 21 (SI) with the unobserved directions left
        unfitted; rows of parameters that are not estimable mean nothing.
    rank : int
        Number of observed directions of the 21 (:mod:`calib.model.information`'s rule).
    unobservable : list of str
        Unobserved directions as combinations of parameter names.
    estimable : ndarray (21,) of bool
        Whether each parameter can be estimated on its own.
    null_basis : ndarray (21, k)
        The unobserved directions (requirement-scaled, orthonormal).
    """

    information: np.ndarray
    covariance: np.ndarray
    rank: int
    unobservable: list[str]
    duration_s: float
    profile: str
    setup_rotvec: np.ndarray
    estimable: np.ndarray
    null_basis: np.ndarray
    requirements: Requirements = PAPER

    @property
    def sigma(self) -> np.ndarray:
        """1-sigma (SI) of each parameter; inf where it is not estimable."""
        s = np.sqrt(np.abs(np.diag(self.covariance)))
        return np.where(self.estimable, s, np.inf)

    @property
    def ratio(self) -> np.ndarray:
        return self.requirements.ratio(self.sigma)

    @property
    def worst(self) -> tuple[str, float]:
        """The estimable parameter with the largest ratio (inf if none is estimable)."""
        r = np.where(self.estimable, self.ratio, -np.inf)
        i = int(np.argmax(r))
        return P.NAMES[i], float(r[i]) if self.estimable.any() else math.inf

    @property
    def correlation(self) -> np.ndarray:
        s = np.sqrt(np.abs(np.diag(self.covariance)))
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = self.covariance / np.outer(s, s)
        rho[~self.estimable, :] = np.nan
        rho[:, ~self.estimable] = np.nan
        return rho

    def correlated_pairs(self, limit: float = CORRELATION_LIMIT) -> list[tuple[str, str, float]]:
        """Pairs of estimable parameters with ``|rho|`` above ``limit``, strongest first."""
        rho = self.correlation
        out = [
            (P.NAMES[i], P.NAMES[j], float(rho[i, j]))
            for i, j in itertools.combinations(range(P.N_PARAMS), 2)
            if self.estimable[i] and self.estimable[j] and abs(rho[i, j]) > limit
        ]
        return sorted(out, key=lambda t: -abs(t[2]))

    def scaled_information(self) -> np.ndarray:
        """Marginal information of the 21, in units of the requirements (dimensionless)."""
        D = self.requirements.si
        return marginal(self.information) * np.outer(D, D)

    def criteria(self) -> dict[str, float]:
        """D-, A-, E-criteria and condition number of the requirement-scaled information.

        D: log det of the scaled information (larger is better); A: trace of
        the scaled covariance, i.e. sum of (sigma/requirement)^2 (smaller is
        better); E: smallest eigenvalue of the scaled information (larger is
        better).
        """
        ev = np.linalg.eigvalsh(self.scaled_information())
        if self.rank < P.N_PARAMS or ev[0] <= 0:
            return {"D": -math.inf, "A": math.inf, "E": 0.0, "condition": math.inf}
        return {
            "D": float(np.sum(np.log(ev))),
            "A": float(np.sum(1.0 / ev)),
            "E": float(ev[0]),
            "condition": float(ev[-1] / ev[0]),
        }


def from_information(
    info: np.ndarray,
    duration_s: float,
    profile: str,
    setup_rotvec,
    nominal: Observability | None = None,
    requirements: Requirements = PAPER,
) -> Observability:
    """Observability from the information of [21, phi0].

    With ``nominal`` (the same sequence at the nominal mounting), what is
    observed is judged there: its unobserved directions stay unfitted here
    too, so a tilt cannot make a parameter count as observed.
    """
    D = requirements.si
    Ms = marginal(info) * np.outer(D, D)
    inv = scaled_inverse(Ms, P.NAMES)
    if nominal is not None and not nominal.estimable.all():
        cov = projected_covariance(Ms, nominal.null_basis)
        inv = ScaledInverse(cov, nominal.rank, nominal.null_basis, nominal.estimable, inv.names)
    return Observability(
        information=info,
        covariance=inv.covariance * np.outer(D, D),
        rank=inv.rank,
        unobservable=inv.null_directions(),
        duration_s=duration_s,
        profile=profile,
        setup_rotvec=np.asarray(setup_rotvec, dtype=float),
        estimable=inv.estimable,
        null_basis=inv.null_basis,
        requirements=requirements,
    )
