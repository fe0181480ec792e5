"""What a Gauss-Newton step solves for, and the fit it ends with.

The unknowns are the 21 parameters, the initial attitude error ``phi0`` and
any optional terms (:mod:`calib.model.optional_terms`), scaled by the requirements
(:func:`unknown_scale`). :func:`solve_information` judges observability by
:mod:`calib.model.information`'s one rule and gives the covariance, refusing a run
that leaves directions unobserved unless the fit is partial (then the weak
combinations are held at zero, :meth:`Solution.project`). :class:`Fit` is
what both loops of :mod:`calib.fit.estimator` return.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib.analysis.nominal import information_along, nominal_run
from calib.errors import CalibError
from calib.model import optional_terms as X, params as P
from calib.model.information import UNKNOWN_NAMES, ScaledInverse, eliminate, scaled_inverse
from calib.model.optional_terms import OptionalTerms
from calib.model.requirements import PAPER, Requirements
from calib.nav.jacobian import N_UNKNOWN, PHI0
from calib.nav.site import Site
from calib.noise.profiles import NoiseProfile

PHI0_SCALE = 1e-4  # rad, for scaling the normal equations only


@dataclass
class Fit:
    """Everything an iteration leaves behind (SI).

    ``covariance`` is over ``[21 parameters, phi0, extras]``. When the run
    leaves some directions unobserved and the fit was asked to be partial,
    the weak combinations are left at their minimum-norm values: the rows of
    the parameters that take part in them are not estimable (``estimable``
    false, sigma inf) and ``null_directions`` names the combinations.
    """

    values: np.ndarray  # (21,)
    C_b_n0: np.ndarray  # (3, 3) at the run's start instant
    covariance: np.ndarray  # (24 + e, 24 + e) of [params, phi0, extras]
    converged: bool
    iterations: int
    residual_rms_mps: float
    chi2_per_dof: float
    n_observations: int
    history: list = field(default_factory=list)
    extras: OptionalTerms = X.NONE
    extra_values: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (e,) SI
    estimable: np.ndarray | None = None  # (21 + e,) bool, over [params, extras]
    null_directions: list = field(default_factory=list)

    def _std(self) -> np.ndarray:
        d = np.sqrt(np.diag(self.covariance)).copy()
        if self.estimable is not None:
            d[param_index(len(d))[~self.estimable]] = np.inf
        return d

    @property
    def sigma(self) -> np.ndarray:
        return self._std()[: P.N_PARAMS]

    @property
    def extra_sigma(self) -> np.ndarray:
        return self._std()[N_UNKNOWN:]

    @property
    def correlation(self) -> np.ndarray:
        d = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = self.covariance / np.outer(d, d)
        if self.estimable is not None:
            bad = param_index(len(d))[~self.estimable]
            rho[bad, :] = np.nan
            rho[:, bad] = np.nan
        return rho


def param_index(n_total: int) -> np.ndarray:
    """Indices of [21 parameters, extras] in the full unknown vector (phi0 skipped)."""
    return np.r_[0 : P.N_PARAMS, N_UNKNOWN:n_total]


def unknown_scale(extras: OptionalTerms = X.NONE, requirements: Requirements = PAPER) -> np.ndarray:
    """The scale of [21 parameters, phi0, extras]: the requirements, PHI0_SCALE, the extras' sizes."""
    return np.concatenate([requirements.si, np.full(3, PHI0_SCALE), extras.scale_si])


def scaled_design(Hw: np.ndarray, extras: OptionalTerms = X.NONE, requirements: Requirements = PAPER):
    """Whitened observation matrix with columns in units of the requirements, and the scale.

    The optional terms are scaled by their typical size (:mod:`calib.model.optional_terms`).
    """
    D = unknown_scale(extras, requirements)
    return Hw.reshape(-1, Hw.shape[-1]) * D, D


@dataclass(frozen=True)
class Solution:
    """Scaled covariance of the unknowns and what the run leaves unobserved."""

    covariance: np.ndarray  # scaled, (24 + e, 24 + e)
    estimable: np.ndarray  # (21 + e,) over [params, extras]
    null_directions: list
    null_basis: np.ndarray | None = None  # (21 + e, k) scaled, orthonormal

    def project(self, x_scaled: np.ndarray) -> np.ndarray:
        """Remove the unobserved combinations from scaled [params, extras] values."""
        if self.null_basis is None or self.null_basis.shape[1] == 0:
            return x_scaled
        return x_scaled - self.null_basis @ (self.null_basis.T @ x_scaled)


