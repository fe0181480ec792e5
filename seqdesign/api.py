"""The library a notebook calls: every command of the CLI is one call here.

>>> from seqdesign import api as sd
>>> run = sd.read_run("demo-out/run.npz")
>>> result = sd.calibrate(run, profile="navigation")       # a CalibrationResult
>>> big = sd.calibrate("long.npz", stream=True)            # the same, read chunk by chunk
>>> result.sigma_scale, result.converged, result.to_json()["worst"]
>>> analysis = sd.analyze("paper-9pos", tolerance_deg=3.0)  # an Analysis
>>> print(analysis.to_text())
>>> sd.record(run, "run.rrd", result=result)              # a rerun recording

Results know how to print themselves (``to_text``) and how to become the
``--json`` document of the matching command (``to_json``); the CLI does no
more than parse options, call these and print.
"""

from __future__ import annotations

from calib.calibration import calibrate
from calib.profiles import load_profile
from calib.requirements import load_requirements
from calib.result import CalibrationResult
from calib.review import review_run
from calib.runlog import read_run
from calib.sequence import load_sequence
from calib.sim import simulate
from viz.record import record_run

from .analysis import Analysis, analyze, compare_text
from .repeatability import compare_results
from .search import DesignReport
from .search import design_budgets as design

__all__ = [
    "Analysis",
    "CalibrationResult",
    "DesignReport",
    "analyze",
    "calibrate",
    "compare_results",
    "compare_text",
    "design",
    "load_profile",
    "load_requirements",
    "load_sequence",
    "read_run",
    "record",
    "simulate",
]


def record(run, path, result=None, sequence=None, truth=None):
    """Write a rerun recording of a run (what ``seqdesign view`` writes); returns its summary."""
    return record_run(run, path, review_run(run, result), sequence=sequence, result=result, truth=truth)
