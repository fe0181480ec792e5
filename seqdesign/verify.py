"""Prove a sequence before the hardware turns: N simulated runs, each calibrated, against the prediction.

Each run draws its own unit (the 21 errors of the profile's grade, uniform within the sizes of
:func:`error_half_range`, or the fixed errors a user gives), its base mounting within the
tolerance, its flip errors and its noise, from ``seed + run``; it is simulated and calibrated
exactly as ``simulate`` and ``calibrate`` do. The report says whether the sigmas the estimator
reports are honest (mean NEES against its chi-square band), whether the errors it makes are the
ones ``analyze`` predicts (RMS error over the predicted sigma), and which runs were refused or
did not converge. The runs are independent: N workers or a dask cluster give the serial answer.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from calib.calibration.entry import CalibrateOptions, calibrate
from calib.errors import CalibError
from calib.hand.plan import HAND_PLAN, HAND_POSES, random_hand_plan, xsens_like_plan
from calib.hand.poses import PoseList, tipping_plan
from calib.hand.simulate import HandStreams, simulate_by_hand, write_hand_run
from calib.hand.troubles import TroubleSpec
from calib.model import params as P
from calib.model.error_model import ErrorModel, paper_table
from calib.model.optional_terms import NONE as NO_EXTRAS, OptionalTerms
from calib.model.requirements import PAPER, Requirements, grade_of as requirements_grade
from calib.nav.transform import rotvec_to_dcm
from calib.noise.profiles import NoiseProfile
from calib.runlog import read_run
from calib.sequence.definition import Sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate

from .search.parallel import map_jobs

# The unit's errors before calibration, half-ranges in spec units, by grade (the profile's ARW
# decides the grade: calib.model.requirements.GRADES, which also gives each its requirements).
# Navigation and tactical: twice the paper's Table 2 standard values, which are a navigation
# unit's; MEMS: the sizes of an ADIS16405-class data sheet (gyro bias 1000 deg/h,
# accelerometer bias 20 mg, scale factors 0.5 %, misalignments 1000 arcsec = 0.28 deg).
_MEMS = {("gyro", "bias"): 1000.0, ("accel", "bias"): 20000.0, ("gyro", "scale"): 5000.0}
_MEMS |= {("accel", "scale"): 5000.0}
MEMS_MISALIGNMENT_ARCSEC = 1000.0


def grade_of(profile: NoiseProfile) -> str:
    """``navigation``, ``tactical`` or ``mems``, from the gyro's angle random walk.

    The grade the default requirements follow too (:func:`calib.model.requirements.grade_of`).
    """
    return requirements_grade(profile)[0].lower()


def error_half_range(grade: str) -> np.ndarray:
    """Half-range of each of the 21 errors of a unit of ``grade``, spec units."""
    if grade == "mems":
        return np.array([_MEMS.get((p.sensor, p.kind), MEMS_MISALIGNMENT_ARCSEC) for p in P.PARAMETERS])
    return 2.0 * np.abs(paper_table("table2_simulation", "standard"))


def chi2_band(n_runs: int, dof: int = P.N_PARAMS, probability: float = 0.99) -> tuple[float, float]:
    """The band the mean NEES of ``n_runs`` honest runs falls in with ``probability``."""
    from scipy.stats import chi2  # scipy.stats costs 0.3 s to import: only when a report is made

    tail = (1.0 - probability) / 2.0
    lo, hi = chi2.ppf([tail, 1.0 - tail], n_runs * dof)
    return float(lo / n_runs), float(hi / n_runs)


@dataclass(frozen=True)
class HandShape:
    """The runs placed by hand a by-hand verification draws (:mod:`calib.hand.plan`)."""

    like: str | None = None  # "xsens": the shape of imu_tk's Xsens recording; None: random
    poses: int = HAND_POSES
    peak_rate_dps: float | None = HAND_PLAN.peak_rate_dps
    translation_m: float = HAND_PLAN.translation_m
    wobble_deg: float = HAND_PLAN.wobble_deg
    g_sensitivity: bool = False  # fit the gyro g-sensitivity too (injected by troubles only)
    pose_list: PoseList | None = None  # a user's poses instead of random ones
    placement_deg: float = 0.0  # each pose of the pose list placed within this (each axis)
    troubles: TroubleSpec = TroubleSpec()  # a real recording's troubles (none by default)

    @property
    def name(self) -> str:
        if self.pose_list is not None:
            shape = self.pose_list.name
        else:
            shape = f"{self.like}-like" if self.like else f"{self.poses} random poses"
        return f"by hand ({shape}{''.join(', ' + t for t in self.trouble_words())})"

    def trouble_words(self) -> list[str]:
        """The troubles the runs carry, in words (none: an empty list)."""
        t = self.troubles
        gs = t.g_sensitivity_dphg
        words = {
            f"tremor {t.tremor_deg:g} deg": t.tremor_deg,
            f"g-sensitivity {gs if isinstance(gs, float | int) else 'fixed'} deg/h/g": gs is not None,
            f"rate error {t.rate_error:+g}": t.rate_error,
            f"stamps up to {1000 * t.stamp_jitter_s:g} ms late": t.stamp_jitter_s,
            f"{t.stamps} stamps": t.stamps != "seconds",
        }
        return [w for w, on in words.items() if on]

    def plan(self, rng: np.random.Generator):
        if self.pose_list is not None:
            C = self.pose_list.attitudes()
            tilt = rng.uniform(-1.0, 1.0, (len(C), 3)) * np.radians(self.placement_deg)
            return tipping_plan(rotvec_to_dcm(tilt) @ C, self.pose_list.hold_s, self.pose_list.move_s)
        shape = replace(
            HAND_PLAN,
            translation_m=self.translation_m,
            wobble_deg=self.wobble_deg,
            peak_rate_dps=self.peak_rate_dps,
        )
        if self.like == "xsens":
            return xsens_like_plan(rng, shape)
        return random_hand_plan(self.poses, rng, shape)


@dataclass(frozen=True)
class VerifyJob:
    """One run's inputs (picklable: a worker or a dask cluster runs it)."""

    seq: Sequence | None
    profile: NoiseProfile
    config: SimConfig
    errors: ErrorModel | None  # None: drawn from the grade's half-ranges
    half_range: np.ndarray = field(repr=False)
    tolerance_deg: float
    flip_error_deg: float
    seed: int
    extras: OptionalTerms
    requirements: Requirements
    hand: HandShape | None = None  # runs placed by hand instead of the sequence


