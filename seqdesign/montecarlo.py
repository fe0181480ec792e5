"""Monte Carlo of simulate -> calibrate: does the estimator reach the predicted accuracy?

Each trial draws its own noise, base mounting within the tolerance and flip
errors from ``seed + trial``, so a run with N workers gives exactly the
serial result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from calib.calibration.entry import CalibrateOptions, calibrate
from calib.model.error_model import ErrorModel
from calib.model.optional_terms import NONE as NO_EXTRAS, OptionalTerms, OptionalTermValues
from calib.noise.profiles import NoiseProfile
from calib.sequence.definition import Sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate

from .search.parallel import map_jobs


@dataclass(frozen=True)
class Trials:
    """Estimation errors and reported covariances of N trials (SI)."""

    errors: np.ndarray  # (N, 21) estimate - truth
    covariances: np.ndarray  # (N, 21, 21) as the estimator reported them
    converged: np.ndarray  # (N,) bool

    @property
    def nees(self) -> np.ndarray:
        return np.array(
            [e @ np.linalg.solve(C, e) for e, C in zip(self.errors, self.covariances, strict=True)]
        )

    @property
    def rms_error(self) -> np.ndarray:
        return np.sqrt(np.mean(self.errors**2, axis=0))

    @property
    def mean_sigma(self) -> np.ndarray:
        return np.mean(np.sqrt(np.einsum("nii->ni", self.covariances)), axis=0)

    def nees_against(self, covariance: np.ndarray) -> np.ndarray:
        """NEES of each trial against a fixed (e.g. predicted) covariance."""
        return np.einsum("ni,ni->n", self.errors, np.linalg.solve(covariance, self.errors.T).T)


@dataclass(frozen=True)
class TrialConfig:
    """How each Monte Carlo trial is simulated and fitted (all but the sequence, profile and seed).

    Parameters
    ----------
    latitude_deg : float
        The simulated site's latitude.
    errors : ErrorModel, optional
        The true 21 of every trial. Default (None): Table 2's.
    tolerance_deg : float
        Each trial's base mounting is drawn within this many degrees (0: none).
    flip_error_deg : float
        Each flip's error, degrees.
    extra : OptionalTermValues, optional
        A real unit's optional terms added to the simulated runs.
    extras : OptionalTerms
        The groups the estimator fits with the 21 (the mismatch report: simulate
        with them, calibrate without or with them).
    fit_profile : NoiseProfile, optional
        Weights the fit when it differs from the simulated noise.
    requirements : Requirements, optional
        Scale the fit (and so what it calls observable).
    """

    latitude_deg: float = 40.0
    errors: ErrorModel | None = None
    tolerance_deg: float = 3.0
    flip_error_deg: float = 0.5
    extra: OptionalTermValues | None = None
    extras: OptionalTerms = NO_EXTRAS
    fit_profile: NoiseProfile | None = None
    requirements: object = None

    @property
    def true_errors(self) -> ErrorModel:
        return self.errors if self.errors is not None else ErrorModel.from_table2()


TRIALS = TrialConfig()  # the defaults


@dataclass(frozen=True)
class TrialJob:
    """One trial's inputs (picklable: run on a worker or a dask cluster)."""

    seq: Sequence
    profile: NoiseProfile
    config: TrialConfig  # with its errors resolved
    seed: int


def one_trial(job: TrialJob) -> tuple[np.ndarray, np.ndarray, bool]:
    """Simulate one run and calibrate it with the library call the CLI uses (same sigmas)."""
    c = job.config
    cfg = SimConfig(latitude_rad=math.radians(c.latitude_deg))
    run, truth = simulate(
        job.seq,
        cfg,
        c.true_errors,
        job.profile,
        SimOptions.drawn(job.seed, c.tolerance_deg, c.flip_error_deg),
        extra=c.extra,
    )
    result = calibrate(
        run,
        c.fit_profile or job.profile,
        extras=c.extras,
        options=CalibrateOptions(require_convergence=False),
        requirements=c.requirements,
    )
    return result.values - c.true_errors.values, result.covariance, result.converged


def run_trials(
    seq: Sequence,
    profile: NoiseProfile,
    n: int,
    seed: int = 0,
    config: TrialConfig = TRIALS,
    workers: int = 1,
    scheduler=None,
) -> Trials:
    """Simulate and calibrate ``n`` runs; trial ``i`` uses seed ``seed + i``.

    ``config`` says how each is simulated and fitted (:class:`TrialConfig`);
    ``workers`` local processes, or ``scheduler`` a dask.distributed address or client
    (:func:`seqdesign.search.parallel.map_jobs`, as the design search).
    """
    config = replace(config, errors=config.true_errors)
    jobs = [TrialJob(seq, profile, config, seed + i) for i in range(n)]
    out = map_jobs(one_trial, jobs, workers, scheduler)
    return Trials(
        errors=np.array([o[0] for o in out]),
        covariances=np.array([o[1] for o in out]),
        converged=np.array([o[2] for o in out]),
    )
