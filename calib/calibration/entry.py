"""Calibrate a logged run: the one library call behind ``seqdesign calibrate``.

:func:`calibrate` takes one run source -- a :class:`calib.runlog.Run` in
memory or a log file, read whole or chunk by chunk (:mod:`calib.fit.chunked`,
:func:`reads_in_chunks`) -- and returns a :class:`calib.calibration.result.CalibrationResult`
that already carries the policy a user relies on, applied once for both
readings: the site gravity and where it came from, the convergence verdict,
the Birge check (sigmas inflated by ``sqrt(chi2/dof)`` when the residuals are
larger than the noise profile says), and, for a run that leaves directions
unobserved, which parameters are not estimable. A notebook, the Monte Carlo
and the CLI get the same sigmas from it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from calib.errors import CalibError
from calib.fit.chunked import fit_file, run_header
from calib.fit.estimator import fit_run
from calib.fit.options import FitOptions
from calib.fit.sanity import MAX_PLAUSIBLE_RATE, GyroUnitError, explain_gyro_unit
from calib.fit.solution import Fit
from calib.hand.calibrate import as_fit, fit_checked, summary_of
from calib.hand.fit_options import HAND_REQUIREMENTS
from calib.hand.setup import carried_by_hand
from calib.model import params as P
from calib.model.optional_terms import OptionalTerms, load_optional_terms
from calib.model.requirements import PAPER, Requirements, load_requirements
from calib.nav.site import Site, site_of
from calib.nav.strapdown import sample_intervals
from calib.noise.profiles import NoiseProfile, load_profile
from calib.runlog import read_run
from calib.sequence.motion import check_sequence_matches, log_turns, sequence_motion

from .result import CalibrationResult

# chi2/dof above this says the profile understates the noise: sigmas are inflated by
# sqrt(chi2/dof). 1.2 is far outside the spread of chi2/dof for the thousands of degrees
# of freedom of a calibration run (its standard deviation is sqrt(2/dof) < 0.05).
BIRGE_LIMIT = 1.2

# A log file larger than this is read chunk by chunk unless told otherwise: held whole, its
# samples and the navigation's temporaries take about ten times the file's size in memory.
STREAM_BYTES = 256 << 20
CHUNK_KINDS = (".npz", ".csv")  # what the chunked reader reads (imu-run/1 CSV, numpy NPZ)


@dataclass(frozen=True)
class CalibrateOptions:
    """What else :func:`calib.calibration.entry.calibrate` is told about a run and its result.

    Parameters
    ----------
    partial : bool
        Fit the estimable part of a run that leaves directions unobserved,
        reporting the rest as not estimable, instead of refusing it.
    require_convergence : bool
        Refuse a fit that did not converge (the CLI writes no result then).
    gravity_mps2 : float, optional
        Surveyed gravity at the site; wins over the log's and over the
        normal-gravity model (a gravity error of dg/g is a common
        accelerometer scale-factor error no sequence can separate).
    allow_gaps : bool
        Reading a file whole: repair dropped and duplicated samples.
    latitude_deg, height_m : float, optional
        Reading a file whole: the site of a logger's CSV that lacks it.
    provenance : dict
        Stored in the result as it is.
    without : str, optional
        A run placed by hand: optional terms never fitted (``"g-sensitivity"``).
    fix_units : bool
        A run placed by hand whose labels its data contradict (an accelerometer in g read
        as m/s^2, deg/s read as rad/s, swapped or flipped axes, a wrong rate;
        :mod:`calib.hand.setup`) is put right and fitted, saying so, instead of refused.
    """

    partial: bool = False
    require_convergence: bool = True
    gravity_mps2: float | None = None
    allow_gaps: bool = False
    latitude_deg: float | None = None
    height_m: float | None = None
    provenance: dict = field(default_factory=dict)
    without: str | None = None
    fix_units: bool = False

    @property
    def reading(self) -> dict:
        """The in-memory reader's options (:func:`calib.runlog.read_run`)."""
        return dict(allow_gaps=self.allow_gaps, latitude_deg=self.latitude_deg, height_m=self.height_m)


CALIBRATE = CalibrateOptions()  # the defaults


