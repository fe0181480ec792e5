"""``seqdesign view``: write a rerun recording (.rrd) of a run and optionally open the viewer.

The command is a plain click command; ``seqdesign/cli.py`` registers it with
``main.add_command(view)``. The estimation work (motion, alignment,
navigations) is :func:`calib.fit.replay.review_run`; :mod:`viz` only logs what
it is given. rerun itself is imported only inside the command.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import click

from calib.errors import CalibError

from . import options
from .tools import guarded, info as _info, rerun_command

# Exit code of `view --spawn` when there is no display: the recording is written, the viewer
# is not opened (2 is kept for bad input, where nothing is written).
EXIT_NO_DISPLAY = 3


def display_available(environ=None, platform: str | None = None) -> bool:
    """Whether a desktop viewer can open a window: on Linux and other X11/Wayland systems
    that needs DISPLAY or WAYLAND_DISPLAY; macOS and Windows always have a display.
    """
    environ = os.environ if environ is None else environ
    platform = sys.platform if platform is None else platform
    if platform == "darwin" or platform.startswith(("win", "cygwin")):
        return True
    return bool(environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"))


def _beside(run_path: str, suffix: str) -> Path:
    p = Path(run_path)
    return p.with_name(p.stem + suffix)


def _check_output(path: Path) -> None:
    if path.suffix.lower() != ".rrd":
        raise CalibError(
            f"unknown recording format {path.suffix!r}", "-o/--output", "name the recording .rrd"
        )
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise CalibError(
            f"directory {str(directory)!r} does not exist",
            "-o/--output",
            "create it first or choose another path",
        )


def _load_sequence(run, explicit, profile):
    """``--sequence`` (must match the log), else the run's ``sequence`` key
    if it names a shipped sequence that matches the log, else None. The log's turns are
    judged with ``profile``'s noise, as ``calibrate`` judges them.
    """
    from calib.nav.strapdown import sample_intervals
    from calib.sequence.definition import load_sequence
    from calib.sequence.motion import check_sequence_matches, log_turns, sequence_motion

    name = explicit or run.sequence_name
    if not name:
        return None, None
    try:
        seq = load_sequence(name)
        dt = sample_intervals(run.time_s)
        check_sequence_matches(
            seq,
            log_turns(run.dtheta_rad, dt, profile.arw, run.source),
            sequence_motion(seq, run.time_s, dt),
            dt,
            run.source,
        )
    except CalibError as exc:
        if explicit:
            raise
        return None, f"the run names sequence {name!r} but it was not used: {exc.message}"
    return seq, None


def _load_result(run_path, explicit):
    """``--result``, else ``RUN.result.toml`` beside the run when it exists.

    A result whose provenance names a different run file (SHA-256) is refused
    when given explicitly and skipped with a warning when found by default.
    """
    from calib.calibration.result import CalibrationResult
    from calib.io.files import sha256_file

    path = Path(explicit) if explicit else _beside(run_path, ".result.toml")
    if not explicit and not path.exists():
        return None, None, None
    result = CalibrationResult.load(path)
    recorded = result.provenance.get("run_sha256")
    if recorded and recorded != sha256_file(run_path):
        message = f"result {str(path)!r} was computed from a different run (SHA-256 differs)"
        if explicit:
            raise CalibError(message, "--result", "give the result of this run, or recalibrate")
        return None, None, message + "; not shown"
    return result, path, None


@click.command(short_help="Write a rerun recording (.rrd) of a run; --spawn opens the viewer.")
@click.argument("run_path", metavar="RUN")
@click.option(
    "--sequence",
    help="Sequence the run followed (default: the run's 'sequence' key "
    "if it is a shipped sequence matching the log).",
)
@options.file_path(
    "--result", "result_path", "Calibration result (default: RUN.result.toml beside the run, if it exists)."
)
@options.file_path(
    "--truth", "truth_path", "Truth file of a simulated run (default: RUN.truth.toml, if it exists)."
)
@click.option("-o", "--output", help="Recording to write (default: RUN with .rrd).")
@click.option(
    "--spawn",
    is_flag=True,
    help="Open the recording in the rerun viewer. Without a "
    "display (Linux: neither DISPLAY nor WAYLAND_DISPLAY set) it says so in one line, "
    f"still writes the recording and exits with code {EXIT_NO_DISPLAY}: not 0, since the "
    "viewer asked for did not open; not 2, since the input was fine.",
)
@click.option("--allow-gaps", is_flag=True, help="Accept time gaps in the log.")
@options.log_reading
@options.latitude("Site latitude, deg, for a logger's file that does not carry latitude_deg.")
@options.height("Site height, m, for a logger's file that does not carry height_m.")
@click.option(
    "--profile",
    default=None,
    help="Noise profile the log's motion is judged with, as calibrate judges it (default: the "
    "result's, else the one the run names, else navigation).",
)
@options.as_json
@guarded
# over 8 parameters: a click command, whose options arrive one parameter each
def view(
    run_path,
    sequence,
    result_path,
    truth_path,
    output,
    spawn,
    allow_gaps,
    reading,
    latitude,
    height,
    profile,
    as_json,
):
    """Record RUN (CSV, CSV.GZ, NPZ or PSINS .imu) for the rerun viewer: the gimbal and IMU in 3D,
    raw gyro and accelerometer signals, navigation velocity errors before and
    after calibration, the positions and flips, and the result against its
    requirements (and against the truth of a simulated run).
    """
    from calib.runlog import read_run
    from calib.sim.truth import read_truth, truth_path_for

    out = Path(output) if output else _beside(run_path, ".rrd")
    _check_output(out)
    from calib.fit.replay import motion_profile, review_run

    from .reading import run_notes

    run = read_run(run_path, allow_gaps=allow_gaps, latitude_deg=latitude, height_m=height, **reading.reader)
    for note in run_notes(run, None)[1]:  # clipped stretches (gravity: the review uses the run's)
        _info(note)
    result, used_result, result_note = _load_result(run_path, result_path)
    noise = motion_profile(run, result, profile)
    seq, seq_note = _load_sequence(run, sequence, noise)
    if truth_path is None and truth_path_for(run_path).exists():
        truth_path = truth_path_for(run_path)
    truth = read_truth(truth_path) if truth_path else None
    for note in (seq_note, result_note):
        if note:
            _info(f"warning: {note}")
    try:
        import rerun  # noqa: F401  (a clear message if the optional viewer SDK is missing)
    except ImportError:
        raise CalibError("rerun-sdk is not installed", None, "pip install 'rerun-sdk>=0.41'") from None
    from viz.record import record_run

    review = review_run(run, result, profile=noise)
    summary = record_run(run, out, review, sequence=seq, result=result, truth=truth)
    no_display = spawn and not display_available()
    if no_display:
        _info(
            f"error: --spawn: no display to open the viewer on (DISPLAY and WAYLAND_DISPLAY "
            f"are unset); {out} is written: open it with '{rerun_command()} {out}' where there is a "
            f"display, or '{rerun_command()} --serve-web {out}' and a browser"
        )
    elif spawn:
        _spawn_viewer(out)
    doc = summary.to_dict()
    doc.update(
        {
            "run": str(run_path),
            "samples": run.n_samples,
            "sequence": seq.name if seq is not None else None,
            "result": str(used_result) if used_result else None,
            "truth": str(truth_path) if truth_path else None,
            "notes": doc["notes"] + [n for n in (seq_note, result_note) if n],
        }
    )
    doc["viewer"] = "no display" if no_display else ("spawned" if spawn else None)
    if as_json:
        click.echo(json.dumps(doc, indent=2, allow_nan=False))
    else:
        rows = sum(doc["entities"].values())
        size = out.stat().st_size / 1e6
        click.echo(
            f"wrote {out} ({len(doc['entities'])} entities, {rows} rows, {size:.1f} MB; "
            f"scene from {doc['scene_source']})"
        )
        if not spawn:
            click.echo(f"open it with: {rerun_command()} {out}")
    if no_display:
        sys.exit(EXIT_NO_DISPLAY)


def _spawn_viewer(path: Path) -> None:
    """Open the recording in a detached rerun viewer (``python -m rerun FILE``).

    The viewer reads the finished file, so the recording on disk is exactly
    what it shows. Failing to start the viewer is reported, not fatal: the
    file is already written.
    """
    try:
        subprocess.Popen(
            [sys.executable, "-m", "rerun", str(path)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            env=os.environ.copy(),
        )
    except OSError as exc:
        _info(f"warning: could not start the rerun viewer ({exc}); open {path} with 'rerun {path}'")
