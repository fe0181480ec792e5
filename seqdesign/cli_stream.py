"""``seqdesign simulate-stream``: a long, fast-sampled run written to disk window by window."""

from __future__ import annotations

import math
from pathlib import Path

import click
import numpy as np

from calib.errors import CalibError

from .clitools import emit_json, guarded, info, provenance


@click.command("simulate-stream", short_help="Simulate a long run straight to disk (bounded memory).")
@click.argument("sequence")
@click.option("-o", "--output", required=True, help="Run log to write: .npz or .csv.")
@click.option(
    "--profile",
    default="navigation",
    show_default=True,
    help="White-noise profile: built-in name or TOML file (no Gauss-Markov terms).",
)
@click.option(
    "--errors",
    "errors_file",
    type=click.Path(dir_okay=False),
    help="TOML file with an [errors] table (spec names and units).",
)
@click.option("--table2", is_flag=True, help="Inject the paper's Table 2 standard values.")
@click.option(
    "--setup-deg", nargs=3, type=float, metavar="E N U", help="Base mounting rotation vector, degrees."
)
@click.option("--seed", type=int, default=None, help="Random seed of the noise.")
@click.option("--latitude", type=float, help="Site latitude, deg (default: sequence, else 40).")
@click.option("--height", type=float, help="Site height, m (default: sequence, else 0).")
@click.option(
    "--gravity",
    "gravity_mps2",
    type=float,
    help="Measured site gravity, m/s^2 (default: WGS-84 normal gravity).",
)
@click.option("--sample-rate-hz", type=float, default=200.0, show_default=True)
@click.option("--noise-free", is_flag=True, help="No sensor noise.")
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def simulate_stream(
    sequence,
    output,
    profile,
    errors_file,
    table2,
    setup_deg,
    seed,
    latitude,
    height,
    gravity_mps2,
    sample_rate_hz,
    noise_free,
    as_json,
):
    """Simulate SEQUENCE like `seqdesign simulate`, writing the run log (-o) a time window
    at a time so that hours at kHz rates fit in memory; the truth file goes beside it.
    """
    from calib.errormodel import ErrorModel
    from calib.profiles import load_profile
    from calib.sequence import load_sequence
    from calib.sim import SimConfig
    from calib.simstream import simulate_to_file
    from calib.truth import read_errors, truth_path_for, write_truth
    from seqdesign.analysis import resolve_site

    if Path(output).suffix.lower() not in (".csv", ".npz"):
        raise CalibError(
            f"unknown run format {Path(output).suffix!r}", "-o/--output", "name the file .csv or .npz"
        )
    if errors_file and table2:
        raise CalibError("--errors and --table2 both given", None, "choose one")
    if setup_deg and any(abs(a) > 10 or not math.isfinite(a) for a in setup_deg):
        raise CalibError(
            f"--setup-deg {setup_deg} beyond 10 deg",
            "--setup-deg",
            "the mounting tolerance of the conventions is +-3 deg",
        )
    if not (1.0 <= sample_rate_hz <= 10000.0):
        raise CalibError(
            f"--sample-rate-hz {sample_rate_hz} outside [1, 10000]",
            "--sample-rate-hz",
            "give the IMU's output rate in Hz",
        )
    if gravity_mps2 is not None and not (9.7 < gravity_mps2 < 9.9):
        raise CalibError(
            f"--gravity {gravity_mps2} m/s^2 is not an Earth gravity", "--gravity", "give m/s^2, e.g. 9.80123"
        )
    seq, prof = load_sequence(sequence), load_profile(profile)
    errors = (
        read_errors(errors_file) if errors_file else ErrorModel.from_table2() if table2 else ErrorModel.zero()
    )
    lat, h = resolve_site(seq, latitude, height)
    cfg = SimConfig(
        latitude_rad=math.radians(lat), height_m=h, sample_rate_hz=sample_rate_hz, gravity_mps2=gravity_mps2
    )
    prov = provenance(
        {"sequence": sequence, "errors": errors_file, "profile": profile if Path(profile).exists() else None},
        sequence=seq.name,
        profile=prof.name,
    )
    meta = {
        "tool_version": prov["tool_version"],
        "command": prov["command"],
        "sequence_sha256": prov["sequence_sha256"],
        "profile": prof.name,
    }
    n, truth = simulate_to_file(
        output,
        seq,
        cfg,
        errors,
        prof,
        np.radians(setup_deg) if setup_deg else (0.0, 0.0, 0.0),
        noise=not noise_free,
        seed=seed,
        meta_extra=meta,
    )
    truth_path = truth_path_for(output)
    write_truth(truth_path, truth, prov)
    summary = {
        "run": str(output),
        "truth": str(truth_path),
        "sequence": seq.name,
        "samples": n,
        "duration_s": n / sample_rate_hz,
        "profile": prof.name,
        "noise": not noise_free,
    }
    if as_json:
        emit_json(summary)
        return
    info(f"wrote {output} ({n} samples, {n / sample_rate_hz:.1f} s, profile {prof.name}) and {truth_path}")


