"""``seqdesign score``: how well calibrations hold on a recording's own still poses.

A calibration is best judged on poses it was not fitted on: a second recording of the
unit (another power-up, other poses) or a part held out. Given a log turned by hand
between still poses and one or more corrections (``calibrate --correction`` writes one),
the command finds the log's rests with the profile's noise and scores each correction,
and the log as read, by what physics fixes whatever the convention
(:mod:`calib.peers.scores`):

* ``|f|`` at every rest is local gravity: the spread of the calibrated magnitude over the
  rests is the accelerometer's error, blind to any rotation of the frame;
* the gravity direction at each rest carried by the calibrated gyro through the move to the
  next rest against the one measured there: the gyro's error over each move.
"""

from __future__ import annotations

import math
from pathlib import Path

import click

from . import options
from .tools import emit_json, guarded, info, say_filled

MIN_RESTS = 3  # a spread over two rests says little, and pose to pose needs a move between two


@click.command(short_help="Score calibrations on a recording's still poses (|f| spread, pose to pose).")
@click.argument("run_path", metavar="LOG")
@options.file_path(
    "--correction",
    "correction_paths",
    "A calibration: ours (calibrate --correction's TOML), imucal's result (.json) or imu_tk's "
    "result text; repeat to score several side by side.",
    required=True,
    multiple=True,
)
@click.option(
    "--profile",
    default="mems",
    show_default=True,
    help="Noise profile whose white noise finds the rests: built-in name or TOML file.",
)
@options.fill_gaps
@options.log_site_and_reading
@options.as_json
@guarded
# over 8 parameters: a click command takes one parameter per option it declares
def score(run_path, correction_paths, profile, allow_gaps, latitude, height, reading, as_json):
    """Score each correction (and the log as read) on the rests and moves of LOG."""
    import numpy as np

    from calib.calibration.correction import Correction, SensorCorrection, raw_samples
    from calib.errors import CalibError
    from calib.hand.rests import find_rests
    from calib.nav.strapdown import sample_intervals
    from calib.noise.profiles import load_profile
    from calib.peers.published import read_correction
    from calib.peers.scores import RestSpans, score as score_of
    from calib.runlog import read_run

    prof = load_profile(profile)
    corrections = [read_correction(path) for path in correction_paths]
    run = read_run(run_path, allow_gaps, latitude_deg=latitude, height_m=height, **reading.reader)
    say_filled(run, "before the scores")
    dt = sample_intervals(run.time_s)
    rests = find_rests(run.dtheta_rad, run.dv_mps, dt, prof.arw, prof.vrw, run_path)
    if len(rests.start) < MIN_RESTS:
        raise CalibError(
            f"found {len(rests.start)} still pose(s) with the {prof.name} profile's noise: "
            "too few to score on",
            run_path,
            f"give a log turned between {MIN_RESTS} or more still poses (held 3 s or more each), "
            "or the unit's own --profile",
        )
    clipped = None if run.clipped is None else run.clipped.any(axis=1)
    spans = RestSpans(run.time_s, rests.start, rests.end, clipped, float(run.meta.get("latitude_deg", 0.0)))
    none = np.full((3, 3), np.nan), np.full(3, np.nan)
    as_read = Correction(
        SensorCorrection(np.eye(3), np.zeros(3), *none, "rad/s"),
        SensorCorrection(np.eye(3), np.zeros(3), *none, "m/s^2"),
        source="as read",
    )
    rows = [("as read", score_of(as_read, run.dtheta_rad / dt[:, None], run.dv_mps / dt[:, None], spans))]
    for path, correction in zip(correction_paths, corrections, strict=True):
        rows.append((path, score_of(correction, *raw_samples(run, correction, path), spans)))
    moves = rows[0][1].poses.used
    left_out = " (a move with a clipped sample left out)" if not moves.all() else ""
    info(
        f"scoring on {run_path}: {len(rests.start)} rests, {int(moves.sum())} of {len(moves)} moves"
        f"{left_out}; rests found with the {prof.name} profile's noise"
    )
    doc = {
        "log": run_path,
        "rests": len(rests.start),
        "moves_used": int(moves.sum()),
        "moves": len(moves),
        "earth_turn_left_out_deg": float(rows[0][1].poses.earth_bound_deg),
        "scores": [_figures(name, s) for name, s in rows],
    }
    if as_json:
        emit_json(doc)
        return
    click.echo(
        f"{'correction':<40}{'mean |f| m/s^2':>16}{'std mm/s^2':>12}{'max-min mm/s^2':>16}"
        f"{'pose RMS deg':>14}{'max deg':>9}"
    )
    for entry in doc["scores"]:
        click.echo(
            f"{_short(entry['correction']):<40}{entry['mean_mps2']:16.5f}{1e3 * entry['std_mps2']:12.2f}"
            f"{1e3 * entry['range_mps2']:16.2f}{entry['pose_rms_deg']:14.3f}{entry['pose_max_deg']:9.3f}"
        )
    click.echo(
        "|f| over the rests' means (local gravity at every pose); pose to pose: gravity carried by the gyro "
        f"from rest to rest against the next rest's (the Earth's turn, up to "
        f"{doc['earth_turn_left_out_deg']:.4f} deg a move, left out)"
    )


def _short(path: str, width: int = 38) -> str:
    """A correction's file name (not its folders), its end kept when too long for the column."""
    name = Path(path).name
    return name if len(name) <= width else "..." + name[-(width - 3) :]


def _figures(name: str, s) -> dict:
    return {
        "correction": name,
        "mean_mps2": float(s.spread.mean),
        "std_mps2": float(s.spread.std),
        "range_mps2": float(s.spread.range),
        "pose_rms_deg": float(s.poses.rms_deg),
        "pose_max_deg": float(s.poses.max_deg),
        "pose_deg": [float(a) if math.isfinite(a) else None for a in s.poses.angle_deg],
    }
