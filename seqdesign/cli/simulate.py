"""``seqdesign simulate``: a calibration run of a sequence, with its truth file."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import click
import numpy as np

from calib.errors import CalibError

from . import options
from .byhand import by_hand_refusals, simulate_by_hand
from .handtroubles import given_troubles, trouble_options
from .tools import emit_json, guarded, hidden_alias, info, provenance

if TYPE_CHECKING:  # the machinery loads when a command runs, not for --help
    from calib.model.error_model import ErrorModel
    from calib.noise.profiles import NoiseProfile
    from calib.sequence.definition import Sequence


@dataclass(frozen=True)
class _Setup:
    """What both ways of simulating read and check the same way: sequence, profile, errors."""

    sequence_arg: str
    seq: Sequence
    profile_arg: str
    profile: NoiseProfile
    errors_file: str | None
    errors: ErrorModel

    @classmethod
    def read(cls, sequence, output, profile, errors_file, table2, setup_deg, random_setup) -> _Setup:
        if Path(output).suffix.lower() not in (".csv", ".npz"):
            raise CalibError(
                f"unknown run format {Path(output).suffix!r}", "-o/--output", "name the file .csv or .npz"
            )
        if errors_file and table2:
            raise CalibError("--errors and --table2 both given", None, "choose one")
        if setup_deg and random_setup:
            raise CalibError("--setup-deg and --random-setup both given", None, "choose one")
        if setup_deg and any(abs(a) > 10 or not math.isfinite(a) for a in setup_deg):
            raise CalibError(
                f"--setup-deg {setup_deg} beyond 10 deg",
                "--setup-deg",
                "the mounting tolerance of the conventions is +-3 deg",
            )
        from calib.model.error_model import ErrorModel
        from calib.noise.profiles import load_profile
        from calib.sequence.definition import load_sequence
        from calib.sim.truth import read_errors

        seq = load_sequence(sequence)
        prof = load_profile(profile)
        errors = (
            read_errors(errors_file)
            if errors_file
            else ErrorModel.from_table2()
            if table2
            else ErrorModel.zero()
        )
        return cls(sequence, seq, profile, prof, errors_file, errors)

    def provenance(self, **inputs) -> dict:
        """The truth file's provenance: tool, command, and the inputs' hashes."""
        files = {
            "sequence": self.sequence_arg,
            "errors": self.errors_file,
            **inputs,
            "profile": self.profile_arg if Path(self.profile_arg).exists() else None,
        }
        return provenance(files, sequence=self.seq.name, profile=self.profile.name)


def _run_meta(prov: dict, profile_name: str) -> dict:
    """What the run log records of how it was made."""
    keys = ("tool_version", "command", "sequence_sha256")
    return {k: prov[k] for k in keys} | {"profile": profile_name}


def _simulate_streamed(setup: _Setup, cfg, output, setup_deg, seed, noise_free, as_json) -> None:
    """``simulate --stream``: the run log written window by window (calib.sim.to_disk)."""
    from calib.sim.gimbal_run import SimOptions
    from calib.sim.to_disk import simulate_to_file
    from calib.sim.truth import truth_path_for, write_truth

    prov = setup.provenance()
    mounting = np.radians(setup_deg) if setup_deg else (0.0, 0.0, 0.0)
    n, truth = simulate_to_file(
        output,
        setup.seq,
        cfg,
        setup.errors,
        setup.profile,
        SimOptions(setup_rotvec=mounting, noise=not noise_free, seed=seed),
        meta_extra=_run_meta(prov, setup.profile.name),
    )
    truth_path = truth_path_for(output)
    write_truth(truth_path, truth, prov)
    rate = cfg.sample_rate_hz
    summary = {
        "run": str(output),
        "truth": str(truth_path),
        "sequence": setup.seq.name,
        "samples": n,
        "duration_s": n / rate,
        "profile": setup.profile.name,
        "noise": not noise_free,
    }
    if as_json:
        emit_json(summary)
        return
    info(f"wrote {output} ({n} samples, {n / rate:.1f} s, profile {setup.profile.name}) and {truth_path}")


# The --by-hand options (given without --by-hand, that is away from their defaults, they are refused).
HAND_OPTIONS = (
    "poses",
    "like",
    "peak_rate_dps",
    "translation_m",
    "wobble_deg",
    "oversample",
    "random_errors",
    "rest_s",
    "first_rest_s",
)


@click.command(
    short_help="Simulate a calibration run of a sequence (or placed by hand) to a run log + truth file."
)
@click.argument("sequence", required=False)
@click.option("-o", "--output", required=True, help="Run log to write: .csv or .npz.")
@options.profile()
@options.file_path("--errors", "errors_file", "TOML file with an [errors] table (spec names and units).")
@click.option("--table2", is_flag=True, help="Inject the paper's Table 2 standard values.")
@click.option(
    "--setup-deg", nargs=3, type=float, metavar="E N U", help="Base mounting rotation vector, degrees."
)
@click.option(
    "--random-setup", is_flag=True, help="Draw the mounting rotation uniformly within the +-3 deg tolerance."
)
@options.seed("Random seed (noise, setup, flip errors).")
@options.latitude()
@options.height()
@options.gravity()
@options.sample_rate()
@click.option(
    "--flip-error-deg",
    type=click.FloatRange(0.0, 10.0),
    default=0.0,
    show_default=True,
    help="Each flip misses its angle by up to this much (uniform).",
)
@click.option("--noise-free", is_flag=True, help="No sensor noise.")
@click.option(
    "--extra",
    "extra_text",
    metavar="NAME=VALUE,...",
    help="Terms of a real unit beyond the 21, in report units: lever arms "
    "rxx..rzz (cm), k2x k2y k2z (ug/g^2), dt_ga (ms, accelerometers lag), "
    "e.g. rxx=3,k2y=20,dt_ga=0.5.",
)
@options.gimbal(
    "Refuse moves this gimbal cannot play; its limits pace the lock counter-rotations in the "
    "encoder channels."
)
@click.option(
    "--stream",
    is_flag=True,
    help="Write the log a time window at a time, so that hours at kHz rates fit in memory "
    "(white-noise profiles; no --random-setup, --flip-error-deg, --extra or --gimbal).",
)
@click.option(
    "--by-hand",
    is_flag=True,
    help="Simulate a run placed by hand on a table instead of a sequence (no SEQUENCE): poses "
    "random on SO(3), fast turns with a wobbling axis, carried out and back (docs/by-hand-sim.md); "
    "100 Hz unless --sample-rate-hz is given.",
)
@click.option(
    "--poses", type=click.IntRange(1, 1000), default=None, help="--by-hand: number of rests (default 20)."
)
@click.option(
    "--like",
    type=click.Choice(["xsens"]),
    default=None,
    help="--by-hand: the shape of imu_tk's Xsens recording (52 s static, 37 poses, 512 s).",
)
@click.option(
    "--peak-rate-dps",
    type=click.FloatRange(1.0, 5000.0),
    default=None,
    help="--by-hand: the fastest turn peaks at this rate, deg/s (default: each turn lasts its move).",
)
@click.option(
    "--translation-m",
    type=click.FloatRange(0.0, 2.0),
    default=0.3,
    show_default=True,
    help="--by-hand: each move carries the unit out and back by up to this distance (0: none).",
)
@click.option(
    "--wobble-deg",
    type=click.FloatRange(0.0, 45.0),
    default=10.0,
    show_default=True,
    help="--by-hand: peak wobble of a turn's axis, deg (0: fixed-axis turns).",
)
@click.option(
    "--oversample",
    type=click.IntRange(1, 1000),
    default=10,
    show_default=True,
    help="--by-hand: pieces per sample of the increments' quadrature.",
)
@click.option(
    "--random-errors",
    type=click.Choice(["mems", "tactical", "navigation"]),
    default=None,
    help="--by-hand: draw the 21 errors uniformly within the sizes of a unit of this grade.",
)
@click.option(
    "--rest-s",
    type=click.FloatRange(0.1, 3600.0),
    nargs=2,
    default=None,
    metavar="MIN MAX",
    help="--by-hand: each rest after the first lasts between these, s (default 5 12; a hand "
    "holding short poses: 1 6).",
)
@click.option(
    "--first-rest-s",
    type=click.FloatRange(0.1, 36000.0),
    default=None,
    help="--by-hand: the first rest (the static start), s (default 50).",
)
@trouble_options
@options.as_json
@guarded
# over 8 parameters: a click command takes one parameter per option it declares
def simulate(
    sequence,
    output,
    profile,
    errors_file,
    table2,
    setup_deg,
    random_setup,
    seed,
    latitude,
    height,
    gravity_mps2,
    sample_rate_hz,
    flip_error_deg,
    noise_free,
    extra_text,
    as_json,
    gimbal_file=None,
    stream=False,
    by_hand=False,
    poses=None,
    like=None,
    peak_rate_dps=None,
    translation_m=0.3,
    wobble_deg=10.0,
    oversample=10,
    random_errors=None,
    rest_s=None,
    first_rest_s=None,
    **troubles,
):
    """Simulate the IMU increments of SEQUENCE on a stationary base with exact
    kinematics, the 21 errors and white noise; write the run log (-o) and its
    truth file beside it (run.truth.toml). With --by-hand, a run placed by hand
    on a table instead (no SEQUENCE), with a real recording's troubles when asked
    (tremor, host stamps, g-sensitivity, a rate error).
    """
    hand = {
        "poses": poses,
        "like": like,
        "peak_rate_dps": peak_rate_dps,
        "translation_m": translation_m,
        "wobble_deg": wobble_deg,
        "oversample": oversample,
        "random_errors": random_errors,
        "rest_s": rest_s,
        "first_rest_s": first_rest_s,
    }
    if by_hand:
        gimbal_run = {
            "--setup-deg": setup_deg,
            "--random-setup": random_setup,
            "--flip-error-deg": flip_error_deg,
            "--extra": extra_text,
            "--gimbal": gimbal_file,
            "--stream": stream,
        }
        by_hand_refusals(sequence, gimbal_run)
        site = (latitude, height, gravity_mps2, sample_rate_hz)
        injected = (errors_file, table2)
        simulate_by_hand(output, profile, injected, seed, site, noise_free, as_json, hand | troubles)
        return
    names = ["--" + k.replace("_", "-") for k, v in hand.items() if v != HAND_DEFAULTS[k]]
    if names := names + given_troubles(troubles):
        raise CalibError(
            f"{', '.join(names)} describe a run placed by hand", "--by-hand", "add --by-hand, or drop them"
        )
    if sequence is None:
        raise click.UsageError("Missing argument 'SEQUENCE' (or give --by-hand).")
    from calib.gimbal.description import load_gimbal
    from calib.gimbal.rule import check_playable, plan_sequence
    from calib.model.optional_terms import parse_values
    from calib.runlog import write_run
    from calib.sequence.kinematics import SimConfig
    from calib.sim.gimbal_run import SimOptions, simulate as run_simulation
    from calib.sim.truth import truth_path_for, write_truth
    from seqdesign.analysis import resolve_site

    if stream:
        unsupported = {
            "--random-setup": random_setup,
            "--flip-error-deg": flip_error_deg,
            "--extra": extra_text,
            "--gimbal": gimbal_file,
        }
        if given := [name for name, value in unsupported.items() if value]:
            raise CalibError(
                f"{', '.join(given)} cannot be written a window at a time",
                "--stream",
                "simulate in memory (without --stream), or drop " + ", ".join(given),
            )
    setup = _Setup.read(sequence, output, profile, errors_file, table2, setup_deg, random_setup)
    extra = parse_values(extra_text)
    gimbal = load_gimbal(gimbal_file)
    check_playable(plan_sequence(setup.seq, gimbal), f"{sequence} on gimbal {gimbal.name!r}", sequence)
    seq, prof, errors = setup.seq, setup.profile, setup.errors
    lat, h = resolve_site(seq, latitude, height)
    cfg = SimConfig(
        latitude_rad=math.radians(lat), height_m=h, sample_rate_hz=sample_rate_hz, gravity_mps2=gravity_mps2
    )
    if stream:
        _simulate_streamed(setup, cfg, output, setup_deg, seed, noise_free, as_json)
        return
    run, truth = run_simulation(
        seq,
        cfg,
        errors,
        prof,
        SimOptions(
            setup_rotvec=np.radians(setup_deg) if setup_deg else (0, 0, 0),
            flip_error_deg=flip_error_deg,
            noise=not noise_free,
            seed=seed,
            random_setup_deg=3.0 if random_setup else None,
        ),
        extra=extra,
        gimbal=gimbal,
    )
    truth_path = truth_path_for(output)
    prov = setup.provenance(gimbal=gimbal.path)
    run.meta.update(_run_meta(prov, prof.name))
    write_run(run, output)
    write_truth(truth_path, truth, prov)
    summary = {
        "run": str(output),
        "truth": str(truth_path),
        "sequence": seq.name,
        "samples": int(run.time_s.size),
        "duration_s": float(run.time_s[-1]),
        "profile": prof.name,
        "noise": not noise_free,
        "setup_deg": [float(x) for x in np.degrees(truth.setup_rotvec)],
        "latitude_deg": lat,
        "height_m": h,
    }
    if as_json:
        emit_json(summary)
    else:
        click.echo(
            f"wrote {output} ({summary['samples']} samples, {summary['duration_s']:.1f} s, "
            f"{'noise-free' if noise_free else 'profile ' + prof.name}) and {truth_path}"
        )


# The --by-hand options' defaults, as the command declares them.
HAND_DEFAULTS = {p.name: p.default for p in simulate.params if p.name in HAND_OPTIONS}

simulate_stream = hidden_alias(simulate, "simulate-stream", "stream")