@click.command(
    "calibrate-stream", short_help="Calibrate a long run read from disk chunk by chunk (bounded memory)."
)
@click.argument("run_path", metavar="RUN")
@click.option(
    "--profile",
    default="navigation",
    show_default=True,
    help="Noise profile that weights the fit and scales the sigmas.",
)
@click.option("-o", "--output", help="Result TOML (default: RUN with .result.toml).")
@click.option(
    "--with",
    "with_terms",
    metavar="TERMS",
    help="Also fit lever-arm, k2, time-offset (comma-separated), or all.",
)
@click.option(
    "--requirements",
    "requirements",
    default=None,
    metavar="FILE|NAME",
    help="Accuracy requirements: paper, tactical, mems or a TOML file.",
)
@click.option(
    "--partial", is_flag=True, help="Fit the estimable part of a run that leaves directions unobserved."
)
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def calibrate_stream(run_path, profile, output, with_terms, requirements, partial, as_json):
    """Fit RUN (CSV or NPZ) as `seqdesign calibrate` does, reading it a chunk at a time:
    memory stays at one chunk plus one byte per sample, whatever the length of the log.
    """
    from calib.calibration import load_requirements, result_from_fit, site_gravity
    from calib.chunks import calibrate_file
    from calib.extras import as_extras
    from calib.profiles import as_profile
    from calib.runlog import Run, read_meta
    from calib.truth import read_truth, truth_path_for

    extras, prof, req = as_extras(with_terms), as_profile(profile), load_requirements(requirements)
    if not Path(run_path).is_file():
        raise CalibError("no such file", run_path, "check the path")
    meta = Run(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), read_meta(run_path), source=run_path)
    gravity = site_gravity(meta)
    out_path = Path(output) if output else Path(run_path).with_name(Path(run_path).stem + ".result.toml")
    info(f"calibrating {run_path} chunk by chunk, profile {prof.name}")
    fit = calibrate_file(
        run_path,
        math.radians(meta.latitude_deg),
        gravity.value_mps2,
        prof,
        extras=extras,
        partial=partial,
        requirements=req,
    )
    if not fit.converged:
        raise CalibError(
            f"the fit did not converge in {fit.iterations} iterations",
            run_path,
            "no result written; check the run and the noise profile",
        )
    result = result_from_fit(
        fit, prof, gravity, provenance({"run": run_path}, profile=prof.name, reader="chunks"), req
    )
    result.save(out_path)
    truth = read_truth(truth_path_for(run_path)) if truth_path_for(run_path).exists() else None
    if as_json:
        emit_json(result.to_json(truth) | {"result": str(out_path)})
        return
    click.echo(result.to_text(truth))
    click.echo(f"wrote {out_path}")
