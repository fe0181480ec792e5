"""``seqdesign correct``: apply a calibration to a log, ``calibrated = M (raw - b)`` per sensor.

The correction file is what ``calibrate --correction`` writes (or any file of
that format: see ``docs/by-hand.md``). The log is read as ``calibrate`` reads it
(a logger's columns, raw counts with their conversion, imu_tk's two files, a
sample counter); the output is a CSV of calibrated rates and specific force
in the tool's own run format (``imu-run/1``, CSV or NPZ by the suffix), which every
command reads back.

A correction with a fitted bias drift is applied as one bias (the calibrated log's
last rest's) unless ``--carry-drift`` asks for the drift, which is carried only over
the log it was fitted on.
"""

from __future__ import annotations

import click
import numpy as np

from . import options
from .tools import emit_json, guarded, info, refuse_overwrite, say_filled


@click.command(short_help="Apply a calibration (calibrated = M (raw - b)) to a log.")
@click.argument("run_path", metavar="LOG")
@options.file_path(
    "--correction", "correction_path", "Correction TOML (calibrate --correction writes it).", required=True
)
@click.option("-o", "--output", required=True, help="Calibrated log to write (imu-run/1, .csv or .npz).")
@click.option(
    "--carry-drift",
    is_flag=True,
    help="Carry the correction's fitted bias drift to each sample's time, b + d (t - t_last rest): only "
    "on the log it was calibrated from (default: the one bias, the last rest's).",
)
@options.fill_gaps
@options.log_site_and_reading
@options.as_json
@guarded
# over 8 parameters: a click command takes one parameter per option it declares
def correct(
    run_path,
    correction_path,
    output,
    carry_drift,
    allow_gaps,
    latitude,
    height,
    reading,
    as_json,
):
    """Apply the correction to every sample of LOG and write the calibrated log."""
    from calib.calibration.correction import (
        Correction,
        drift_carried_times,
        drift_note,
        raw_samples,
    )
    from calib.nav.strapdown import sample_intervals
    from calib.runlog import Run, read_run, write_run

    refuse_overwrite(
        {"-o": output},
        {
            "LOG": run_path,
            "--correction": correction_path,
            "--gyro-file": reading.gyro_file,
            "--conversion": reading.conversion,
        },
    )
    correction = Correction.load(correction_path)
    run = read_run(run_path, allow_gaps, latitude_deg=latitude, height_m=height, **reading.reader)
    say_filled(run, "before the correction")
    raw_gyro, raw_accel = raw_samples(run, correction, run_path)
    times = drift_carried_times(correction, run) if carry_drift else None
    note = None if carry_drift else drift_note(correction, run)
    if note:
        info(note)
    rate, force = correction.apply(raw_gyro, raw_accel, times)
    dt = sample_intervals(run.time_s)[:, None]
    # The calibrated log is in SI: the raw reading's keys (its conversion, its source format) go.
    meta = {k: v for k, v in run.meta.items() if not k.startswith(("conversion", "source_format"))}
    meta["calibrated_with"] = str(correction_path)
    origin = run.time_origin_s
    if origin:  # epoch stamps were re-based to their first: the absolute time is kept beside them
        meta["time_origin_s"] = repr(origin)
    write_run(Run(run.time_s, rate * dt, force * dt, meta, source=output, clock=run.clock), output)
    info(f"applied {correction_path} to {run.n_samples} samples of {run_path}")
    if run.clock is not None and run.clock.told:
        info(f"{output} keeps the stamps its rows were read at: read it again with --at-stamps")
    if origin:
        info(f"time_s counts from {origin:.6f} s, the log's first stamp (time_origin_s in {output})")
    doc = {
        "output": output,
        "samples": run.n_samples,
        "drift_carried": bool(carry_drift),
        "mean_rate_radps": np.mean(rate, axis=0).tolist(),
        "mean_specific_force_mps2": np.mean(force, axis=0).tolist(),
    }
    if as_json:
        emit_json(doc)
        return
    click.echo(f"wrote {output}")
