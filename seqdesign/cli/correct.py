"""``seqdesign correct``: apply a calibration to a log, ``calibrated = M (raw - b)`` per sensor.

The correction file is what ``calibrate --correction`` writes (or any file of
that format: see ``docs/by-hand.md``). The log is read as ``calibrate`` reads it
(a logger's columns, raw counts with their conversion, imu_tk's two files, a
sample counter); the output is a CSV of calibrated rates and specific force
in the tool's own run format (``imu-run/1``, CSV or NPZ by the suffix), which every
command reads back.
"""

from __future__ import annotations

import click

from . import options
from .tools import emit_json, guarded, info, refuse_overwrite


@click.command(short_help="Apply a calibration (calibrated = M (raw - b)) to a log.")
@click.argument("run_path", metavar="LOG")
@options.file_path(
    "--correction", "correction_path", "Correction TOML (calibrate --correction writes it).", required=True
)
@click.option("-o", "--output", required=True, help="Calibrated log to write (imu-run/1, .csv or .npz).")
@options.log_site_and_reading
@options.as_json
@guarded
# over 8 parameters: a click command takes one parameter per option it declares
def correct(
    run_path,
    correction_path,
    output,
    latitude,
    height,
    reading,
    as_json,
):
    """Apply the correction to every sample of LOG and write the calibrated log."""
    import numpy as np

    from calib.calibration.correction import Correction, raw_samples
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
    run = read_run(run_path, latitude_deg=latitude, height_m=height, **reading.reader)
    raw_gyro, raw_accel = raw_samples(run, correction, run_path)
    rate, force = correction.apply(raw_gyro, raw_accel)
    dt = sample_intervals(run.time_s)[:, None]
    # The calibrated log is in SI: the raw reading's keys (its conversion, its source format) go.
    meta = {k: v for k, v in run.meta.items() if not k.startswith(("conversion", "source_format"))}
    meta["calibrated_with"] = str(correction_path)
    origin = _time_origin(run)
    if origin:  # epoch stamps were re-based to their first: the absolute time is kept beside them
        meta["time_origin_s"] = repr(origin)
    write_run(Run(run.time_s, rate * dt, force * dt, meta, source=output), output)
    info(f"applied {correction_path} to {run.n_samples} samples of {run_path}")
    if origin:
        info(f"time_s counts from {origin:.6f} s, the log's first stamp (time_origin_s in {output})")
    doc = {
        "output": output,
        "samples": run.n_samples,
        "mean_rate_radps": np.mean(rate, axis=0).tolist(),
        "mean_specific_force_mps2": np.mean(force, axis=0).tolist(),
    }
    if as_json:
        emit_json(doc)
        return
    click.echo(f"wrote {output}")


def _time_origin(run) -> float:
    """The absolute time of ``time_s = 0``: epoch stamps' first, on top of any origin the log states.

    A log whose time column counts from an epoch (UNIX or ROS time) is read from
    its first stamp (``calib.runlog.clock.epoch_origin``: a float64 at 1.7e9 s
    rounds each interval); the calibrated log writes its stamps the same way and
    states that first stamp as ``time_origin_s``, so no absolute time is lost.
    """
    from calib.runlog.run import meta_float

    stated = meta_float(run.meta, "time_origin_s", run.source) if "time_origin_s" in run.meta else 0.0
    return stated + (run.clock.origin_s if run.clock is not None else 0.0)