@dataclass(frozen=True)
class RunOutcome:
    """What one run gave: its errors and covariance (SI), or why it was refused."""

    seed: int
    error: np.ndarray | None
    covariance: np.ndarray | None
    converged: bool
    refusal: str | None = None


def one_run(job: VerifyJob) -> RunOutcome:
    """Simulate one run and calibrate it as the CLI does; a refusal is an outcome, not a crash."""
    rng = np.random.default_rng(job.seed)
    errors = job.errors
    if errors is None:
        errors = ErrorModel.from_units(rng.uniform(-1.0, 1.0, P.N_PARAMS) * job.half_range)
    if job.hand is not None:
        return _one_hand_run(job, errors, rng)
    assert job.seq is not None
    run, truth = simulate(
        job.seq,
        job.config,
        errors,
        job.profile,
        SimOptions.drawn(job.seed, job.tolerance_deg, job.flip_error_deg),
    )
    try:
        result = calibrate(
            run,
            job.profile,
            extras=job.extras,
            options=CalibrateOptions(require_convergence=False),
            requirements=job.requirements,
        )
    except CalibError as exc:
        return RunOutcome(job.seed, None, None, False, str(exc))
    return RunOutcome(job.seed, result.values - truth.errors.values, result.covariance, result.converged)


def _one_hand_run(job: VerifyJob, errors: ErrorModel, rng: np.random.Generator) -> RunOutcome:
    """One run placed by hand: its poses, moves and noise drawn from the run's generator."""
    assert job.hand is not None
    plan = job.hand.plan(rng)
    troubles = job.hand.troubles.draw(plan, rng)
    run, truth = simulate_by_hand(
        plan, job.config, errors, job.profile, troubles=troubles, streams=HandStreams(rng, rng)
    )
    try:
        if troubles.stamp_jitter_s or troubles.stamps != "seconds":
            run = _as_read(run, truth)
        result = calibrate(
            run,
            job.profile,
            by_hand=True,
            extras="g-sensitivity" if job.hand.g_sensitivity else None,
            options=CalibrateOptions(require_convergence=False),
            requirements=job.requirements,
        )
    except CalibError as exc:
        return RunOutcome(job.seed, None, None, False, str(exc))
    return RunOutcome(job.seed, result.values - truth.errors.values, result.covariance, result.converged)


