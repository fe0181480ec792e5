"""``seqdesign calibrate``: the 21 parameters of a run log, read whole or chunk by chunk.

Both readings go through :func:`calib.calibration.entry.calibrate`, which applies
the policy once (site gravity, convergence refusal, Birge check).
``calibrate-stream`` is the same command with ``--stream`` on, kept (hidden)
for the scripts that call it.
"""

from __future__ import annotations

from pathlib import Path

import click

from . import options
from .tools import emit_json, guarded, hidden_alias, info, provenance, refuse_overwrite


@click.command(short_help="Identify the 21 parameters (value and sigma) from a run log.")
@click.argument("run_path", metavar="RUN")
@click.option("--sequence", help="Sequence file the run followed (default: detect flips from the gyros).")
@options.profile("Noise profile that weights the fit and scales the sigmas.")
@click.option("-o", "--output", help="Result TOML (default: RUN with .result.toml).")
@options.file_path(
    "--truth", "truth_path", "Truth file to compare with (default: RUN.truth.toml if it exists)."
)
@options.log_site_and_reading
@click.option(
    "--allow-gaps",
    is_flag=True,
    help="Remove duplicated samples and fill samples dropped at rest; by hand, also leave out a move "
    "that lost a sample amid its turn.",
)
@options.with_terms(
    "Also fit a real unit's terms beyond the 21: any of lever-arm, k2, time-offset (comma-separated), or "
    "all; by hand: g-sensitivity, accel-bias-drift, gyro-bias-drift (each fitted anyway when the data "
    "need it)."
)
@click.option(
    "--without",
    "without_terms",
    default=None,
    metavar="TERMS",
    help="By hand: never fit these optional terms (g-sensitivity, accel-bias-drift, gyro-bias-drift), even "
    "when the data would choose them.",
)
@options.requirements
@options.gravity(
    "Surveyed site gravity, m/s^2 (default: the log's gravity_mps2, else WGS-84 normal "
    "gravity, which misses local anomalies of tens of mGal = tens of ppm of scale)."
)
@click.option(
    "--partial",
    is_flag=True,
    help="On a run that leaves directions unobserved, fit the estimable parameters and "
    "report the rest as not estimable instead of refusing the run.",
)
@click.option(
    "--stream/--no-stream",
    default=None,
    help="Read RUN (.npz or imu-run/1 .csv) chunk by chunk: memory stays at one chunk plus a "
    "byte per sample, whatever its length. Default: only a log over 256 MB.",
)
@click.option(
    "--by-hand",
    is_flag=True,
    help="RUN was placed by hand (no gimbal, no sequence): fit it from its rests, found with the "
    "profile's noise, and the gyros across the moves between them (any axis, fast, carried). "
    "Give the unit's white-noise profile (--profile mems, or your own): the default navigation "
    "profile's noise is far below a hand-turned unit's and finds no rest.",
)
@options.file_path(
    "--correction",
    "correction_path",
    "Also write the result as the correction a user applies, calibrated = M (raw - b) per "
    "sensor with its sigmas, in the log's units (counts for a log read through --conversion).",
)
@click.option(
    "--fix-units",
    is_flag=True,
    help="By hand: where the data contradict the log's labels (accelerometer in g read as m/s^2, "
    "gyro in deg/s read as rad/s, swapped or flipped axes, a wrong sample rate), put them right and "
    "say so instead of refusing.",
)
@options.as_json
@guarded
# over 8 parameters: a click command takes one parameter per option it declares
def calibrate(
    run_path,
    sequence,
    profile,
    output,
    truth_path,
    latitude,
    height,
    reading,
    allow_gaps,
    with_terms,
    without_terms,
    requirements,
    gravity_mps2,
    partial,
    stream,
    by_hand,
    correction_path,
    fix_units,
    as_json,
):
    """Align, navigate on the stationary base and fit the 21 error parameters of
    RUN (CSV, CSV.GZ, NPZ or PSINS .imu) by iterated, noise-weighted least squares.
    """
    from calib.calibration.entry import CalibrateOptions, calibrate as calibrate_source, reads_in_chunks
    from calib.errors import CalibError
    from calib.model.optional_terms import load_optional_terms
    from calib.noise.profiles import load_profile
    from calib.sequence.definition import load_sequence
    from calib.sim.truth import read_truth, truth_path_for

    out_path = Path(output) if output else Path(run_path).with_name(Path(run_path).stem + ".result.toml")
    refuse_overwrite(
        {"-o": out_path, "--correction": correction_path},
        {
            "RUN": run_path,
            "--gyro-file": reading.gyro_file,
            "--conversion": reading.conversion,
            "--sequence": sequence,
            "--truth": truth_path,
            "--profile": profile,
            "--requirements": requirements,
        },
    )
    extras = load_optional_terms(with_terms, by_hand=by_hand)
    prof = load_profile(profile)
    if not by_hand:  # a hand fit takes the mems requirements by default (calib.calibration.entry)
        from calib.model.requirements import default_for

        requirements, chosen = default_for(prof, requirements)  # the profile's grade, when not given
        if chosen:
            info(chosen)
    site = dict(allow_gaps=allow_gaps, latitude_deg=latitude, height_m=height)
    from .reading import run_notes

    if reading.logger and stream:
        raise CalibError(
            "--columns, --gyro-file, --conversion, --sample-rate-hz and --at-stamps read a logger's file, "
            "which is read whole",
            run_path,
            "calibrate it without --stream",
        )
    run = None
    if by_hand and stream:
        raise CalibError("a run placed by hand is read whole", run_path, "leave out --stream")
    if not reading.logger and not by_hand and reads_in_chunks(run_path, stream, **site):
        info(f"calibrating {run_path} chunk by chunk, profile {prof.name}")
    else:
        from calib.runlog import read_run

        # A hand fit leaves out a move whose turn lost a sample (--allow-gaps puts it in as a guess).
        run = read_run(run_path, **site, **reading.reader, guess_turns=by_hand)
        info(run.clock.summary())  # jitter, dropped and duplicated samples (calib.clock)
        gravity_mps2, notes = run_notes(run, gravity_mps2)  # a conversion file's gravity, clipping
        for note in notes:
            info(note)
    if truth_path is None and truth_path_for(run_path).exists():
        truth_path = truth_path_for(run_path)
    truth = read_truth(truth_path) if truth_path else None
    seq = load_sequence(sequence) if sequence else None
    if run is not None:
        info(f"calibrating {run_path}: {run.n_samples} samples, {run.duration_s:.1f} s, profile {prof.name}")
    result = calibrate_source(
        run_path if run is None else run,
        prof,
        stream=run is None,
        sequence=seq,
        extras=extras,
        requirements=requirements,
        by_hand=by_hand,
        options=CalibrateOptions(
            partial=partial,
            gravity_mps2=gravity_mps2,
            without=without_terms,
            fix_units=fix_units,
            provenance=provenance(
                {
                    "run": run_path,
                    "sequence": sequence,
                    "truth": truth_path,
                    "profile": profile if Path(profile).exists() else None,
                    "requirements": requirements if requirements and Path(requirements).exists() else None,
                },
                sequence=sequence,
                profile=prof.name,
                **({} if run is not None else {"reader": "chunks"}),
            ),
        ),
    )
    # Rendered before anything is written: a report that cannot be printed leaves no file behind.
    text = None if as_json else result.to_text(truth)
    result.save(out_path)
    if correction_path:
        from calib.calibration.correction import correction_of_result

        correction_of_result(result, run.conversion if run is not None else None, run_path, run).save(
            correction_path
        )
        info(f"wrote {correction_path}")
    # On the command line the surveyed gravity is --gravity (the library names its argument).
    warned = result.warnings(gravity_option="--gravity")
    for warning in warned:
        info(f"warning: {warning}")
    doc = {"result": str(out_path)} | ({} if run is None else {"clock": run.clock.as_dict()})
    if as_json:
        emit_json(result.to_json(truth) | doc | {"warnings": warned})
        return
    click.echo(text)
    click.echo(f"wrote {out_path}")


calibrate_stream = hidden_alias(calibrate, "calibrate-stream", "stream")
