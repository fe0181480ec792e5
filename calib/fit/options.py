"""The estimator's options as one value: what is fitted, how far and how it iterates.

:class:`FitOptions` travels unchanged from :func:`calib.fit.estimator.fit_run` and
:func:`calib.fit.chunked.fit_file` down to the Gauss-Newton loops; its defaults are
written here once, for the library, the CLI and :mod:`seqdesign.api`.
"""

from __future__ import annotations

from dataclasses import dataclass

from calib.model import optional_terms as X
from calib.model.optional_terms import OptionalTerms
from calib.model.requirements import PAPER, Requirements

from .sanity import MAX_PLAUSIBLE_RATE

RENAVIGATE = ("when-needed", "always")  # the loops fit_run chooses between


@dataclass(frozen=True)
class FitOptions:
    """How the estimator fits a run.

    Parameters
    ----------
    extras : OptionalTerms
        Optional terms (:mod:`calib.model.optional_terms`) to estimate with the 21.
    partial : bool
        Fit the estimable part of a run that leaves directions unobserved
        instead of refusing it (:func:`calib.fit.solution.solve_information`).
    requirements : Requirements
        Scale the unknowns, and so decide what counts as observed
        (:mod:`calib.model.information`).
    max_iterations : int, optional
        Gauss-Newton iterations at most. Default (None): :data:`calib.fit.feedback.MAX_ITERATIONS`,
        or more for a run whose attitude noise needs the feedback of
        :func:`calib.fit.feedback.attitude_feedback`.
    tol_sigma : float
        Converged when every correction is below this fraction of its sigma.
    renavigate : {"when-needed", "always"}
        "when-needed": stream the run through :func:`calib.fit.estimator.fit_intervals`,
        which navigates only while a step could still move the estimate by
        ``tol_sigma``; "always": the reference loop that re-navigates the
        whole run in memory at every iteration (for tests and benchmarks).
        A run in memory only (:func:`calib.fit.estimator.fit_run`).
    max_rate_rad_s : float or None
        The fastest plausible turn (:func:`calib.fit.sanity.check_rates`): a gimbal's by
        default; a run turned by hand gives its sensor's range, or None for no check.
        A run in memory only.
    """

    extras: OptionalTerms = X.NONE
    partial: bool = False
    requirements: Requirements = PAPER
    max_iterations: int | None = None
    tol_sigma: float = 1e-3
    renavigate: str = "when-needed"
    max_rate_rad_s: float | None = MAX_PLAUSIBLE_RATE

    def __post_init__(self) -> None:
        if self.renavigate not in RENAVIGATE:
            raise ValueError(f"renavigate must be 'when-needed' or 'always', not {self.renavigate!r}")


FIT = FitOptions()  # the defaults