def _as_read(run, truth):
    """A run with a host's stamps as ``calibrate`` gets it from its file: written, then read back."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.csv"
        write_hand_run(path, run, truth)
        return read_run(path)


@dataclass(frozen=True)
class Verification:
    """N runs of one sequence under one profile, against the analyser's prediction."""

    sequence: Sequence | None
    profile: NoiseProfile
    requirements: Requirements
    grade: str
    predicted_sigma: np.ndarray  # (21,) SI, analyze's worst case over the mounting box (nan: none)
    outcomes: tuple[RunOutcome, ...]
    hand: HandShape | None = None

    @property
    def name(self) -> str:
        return self.hand.name if self.hand is not None else self.sequence.name if self.sequence else "?"

    @property
    def fitted(self) -> list[RunOutcome]:
        """The runs that converged (the statistics are over these)."""
        return [o for o in self.outcomes if o.error is not None and o.converged]

    @property
    def refused(self) -> list[RunOutcome]:
        return [o for o in self.outcomes if o.error is None]

    @property
    def unconverged(self) -> list[RunOutcome]:
        return [o for o in self.outcomes if o.error is not None and not o.converged]

    def _stack(self) -> tuple[np.ndarray, np.ndarray]:
        runs = self.fitted
        return np.array([o.error for o in runs]), np.array([o.covariance for o in runs])

    def nees(self) -> np.ndarray:
        """Each converged run's normalised estimation error squared (21 dof if honest)."""
        err, cov = self._stack()
        return np.einsum("ni,ni->n", err, np.linalg.solve(cov, err[..., None])[..., 0])

    def z_scores(self) -> np.ndarray:
        """(runs, 21) error over the sigma each run reported."""
        err, cov = self._stack()
        return err / np.sqrt(np.einsum("nii->ni", cov))

    def rms_over_reported(self) -> np.ndarray:
        """RMS over the runs of error / reported sigma, per parameter (1 if honest)."""
        return np.sqrt(np.mean(self.z_scores() ** 2, axis=0))

    def rms_over_predicted(self) -> np.ndarray:
        """RMS error over analyze's sigma, per parameter (about 1 if the prediction holds)."""
        err, _ = self._stack()
        return np.sqrt(np.mean(err**2, axis=0)) / self.predicted_sigma

    def to_json(self) -> dict:
        n = len(self.fitted)
        doc: dict = {
            "sequence": self.name,
            "profile": self.profile.name,
            "requirements": self.requirements.name,
            "grade": self.grade,
            "runs": len(self.outcomes),
            "converged": n,
            "unconverged_seeds": [o.seed for o in self.unconverged],
            "refused": [{"seed": o.seed, "why": o.refusal} for o in self.refused],
        }
        if n == 0:
            return doc
        lo, hi = chi2_band(n)
        nees = self.nees()
        z = self.z_scores()
        worst = np.abs(z).max(axis=0)
        rms_error = np.sqrt(np.mean(self._stack()[0] ** 2, axis=0))
        over_reported, over_predicted = self.rms_over_reported(), self.rms_over_predicted()
        doc["nees"] = {
            "mean": float(nees.mean()),
            "band_99": [lo, hi],
            "in_band": bool(lo <= nees.mean() <= hi),
        }
        doc["parameters"] = {
            p.name: {
                "unit": p.unit,
                "predicted_sigma": _finite_or_none(self.predicted_sigma[i] / p.si_per_unit),
                "rms_error": float(rms_error[i] / p.si_per_unit),
                "rms_over_reported_sigma": float(over_reported[i]),
                "rms_over_predicted_sigma": _finite_or_none(over_predicted[i]),
                "mean_error_over_sigma": float(z[:, i].mean()),
                "worst_error_over_sigma": float(worst[i]),
            }
            for i, p in enumerate(P.PARAMETERS)
        }
        return doc

    def to_text(self) -> str:
        doc = self.to_json()
        lines = [
            f"verify {self.name}: {doc['runs']} runs, profile {self.profile.name} "
            f"({self.grade} errors), requirements {self.requirements.name}",
            f"converged {doc['converged']}, did not converge {len(doc['unconverged_seeds'])}, "
            f"refused {len(doc['refused'])}",
        ]
        lines += [f"  refused seed {r['seed']}: {r['why']}" for r in doc["refused"]]
        if "nees" not in doc:
            return "\n".join(lines)
        nees = doc["nees"]
        lo, hi = nees["band_99"]
        verdict = "honest" if nees["in_band"] else "NOT honest: the reported sigmas are wrong"
        lines.append(f"mean NEES {nees['mean']:.2f} (99 % band [{lo:.2f}, {hi:.2f}] for 21 dof): {verdict}")
        # Runs placed by hand at random have no analyser's prediction: its two columns would be
        # all "-", so they are left out.
        predicted = any(e["predicted_sigma"] is not None for e in doc["parameters"].values())
        if predicted:
            head = ("param", "unit", "analyze σ", "RMS error", "RMS/σ run", "RMS/σ pred")
            lines.append("{:>6} {:>8} {:>11} {:>11} {:>10} {:>10}".format(*head))
        else:
            lines.append("{:>6} {:>8} {:>11} {:>10}".format("param", "unit", "RMS error", "RMS/σ run"))
        for name, e in doc["parameters"].items():
            row = f"{name:>6} {e['unit']:>8} "
            if predicted:
                row += f"{_figure(e['predicted_sigma'], 11, '.4g')} "
            row += f"{e['rms_error']:11.4g} {e['rms_over_reported_sigma']:10.2f}"
            if predicted:
                row += f" {_figure(e['rms_over_predicted_sigma'], 10, '.2f')}"
            lines.append(row)
        return "\n".join(lines)


