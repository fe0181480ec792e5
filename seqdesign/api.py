"""The library a notebook calls: every command of the CLI is one call here.

>>> from seqdesign import api as sd
>>> analysis = sd.analyze("paper-9pos", tolerance_deg=3.0)  # an Analysis       (seqdesign analyze)
>>> print(analysis.to_text())
>>> report = sd.design([2], beam_width=8, gimbal="cable-wrap")  # a DesignReport (seqdesign design)
>>> seq = report.rows[0].result.sequence
>>> shown = sd.show(seq, gimbal="cable-wrap")              # rest positions     (seqdesign show)
>>> schedule = sd.export(seq, gimbal="cable-wrap")         # encoder commands   (seqdesign export)
>>> schedule.save("commands.csv")
>>> run, truth = sd.simulate(seq, sd.SimConfig(latitude_rad=0.7), sd.ErrorModel.from_table2(),
...                          sd.load_profile("navigation"))   # a run and its truth (seqdesign simulate)
>>> run = sd.read_run("demo-out/run.npz")
>>> result = sd.calibrate(run, profile="navigation")       # a CalibrationResult (seqdesign calibrate)
>>> big = sd.calibrate("long.npz", stream=True)            # the same, read chunk by chunk
>>> surveyed = sd.calibrate(run, options=sd.CalibrateOptions(gravity_mps2=9.80665))  # the rarer choices
>>> sd.record(run, "run.rrd", result=result)              # a rerun recording  (seqdesign view)
>>> fitted = sd.profile_fit("static.csv", height_m=1100)   # a FittedProfile    (seqdesign profile fit)
>>> fitted.save("myimu.toml")

Results know how to print themselves (``to_text``) and how to become the
``--json`` document of the matching command (``to_json``); the CLI does no
more than parse options, call these and print.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from calib.allan.profile_fit import METHOD, FittedProfile, fit_log
from calib.calibration.entry import CalibrateOptions, calibrate
from calib.calibration.result import CalibrationResult
from calib.fit.replay import review_run
from calib.gimbal.description import Gimbal
from calib.model.error_model import ErrorModel
from calib.model.params import PARAMETERS
from calib.model.requirements import load_requirements
from calib.noise.profiles import NoiseProfile, load_profile
from calib.runlog import read_run
from calib.sequence.definition import Sequence, load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import simulate
from viz.record import record_run

from .analysis import Analysis, analyze, compare_text
from .positions import Positions, as_gimbal, show_positions as show
from .provenance import call_provenance
from .repeatability import compare_results
from .schedule import Schedule, export_schedule as export, read_schedule
from .search import Constraints, DesignReport, design_budgets, gimbal_constraints, parse_node

__all__ = [
    "Analysis",
    "CalibrateOptions",
    "CalibrationResult",
    "Constraints",
    "DesignReport",
    "ErrorModel",
    "FittedProfile",
    "PARAMETERS",
    "Positions",
    "Schedule",
    "Sequence",
    "SimConfig",
    "analyze",
    "calibrate",
    "compare_results",
    "compare_text",
    "design",
    "export",
    "load_profile",
    "load_requirements",
    "load_sequence",
    "profile_fit",
    "read_run",
    "read_schedule",
    "record",
    "show",
    "simulate",
]


def record(run, path, result=None, sequence=None, truth=None):
    """Write a rerun recording of a run (what ``seqdesign view`` writes); returns its summary."""
    return record_run(run, path, review_run(run, result), sequence=sequence, result=result, truth=truth)


def profile_fit(
    path: str | Path,
    latitude_deg: float | None = None,
    height_m: float | None = None,
    name: str | None = None,
    columns: str | dict | None = None,
) -> FittedProfile:
    """Fit a noise profile to a static log: what ``seqdesign profile fit`` writes.

    Parameters
    ----------
    path : str or Path
        The static log (``.csv``, ``.csv.gz``, ``.npz`` or PSINS ``.imu``; docs/logs-columns.md).
    latitude_deg : float, optional
        Site latitude, deg, when the log lacks it.
    height_m : float, optional
        Site height, m, when the log lacks it; without either, 0 m (with a warning): it moves
        only the accelerometer bias along the vertical, by 0.31 ug per m.
    name : str, optional
        The profile's name; default: the log's file name without its suffixes.
    columns : str or dict, optional
        The file's column names mapped to ours (``"t=time_ms,gx=gyro_x_dps,..."``), as
        :func:`calib.runlog.read_run` takes them (docs/logs-columns.md).

    Returns
    -------
    FittedProfile
        ``.to_text()`` the table, ``.to_json()`` the figures of ``--json``, ``.profile`` the
        profile the other calls take, ``.save("myimu.toml", plot="myimu.png")`` the files.
    """
    call = f"seqdesign.api.profile_fit({str(path)!r}, latitude_deg={latitude_deg}, height_m={height_m})"
    prov = call_provenance(call, {"log": path}, method=METHOD)
    fitted = fit_log(
        path, name or Path(path).name.split(".")[0], prov, latitude_deg, height_m, columns=columns
    )
    if fitted.height_assumed:
        warnings.warn("the log gives no height and height_m is not given: using 0 m", stacklevel=2)
    return fitted


def design(
    budgets_min,
    constraints: Constraints | dict | None = None,
    profile: NoiseProfile | str = "navigation",
    *,
    latitude_deg: float = 40.0,
    objective: str = "worst",
    tolerance_deg: float = 3.0,
    beam_width: int = 200,
    refine: bool = True,
    workers: int = 1,
    scheduler: str | None = None,
    progress=None,
    requirements=None,
    extras=None,
    start: str | tuple | None = None,
    end: str | tuple | None = None,
    max_flips: int | None = None,
    axes: str | None = None,
    max_quarters: int | None = None,
    rate_dps: float | None = None,
    min_dwell_s: float | None = None,
    max_dwell_s: float | None = None,
    gimbal: Gimbal | str | Path | None = None,
) -> DesignReport:
    """Design one sequence per time budget: what ``seqdesign design`` finds.

    ``sd.design([10], min_dwell_s=10, gimbal="cable-wrap", profile="mems")`` is
    ``seqdesign design --budget-min 10 --min-dwell-s 10 --gimbal cable-wrap --profile mems``.

    Parameters
    ----------
    budgets_min : iterable of float
        Total time budgets, minutes (one design each).
    constraints : Constraints or dict, optional
        What is fixed about the design, as a :class:`seqdesign.search.Constraints` (its
        ``budget_s`` is ignored) or a dict of its fields; the keywords below override it.
    profile : NoiseProfile or str
        The noise the design is optimised for (``navigation``, ``mems``, a file).
    latitude_deg : float
        Site latitude, deg.
    objective : str
        ``worst`` (worst 3 sigma/requirement), or ``D``, ``A``, ``E``-optimal.
    tolerance_deg : float
        Mounting box half-width, deg; designs are scored at its worst case.
    beam_width : int
        Candidates kept per depth of the beam search (fewer: faster, perhaps worse).
    refine : bool
        Refine the winner's dwells with IPOPT.
    workers, scheduler : int, str (optional)
        Local processes; or a dask.distributed scheduler address.
    progress : callable, optional
        ``progress(budget_min, message, steps)`` as the search advances.
    requirements : Requirements or str, optional
        The objective's requirements (default: the paper's).
    extras : Extras or str, optional
        Terms fitted beside the 21: ``lever-arm,k2,time-offset`` or ``all``.
    start, end : str or tuple of str, optional
        Where body X, Y, Z point at the start (default ``"east,up,south"``) and, if given,
        at the end.
    max_flips : int, optional
        Most moves (default 60; the budget ends most walks sooner).
    axes : str, optional
        Body axes the gimbal may turn about (default ``"XYZ"``).
    max_quarters : int, optional
        Longest move in quarter turns (default 5).
    rate_dps : float, optional
        Rotation rate, deg/s (default 10, or the gimbal's own rate with ``gimbal``).
    min_dwell_s, max_dwell_s : float, optional
        Shortest and longest rest, s (default 10 and 300).
    gimbal : Gimbal, str or Path, optional
        Only moves this gimbal plays (a file or a shipped name: ``cable-wrap``, ``slip-rings``).

    Returns
    -------
    DesignReport
        ``.rows[i].result.sequence`` each design; ``.to_text()``, ``.to_json()``,
        ``.save_design(row, path, provenance)``.
    """
    base = dict(constraints or {}) if not isinstance(constraints, Constraints) else _fields(constraints)
    given = {
        "start": None if start is None else parse_node(start, "start") if isinstance(start, str) else start,
        "end": None if end is None else parse_node(end, "end") if isinstance(end, str) else end,
        "max_flips": max_flips,
        "axes": None if axes is None else axes.upper(),
        "max_quarters": max_quarters,
        "rate_dps": rate_dps,
        "min_dwell_s": min_dwell_s,
        "max_dwell_s": max_dwell_s,
    }
    fields = base | {k: v for k, v in given.items() if v is not None}
    chosen = gimbal if gimbal is not None else fields.pop("gimbal", None)
    if chosen is not None:
        if rate_dps is None and not isinstance(constraints, Constraints) and "rate_dps" not in base:
            fields["rate_dps"] = None  # the gimbal's own rate, as the CLI's default
        _, fields = gimbal_constraints(as_gimbal(chosen), fields)
    return design_budgets(
        budgets_min,
        fields,
        profile,
        latitude_deg=latitude_deg,
        objective=objective,
        tolerance_deg=tolerance_deg,
        beam_width=beam_width,
        refine=refine,
        workers=workers,
        scheduler=scheduler,
        progress=progress,
        requirements=requirements,
        extras=extras,
    )


def _fields(c: Constraints) -> dict:
    """A Constraints' fields but the budget (the budgets are the call's)."""
    return {k: v for k, v in vars(c).items() if k != "budget_s"}