def reads_in_chunks(path, stream: bool | None = None, **reading) -> bool:
    """Whether :func:`calibrate` reads the log at ``path`` chunk by chunk.

    ``stream`` True or False decides; None (the default): an ``.npz`` or
    ``.csv`` log over :data:`STREAM_BYTES` is read in chunks when none of the
    in-memory reader's options (``allow_gaps``, ``latitude_deg``,
    ``height_m``) is set. Asked to stream what the chunked reader cannot
    read, refuses in one line (:func:`check_streamable`).
    """
    if stream is None:
        p = Path(path)
        return (
            p.suffix.lower() in CHUNK_KINDS
            and not any(v not in (None, False) for v in reading.values())
            and p.is_file()
            and p.stat().st_size > STREAM_BYTES
        )
    if stream:
        check_streamable(path, **reading)
    return bool(stream)


def check_streamable(path, allow_gaps: bool = False, latitude_deg=None, height_m=None) -> None:
    """Refuse what the chunked reader cannot do in bounded memory, naming why."""
    where = str(path)
    if Path(path).suffix.lower() not in CHUNK_KINDS:
        raise CalibError(
            f"the chunked reader reads .npz and imu-run/1 .csv logs, not {''.join(Path(path).suffixes)!r}",
            where,
            "read it whole (stream=False; the CLI without --stream): gzip, PSINS and a logger's "
            "columns are read whole",
        )
    if allow_gaps:
        raise CalibError(
            "allow_gaps (the CLI's --allow-gaps) cannot be read chunk by chunk: repairing gaps "
            "fits the whole time column",
            where,
            "read it whole (stream=False; the CLI without --stream)",
        )
    if latitude_deg is not None or height_m is not None:
        raise CalibError(
            "latitude_deg/height_m (the CLI's --latitude/--height) complete a logger's CSV, "
            "which only the in-memory reader reads",
            where,
            "read it whole (stream=False; the CLI without --stream), or write latitude_deg and "
            "height_m in the log",
        )
    if not Path(path).is_file():
        raise CalibError("no such file", where, "check the path")


def calibrate(
    source,
    profile: NoiseProfile | str = "navigation",
    *,
    by_hand: bool = False,
    requirements=None,
    extras: OptionalTerms | str | None = None,
    sequence=None,
    stream: bool | None = None,
    options: CalibrateOptions = CALIBRATE,
) -> CalibrationResult:
    """Fit the 21 parameters (and any optional terms) of a run log.

    The choices a notebook makes most are keywords; the rest is one
    :class:`calib.calibration.entry.CalibrateOptions` (``options=CalibrateOptions(partial=True)``).

    Parameters
    ----------
    source : calib.runlog.Run or path
        The log in memory (:func:`calib.runlog.read_run`, or
        :func:`calib.sim.gimbal_run.simulate`), or its file.
    profile : NoiseProfile or str
        Weights the fit and scales the sigmas.
    by_hand : bool
        The run was placed by hand (no gimbal, no sequence): fitted from its
        rests and the moves between them (:mod:`calib.hand.joint_fit`); read whole.
        Its optional term (the gyro g-sensitivity) is fitted when the data need
        it (:func:`calib.hand.calibrate.hand_fit_of`) unless ``extras`` or ``options.without``
        names it.
    requirements : Requirements or str, optional
        What the ratios are judged against (default: the paper's; ``mems`` for a run placed by hand).
    extras : OptionalTerms or str, optional
        Optional terms to fit beside the 21 (``"lever-arm,k2"``, ``"all"``).
    sequence : calib.sequence.definition.Sequence, optional
        The sequence the run followed: its flips mark where the log turns
        (refused if they are not where the gyros turn). Default: detected.
    stream : bool, optional
        For a file: read it chunk by chunk (True), whole (False), or by
        :func:`reads_in_chunks`'s rule (None). Both readings fit the same
        samples with the same estimator.
    options : CalibrateOptions
        The rest: ``partial``, ``require_convergence``, the surveyed ``gravity_mps2``,
        the whole reader's ``allow_gaps``, ``latitude_deg`` and ``height_m``, the
        ``provenance`` stored, and a hand run's ``without`` and ``fix_units``.

    Returns
    -------
    CalibrationResult
        With the Birge-checked sigmas, the correlation of the 21, the site
        gravity and the fit's health.
    """
    prof, extras = load_profile(profile), load_optional_terms(extras, by_hand=by_hand)
    # A unit calibrated by hand is a MEMS unit: judged by the paper's navigation-grade requirements,
    # every sigma would be "weak" (beyond 1000 requirements) and nothing estimable.
    req = load_requirements(requirements if requirements is not None or not by_hand else HAND_REQUIREMENTS)
    if by_hand:
        return _by_hand(source, prof, extras, req, sequence, stream, options)
    if options.without:
        raise CalibError(
            "--without chooses the optional terms of a run placed by hand",
            str(getattr(source, "source", source)),
            "leave it out (a gimbal run fits only the terms --with names), or add --by-hand",
        )
    fit_options = FitOptions(extras=extras, partial=options.partial, requirements=req)
    provenance, gravity_mps2 = options.provenance, options.gravity_mps2
    if isinstance(source, (str, os.PathLike)):
        reading: dict[str, Any] = options.reading
        if reads_in_chunks(source, stream, **reading):
            site = site_of(run_header(source), gravity_mps2)
            fit, where = fit_file(source, site, prof, sequence, options=fit_options), str(source)
            return _checked_result(fit, where, options.require_convergence, prof, site, provenance, req)

        source = read_run(source, **reading)
    elif stream:
        raise ValueError("a run in memory is calibrated in memory: stream applies to a file")
    site = site_of(source, gravity_mps2)
    fit = _fit_in_memory(source, site, prof, sequence, fit_options)
    provenance = {**provenance, "samples": samples_fingerprint(source)}
    return _checked_result(fit, source.source, options.require_convergence, prof, site, provenance, req)


