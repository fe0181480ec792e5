"""``seqdesign simulate-stream``: a long, fast-sampled run written to disk window by window."""

from __future__ import annotations

import math
from pathlib import Path

import click
import numpy as np

from calib.errors import CalibError

from . import options
from .tools import emit_json, guarded, info, provenance


@click.command("simulate-stream", short_help="Simulate a long run straight to disk (bounded memory).")
@click.argument("sequence")
@click.option("-o", "--output", required=True, help="Run log to write: .npz or .csv.")
@options.profile("White-noise profile: built-in name or TOML file (no Gauss-Markov terms).")
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
@options.seed("Random seed of the noise.")
@options.latitude()
@options.height()
@options.gravity()
@options.sample_rate()
@click.option("--noise-free", is_flag=True, help="No sensor noise.")
@options.as_json
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
