"""What a command says about a run read by hand's options: the conversion's gravity, clipping.

``calibrate`` and ``view`` read a run with ``--gyro-file``, ``--conversion`` and
``--sample-rate-hz`` (:class:`seqdesign.cli.options.LogReading`, :func:`calib.runlog.read_run`);
these are the lines they print about it, and the gravity a conversion file states when the user
gives none.
"""

from __future__ import annotations

from calib.runlog import Run
from calib.runlog.clipping import describe_clipping


def run_notes(run: Run, gravity_mps2: float | None) -> tuple[float | None, list[str]]:
    """The gravity to use and the lines to print about ``run``.

    Without ``--gravity`` (``gravity_mps2`` None) and without a ``gravity_mps2``
    in the run, a conversion file's stated local gravity is used, and said.
    Each clipped stretch is named (:func:`calib.runlog.clipping.describe_clipping`).
    """
    notes = [run.meta["streams"]] if "streams" in run.meta else []  # two files on two clocks
    if gravity_mps2 is None and run.gravity_mps2 is None and run.conversion is not None:
        stated = run.conversion.gravity_mps2
        if stated is not None:
            gravity_mps2 = stated
            notes.append(
                f"gravity: {stated:.6g} m/s^2, the local gravity the conversion file "
                f"{run.conversion.source} states (give --gravity to override)"
            )
    notes += [f"warning: {line}" for line in describe_clipping(run)]
    return gravity_mps2, notes