def _finite_or_none(x) -> float | None:
    """A figure for JSON: None where there is none (a by-hand run has no analyser's prediction)."""
    return float(x) if math.isfinite(float(x)) else None


def _figure(x: float | None, width: int, spec: str) -> str:
    return f"{'-':>{width}}" if x is None else f"{x:{width}{spec}}"


@dataclass(frozen=True)
class VerifyOptions:
    """How a Monte Carlo of runs is drawn and fitted: the defaults of ``seqdesign verify``.

    Attributes
    ----------
    runs : int
        How many runs (run ``i`` from seed ``seed + i``).
    seed : int
        Seed of run 0.
    tolerance_deg : float
        Each run's base mounting drawn within this box, deg.
    flip_error_deg : float
        Flips missing their angle by up to this much, deg.
    extras : OptionalTerms
        What the fit estimates beside the 21.
    requirements : Requirements
        The scale the fit judges observability in.
    workers : int
        Local processes.
    scheduler : str, optional
        A dask.distributed scheduler address (or client) instead (:func:`map_jobs`).
    """

    runs: int = 50
    seed: int = 0
    tolerance_deg: float = 3.0
    flip_error_deg: float = 0.5
    extras: OptionalTerms = NO_EXTRAS
    requirements: Requirements = PAPER
    workers: int = 1
    scheduler: Any = None


def verify(
    seq: Sequence | None,
    profile: NoiseProfile,
    options: VerifyOptions | None = None,
    *,
    config: SimConfig,
    predicted_sigma: np.ndarray,
    errors: ErrorModel | None = None,
    hand: HandShape | None = None,
    progress=None,
) -> Verification:
    """Simulate and calibrate ``options.runs`` runs of ``seq`` (run ``i`` from seed ``options.seed + i``).

    Parameters
    ----------
    seq, profile : Sequence, NoiseProfile
        What is played and the noise it is simulated and calibrated with.
    options : VerifyOptions, optional
        Runs, seed, mounting box, flip errors, extra terms, requirements, workers or scheduler
        (default: its defaults).
    config : SimConfig
        Site, gravity and sample rate of the simulated runs.
    predicted_sigma : ndarray, shape (21,)
        The analyser's sigma (SI) the runs are held against.
    errors : ErrorModel, optional
        Fixed errors of every run; default: drawn per run within the profile's grade.
    hand : HandShape, optional
        Runs placed by hand of this shape instead of ``seq`` (then None): each run draws its
        own poses, moves and noise; there is no analyser's prediction (``predicted_sigma`` nan).
    progress : callable, optional
        ``progress(done, runs)`` as runs finish (:func:`map_jobs`).

    Returns
    -------
    Verification
    """
    o = options or VerifyOptions()
    runs, seed, requirements = o.runs, o.seed, o.requirements
    grade = grade_of(profile)
    half = error_half_range(grade)
    jobs = [
        VerifyJob(
            seq,
            profile,
            config,
            errors,
            half,
            o.tolerance_deg,
            o.flip_error_deg,
            seed + i,
            o.extras,
            requirements,
            hand,
        )
        for i in range(runs)
    ]
    done = None if progress is None else (lambda n: progress(n, runs))
    outcomes = tuple(map_jobs(one_run, jobs, o.workers, o.scheduler, done=done))
    return Verification(seq, profile, requirements, grade, np.asarray(predicted_sigma, float), outcomes, hand)