def solve_information(
    N: np.ndarray, where: str = "run", names=None, partial: bool = False, nominal=None
) -> Solution:
    """Covariance of the unknowns from a requirement-scaled information matrix.

    Observability is judged by :mod:`calib.model.information`'s one rule on the
    information of [21, extras] with the initial attitude eliminated (as the
    analyser does). A run that leaves directions unobserved is refused by
    naming the parameters it cannot estimate, unless ``partial``: then the
    weak combinations are constrained to zero (a minimum-norm solution)
    and the estimable parameters keep the variance any solution would give.

    ``nominal``, a callable returning the :class:`ScaledInverse` of the
    run's nominal (error-free) trajectory or None, decides instead of the
    run's own trajectory when that one leaves directions unobserved: as the
    analyser judges, and unmoved by the errors not yet estimated.
    """
    names = tuple(names or UNKNOWN_NAMES)
    kept = [n for i, n in enumerate(names) if not P.N_PARAMS <= i < N_UNKNOWN]
    inv = scaled_inverse(eliminate(N, PHI0), kept)
    if inv.full_rank:
        evals, evecs = np.linalg.eigh(N)
        return Solution((evecs / evals) @ evecs.T, inv.estimable, [])
    judged = nominal() if nominal is not None else None
    if judged is not None and not judged.full_rank:
        # The nominal trajectory says which directions are unobserved and which parameters are
        # estimable. Held fixed, those directions stay at zero in the estimate, so they cannot
        # bend the navigated trajectory the next Jacobians are taken along.
        inv = judged
    dirs = inv.null_directions()
    if not partial:
        raise CalibError(
            f"the run cannot observe {len(dirs)} direction(s) of the parameters, so it cannot "
            f"estimate {', '.join(inv.not_estimable()) or 'them'} on their own; unobserved "
            "(in units of each requirement): " + "; ".join(dirs),
            where,
            "use a sequence that excites them (`seqdesign analyze` shows which), or fit the "
            "estimable part with partial=True (the CLI's --partial)",
        )
    null_full = np.zeros((N.shape[0], inv.null_basis.shape[1]))
    null_full[param_index(N.shape[0])] = inv.null_basis
    u, _, _ = np.linalg.svd(null_full, full_matrices=True)
    Q = u[:, null_full.shape[1] :]  # unknowns with no component along the weak subspace
    cov = Q @ np.linalg.inv(Q.T @ N @ Q) @ Q.T
    return Solution(cov, inv.estimable, dirs, inv.null_basis)


def nominal_decision(
    seq, site: Site, profile: NoiseProfile, extras: OptionalTerms, requirements: Requirements, names
) -> ScaledInverse:
    """What the error-free trajectory of ``seq`` at ``site`` observes, by :mod:`calib.model.information`."""
    info = information_along(nominal_run(seq, site, np.zeros(3)), profile, site, extras)
    D = unknown_scale(extras, requirements)
    kept = [n for i, n in enumerate(names) if not P.N_PARAMS <= i < N_UNKNOWN]
    return scaled_inverse(eliminate(info * np.outer(D, D), PHI0), kept)


def solve_step(Hs, D, zw, sol):
    """One Gauss-Newton step: the correction (SI) and the whitened residual after it."""
    delta_scaled = sol.covariance @ (Hs.T @ zw)
    return D * delta_scaled, zw - Hs @ delta_scaled


def history_entry(it: int, delta, cov, resid, sol) -> dict:
    """An iteration's record: its largest step in sigmas and the chi-square after it."""
    n_fitted = sol.covariance.shape[0] - len(sol.null_directions)
    return {
        "iteration": it,
        "max_step_sigma": float(np.max(np.abs(delta) / np.sqrt(np.diag(cov)))),
        "chi2_per_dof": float(resid @ resid / max(1, resid.size - n_fitted)),
    }


def apply_step(values, extra_values, delta, sol, D):
    """Add a step; a partial fit keeps the unobserved combinations of the totals at zero.

    Zeroing them only in each step would let them drift as the directions
    turn from one Jacobian to the next, and the drift bends the trajectory.
    """
    values, extra_values = values + delta[: P.N_PARAMS], extra_values + delta[N_UNKNOWN:]
    if sol.null_directions:
        Dp = D[param_index(len(D))]
        x = sol.project(np.concatenate([values, extra_values]) / Dp) * Dp
        values, extra_values = x[: P.N_PARAMS], x[P.N_PARAMS :]
    return values, extra_values


def fit_result(estimate: tuple, cov, sol, last: tuple, history, converged, extras) -> Fit:
    """The :class:`Fit` both loops end with; the residual is after the last correction (m/s).

    Parameters
    ----------
    estimate : tuple
        ``(values, extra_values, C0)``: the 21, the optional terms and the attitude the run began at.
    cov : ndarray
        The unknowns' covariance.
    sol : Solution
    last : tuple
        ``(z, H, delta)``: the last iteration's observations, Jacobian and step.
    history : list of dict
    converged : bool
    extras : OptionalTerms
    """
    values, extra_values, C0 = estimate
    z, H, delta = last
    z_fit = z - np.einsum("kin,n->ki", H, delta)
    return Fit(
        values=values,
        C_b_n0=C0,
        covariance=cov,
        converged=converged,
        iterations=len(history),
        residual_rms_mps=float(np.sqrt(np.mean(z_fit**2))),
        chi2_per_dof=history[-1]["chi2_per_dof"],
        n_observations=int(z.size),
        history=history,
        extras=extras,
        extra_values=extra_values,
        estimable=sol.estimable,
        null_directions=sol.null_directions,
    )


def nominal_judge(find_sequence, site: Site, profile: NoiseProfile, extras: OptionalTerms, requirements):
    """A callable giving the nominal trajectory's observability decision, computed once.

    Called only when a run's own information leaves directions unobserved:
    the sequence ``find_sequence()`` returns (the one given, else one read off
    a navigation of the log, :mod:`calib.sequence.inferred`; None: no decision)
    decides what is estimable, as the analyser does at the run's latitude and its
    default height (normal gravity at 0 m, whatever gravity the fit itself uses).
    """
    memo = {}
    at_latitude = Site.at(site.latitude_rad)

    def judge():
        if "inv" not in memo:
            seq = find_sequence()
            memo["inv"] = (
                None
                if seq is None
                else nominal_decision(
                    seq, at_latitude, profile, extras, requirements, UNKNOWN_NAMES + extras.names
                )
            )
        return memo["inv"]

    return judge