def _fit_in_memory(run, site: Site, profile: NoiseProfile, sequence, options: FitOptions) -> Fit:
    """The estimator on a run held whole; a sequence's flips mark where it turns.

    A run whose fast turns carry the unit (:func:`calib.hand.setup.carried_by_hand`) was turned
    by hand: the gimbal's model (flips about the IMU's centre, long dwells) does not hold, and
    it is refused naming ``--by-hand``.
    """
    if run.guessed is not None:  # the gimbal fit integrates every sample: a guess is no measurement
        first = float(run.time_s[int(np.flatnonzero(run.guessed)[0])])
        raise CalibError(
            f"{int(run.guessed.sum())} sample(s) lost while the IMU turns (first at t = {first:.6g} s) "
            "were put in as a guess, which the gimbal fit would integrate",
            run.source,
            "read the log without guessing turns (a hand fit's reading), repair it, or record the run again",
        )
    if sequence is None:
        carried = carried_by_hand(run)
        if carried is not None:
            raise CalibError(
                carried,
                run.source,
                "calibrate it as a run placed by hand: add --by-hand (and --profile mems for a MEMS unit)",
            )
    moving = None
    if sequence is not None:
        dt = sample_intervals(run.time_s)
        moving = sequence_motion(sequence, run.time_s, dt)
        check_sequence_matches(
            sequence, log_turns(run.dtheta_rad, dt, profile.arw, run.source), moving, dt, run.source
        )
    try:
        options = replace(options, max_rate_rad_s=rate_limit(run))
        return fit_run(run, site, profile, moving=moving, sequence=sequence, options=options)
    except GyroUnitError as exc:  # told in the terms of the file's gyro columns (rates, not dtheta)
        raise explain_gyro_unit(exc, run.gyro_columns) from None


def _by_hand(
    source, prof, extras: OptionalTerms, req: Requirements, sequence, stream, options: CalibrateOptions
) -> CalibrationResult:
    """A run placed by hand, read whole: its fit, checked as a gimbal run's.

    The optional terms are forced in by ``extras`` and out by ``options.without``;
    ``options.fix_units`` puts right the setup mistakes the data show (``--fix-units``).
    """
    terms = (extras, tuple(g for g in (options.without or "").split(",") if g))
    if sequence is not None:
        raise CalibError(
            "a run placed by hand follows no sequence file",
            str(getattr(source, "source", source)),
            "leave out --sequence, or calibrate without --by-hand",
        )
    if isinstance(source, (str, os.PathLike)):
        if stream:
            raise CalibError("a run placed by hand is read whole", str(source), "leave out --stream")
        source = read_run(source, **options.reading)
    site = site_of(source, options.gravity_mps2)
    hand, extras, choices, source, notes = fit_checked(
        source, site, prof, terms, options.partial, req, options.fix_units
    )
    fit = as_fit(hand, extras)
    provenance = {**options.provenance, "samples": samples_fingerprint(source)}
    result = _checked_result(fit, source.source, options.require_convergence, prof, site, provenance, req)
    return replace(result, by_hand=summary_of(hand, source, choices, tuple(notes)))


