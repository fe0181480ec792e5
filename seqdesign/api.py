"""The library a notebook calls: every command of the CLI is one call here.

>>> from seqdesign import api as sd
>>> analysis = sd.analyze("paper-9pos", tolerance_deg=3.0)  # an Analysis       (seqdesign analyze)
>>> print(analysis.to_text())
>>> report = sd.design([2], options=sd.DesignOptions(beam_width=8), gimbal="cable-wrap")  # (seqdesign design)
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
from calib.sim.gimbal_run import SimOptions, simulate
from viz.record import record_run

from .analysis import Analysis, analyze, compare_text
from .positions import Positions, as_gimbal, show_positions as show
from .provenance import call_provenance
from .repeatability import compare_results
from .schedule import Schedule, export_schedule as export, read_schedule
from .search import (
    Constraints,
    DesignOptions,
    DesignReport,
    design_budgets,
    gimbal_constraints,
    parse_node,
)

__all__ = [
    "Analysis",
    "CalibrateOptions",
    "CalibrationResult",
    "Constraints",
    "DesignOptions",
    "DesignReport",
    "ErrorModel",
    "FittedProfile",
    "PARAMETERS",
    "Positions",
    "Schedule",
    "Sequence",
    "SimConfig",
    "SimOptions",
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
    options: DesignOptions | None = None,
    *,
    progress=None,
    gimbal: Gimbal | str | Path | None = None,
) -> DesignReport:
    """Design one sequence per time budget: what ``seqdesign design`` finds.

    ``sd.design([10], {"min_dwell_s": 10}, "mems", gimbal="cable-wrap")`` is
    ``seqdesign design --budget-min 10 --min-dwell-s 10 --gimbal cable-wrap --profile mems``;
    ``sd.design([2], options=sd.DesignOptions(beam_width=8))`` is ``--beam-width 8``.

    Parameters
    ----------
    budgets_min : iterable of float
        Total time budgets, minutes (one design each).
    constraints : Constraints or dict, optional
        What is fixed about the design, as a :class:`seqdesign.search.Constraints` (its
        ``budget_s`` is ignored) or a dict of some of its fields (the others its defaults,
        the CLI's): ``start`` and ``end`` where body X, Y, Z point (``"east,up,south"`` or a
        tuple), ``max_flips``, ``axes`` (``"XYZ"``), ``max_quarters``, ``rate_dps`` (with a
        gimbal and no rate: the gimbal's own), ``min_dwell_s``, ``max_dwell_s``, ``gimbal``.
    profile : NoiseProfile or str
        The noise the design is optimised for (``navigation``, ``mems``, a file).
    options : DesignOptions, optional
        Latitude, objective, tolerance, beam width, refinement, workers or scheduler,
        requirements and extra terms (:class:`seqdesign.search.DesignOptions`; default: its
        defaults, the CLI's).
    progress : callable, optional
        ``progress(budget_min, report)`` as the search advances.
    gimbal : Gimbal, str or Path, optional
        Only moves this gimbal plays (a file or a shipped name: ``cable-wrap``, ``slip-rings``);
        overrides the constraints' own.

    Returns
    -------
    DesignReport
        ``.rows[i].result.sequence`` each design; ``.to_text()``, ``.to_json()``,
        ``.save_design(row, path, provenance)``.
    """
    typed = isinstance(constraints, Constraints)
    fields = _fields(constraints) if isinstance(constraints, Constraints) else dict(constraints or {})
    for end in ("start", "end"):
        if isinstance(fields.get(end), str):
            fields[end] = parse_node(fields[end], end)
    if isinstance(fields.get("axes"), str):
        fields["axes"] = fields["axes"].upper()
    chosen = gimbal if gimbal is not None else fields.pop("gimbal", None)
    if chosen is not None:
        if not typed and "rate_dps" not in fields:
            fields["rate_dps"] = None  # the gimbal's own rate, as the CLI's default
        _, fields = gimbal_constraints(as_gimbal(chosen), fields)
    return design_budgets(budgets_min, fields, profile, options, progress=progress)


def _fields(c: Constraints) -> dict:
    """A Constraints' fields but the budget (the budgets are the call's)."""
    return {k: v for k, v in vars(c).items() if k != "budget_s"}