def rate_limit(run) -> float:
    """The fastest plausible turn of ``run``, rad/s (:func:`calib.fit.sanity.check_rates`).

    A gimbal's (``MAX_PLAUSIBLE_RATE``) for a run in physical units; for one
    read from raw counts, at least the range of its gyro (``run.conversion``):
    a hand turns it that fast, and a sample within the range is no unit error.
    """
    conversion = getattr(run, "conversion", None)
    if conversion is None:
        return MAX_PLAUSIBLE_RATE
    return max(MAX_PLAUSIBLE_RATE, conversion.max_rate_rad_s)


def samples_fingerprint(run) -> str:
    """What identifies a log's samples whatever its time stamps: their count, mean rate and force.

    The means are ratios of the increments' sums to the time's, in which the period
    cancels: the same samples read with uniform, float or epoch-ms stamps give the same
    figures, and ``compare`` knows two results as fits of one recording.
    """
    T = float(run.time_s[-1] - run.time_s[0]) * len(run.time_s) / max(len(run.time_s) - 1, 1)
    w = run.dtheta_rad.sum(axis=0) / T
    f = run.dv_mps.sum(axis=0) / T
    return (
        f"n={len(run.time_s)} w=" + ",".join(f"{x:.7e}" for x in w) + " f=" + ",".join(f"{x:.7e}" for x in f)
    )


def _checked_result(fit: Fit, where: str, require_convergence: bool, profile, site, provenance, req):
    """The convergence refusal, then :func:`result_from_fit`."""
    if require_convergence and not fit.converged:
        raise CalibError(
            f"the fit did not converge in {fit.iterations} iterations (last step "
            f"{fit.history[-1]['max_step_sigma']:.3g} sigma)"
            + (f": {fit.history[-1]['why_not_converged']}" if "why_not_converged" in fit.history[-1] else ""),
            where,
            "no result written; check the run and the noise profile",
        )
    return result_from_fit(fit, profile, site, provenance or {}, req)


def result_from_fit(
    fit: Fit,
    profile: NoiseProfile,
    site: Site,
    provenance: dict,
    requirements: Requirements = PAPER,
) -> CalibrationResult:
    """The result a user sees: sigmas Birge-checked, the 21's correlation, what is estimable."""
    scale = math.sqrt(fit.chi2_per_dof) if fit.chi2_per_dof > BIRGE_LIMIT else 1.0
    estimable = fit.estimable if fit.estimable is not None else np.ones(P.N_PARAMS + fit.extras.n, dtype=bool)
    names = P.NAMES + fit.extras.names
    return CalibrationResult(
        values=fit.values,
        sigma=fit.sigma * scale,
        C_b_n0=fit.C_b_n0,
        converged=fit.converged,
        iterations=fit.iterations,
        residual_rms_mps=fit.residual_rms_mps,
        profile=profile.name,
        chi2_per_dof=fit.chi2_per_dof,
        correlation=fit.correlation[: P.N_PARAMS, : P.N_PARAMS],
        provenance=dict(provenance),
        extras=fit.extras,
        extra_values=fit.extra_values,
        extra_sigma=fit.extra_sigma * scale,
        sigma_scale=scale,
        not_estimable=tuple(n for n, e in zip(names, estimable, strict=True) if not e),
        null_directions=tuple(fit.null_directions),
        n_observations=fit.n_observations,
        gravity_mps2=site.gravity_mps2,
        gravity_source=site.gravity_source,
        requirements=requirements,
        caveats=_caveats(fit),
    )


def _caveats(fit: Fit) -> tuple:
    """What the fit's model does not prove for this run: a heading held undetermined."""
    sigma = fit.history[-1].get("heading_held_sigma_deg") if fit.history else None
    if sigma is None:
        return ()
    return (
        f"the run does not determine the heading (sigma {sigma:.0f} deg: the gyro's bias instability "
        "buries the Earth's horizontal rate); it cycled and was held, the 21 fitted given it; their "
        "sigmas carry its linearised uncertainty (docs/grades.md)",
    )
