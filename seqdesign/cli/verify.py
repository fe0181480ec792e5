"""``seqdesign verify``: the user's proof before the hardware turns (a Monte Carlo of the sequence)."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import click

from calib.errors import CalibError

from . import options
from .design import _duration
from .handtroubles import given_troubles, trouble_options
from .tools import emit_json, guarded, info


@click.command(
    short_help="Simulate and calibrate N runs of a sequence: are the sigmas honest and as predicted?"
)
@click.argument("sequence", required=False)
@options.profile()
@options.requirements
@options.with_terms(
    "Fit these beside the 21 in every run: lever-arm, k2, time-offset (comma-separated) or all."
)
@click.option("--runs", type=click.IntRange(min=2), default=50, show_default=True, help="Simulated runs.")
@click.option("--workers", type=click.IntRange(min=1), default=1, show_default=True, help="Local processes.")
@click.option("--scheduler", default=None, help="dask.distributed scheduler address (instead of --workers).")
@options.latitude()
@options.height()
@options.gravity()
@options.sample_rate()
@options.seed("Seed of run 0; run i uses seed + i (noise, errors, mounting, flip errors).")
@options.tolerance("Each run's base mounting is drawn uniformly within this box (deg).")
@click.option(
    "--flip-error-deg",
    type=click.FloatRange(0.0, 10.0),
    default=0.5,
    show_default=True,
    help="Each flip misses its angle by up to this much (uniform).",
)
@options.file_path(
    "--errors",
    "errors_file",
    "TOML file with an [errors] table: every run has these errors (default: each run draws a "
    "unit of the profile's grade, see docs/verify.md).",
)
@click.option("--table2", is_flag=True, help="Every run has the paper's Table 2 standard errors.")
@options.gimbal("Refuse a sequence this gimbal cannot play.")
@click.option(
    "--by-hand",
    is_flag=True,
    help="Runs placed by hand on a table instead of SEQUENCE (no SEQUENCE): each run draws its own "
    "poses, fast carried moves and noise (docs/by-hand-sim.md) and is calibrated with --by-hand.",
)
@click.option(
    "--like", type=click.Choice(["xsens"]), help="--by-hand: the shape of imu_tk's Xsens recording."
)
@click.option(
    "--poses", type=click.IntRange(3, 1000), default=20, show_default=True, help="--by-hand: rests per run."
)
@click.option(
    "--placement-deg",
    type=click.FloatRange(0.0, 45.0),
    default=0.0,
    show_default=True,
    help="--by-hand with a pose list: each run places each pose within this of the plan (each axis).",
)
@click.option(
    "--peak-rate-dps",
    type=click.FloatRange(1.0, 5000.0),
    help="--by-hand: the fastest turn of a run peaks at this rate, deg/s.",
)
@trouble_options
@click.option("--plot", "plot_path", metavar="FILE.png", help="Also draw the RMS ratios per parameter (PNG).")
@options.as_json
@guarded
# over 8 parameters: a click command, whose options arrive one parameter each
def verify(
    sequence,
    profile,
    requirements,
    with_terms,
    runs,
    workers,
    scheduler,
    latitude,
    height,
    gravity_mps2,
    sample_rate_hz,
    seed,
    tolerance_deg,
    flip_error_deg,
    errors_file,
    table2,
    gimbal_file,
    by_hand,
    like,
    poses,
    peak_rate_dps,
    placement_deg,
    plot_path,
    as_json,
    **troubles,
):
    """Simulate RUNS runs of SEQUENCE (each its own unit of the profile's grade, mounting within the
    tolerance, flip errors and noise), calibrate each as `calibrate` does, and report: the mean NEES
    against its 99 % band (are the sigmas honest?), per parameter the RMS error over the sigma each
    run reported and over `analyze`'s sigma (is the prediction right?), refusals and runs that did
    not converge. Identical with any --workers or --scheduler.
    """
    from calib.model.error_model import ErrorModel
    from calib.model.requirements import default_for, load_requirements
    from calib.noise.profiles import load_profile
    from calib.sim.truth import read_errors
    from seqdesign.plots import verify_png
    from seqdesign.verify import VerifyOptions

    if errors_file and table2:
        raise CalibError("--errors and --table2 both given", None, "choose one")
    if workers > 1 and scheduler:
        raise CalibError("--workers and --scheduler both given", None, "choose one")
    if not by_hand and (names := given_troubles(troubles)):
        raise CalibError(
            f"{', '.join(names)} describe runs placed by hand", "--by-hand", "add --by-hand, or drop them"
        )
    if plot_path and Path(plot_path).suffix.lower() != ".png":
        raise CalibError(f"plot {plot_path!r} must end in .png", "--plot")
    # A unit placed by hand is judged by the mems requirements unless told otherwise, as calibrate does.
    prof = load_profile(profile)
    if by_hand:
        from calib.hand.fit_options import HAND_REQUIREMENTS

        req = load_requirements(requirements or HAND_REQUIREMENTS)
    else:
        requirements, chosen = default_for(prof, requirements)  # the profile's grade, when not given
        if chosen:
            info(chosen)
        req = load_requirements(requirements)
    errors = read_errors(errors_file) if errors_file else ErrorModel.from_table2() if table2 else None
    # each path reads --with as its own fit does (a hand run's groups are not a gimbal run's)
    chosen = VerifyOptions(
        runs=runs,
        seed=seed or 0,
        tolerance_deg=tolerance_deg,
        flip_error_deg=flip_error_deg,
        requirements=req,
        workers=workers,
        scheduler=scheduler,
    )
    where = (latitude, height, gravity_mps2, sample_rate_hz)
    if by_hand or sequence is None:
        from .verifyhand import verify_by_hand

        drawn = {"like": like, "poses": poses, "peak_rate_dps": peak_rate_dps, "placement_deg": placement_deg}
        shape = (drawn, by_hand, troubles)
        result = verify_by_hand(sequence, prof, chosen, with_terms, where, errors, shape, RunsProgress())
    else:
        result = _verify_sequence(sequence, prof, chosen, with_terms, where, errors, gimbal_file)
    doc = result.to_json()
    if plot_path:
        verify_png(result, plot_path)
        doc["plot"] = str(plot_path)
        info(f"wrote {plot_path}")
    if as_json:
        emit_json(doc)
        return
    click.echo(result.to_text())


def _verify_sequence(sequence, prof, options, with_terms, where, errors, gimbal_file):
    """The Monte Carlo of a gimbal sequence, held against ``analyze``'s worst-case sigma.

    ``options`` a :class:`seqdesign.verify.VerifyOptions` (its extras read here from ``with_terms``),
    ``where`` ``(latitude, height, gravity_mps2, sample_rate_hz)`` as given.
    """
    from calib.gimbal.description import load_gimbal
    from calib.gimbal.rule import check_playable, plan_sequence
    from calib.model.optional_terms import load_optional_terms
    from calib.sequence.definition import load_sequence
    from calib.sequence.kinematics import SimConfig
    from seqdesign.analysis import analyze, resolve_site
    from seqdesign.verify import verify as run_verify

    latitude, height, gravity_mps2, sample_rate_hz = where
    seq = load_sequence(sequence)
    gimbal = load_gimbal(gimbal_file)
    check_playable(plan_sequence(seq, gimbal), f"{sequence} on gimbal {gimbal.name!r}")
    lat, h = resolve_site(seq, latitude, height)
    prediction = analyze(
        seq,
        prof,
        latitude_deg=lat,
        height_m=h,
        tolerance_deg=options.tolerance_deg,
        extras=with_terms,
        requirements=options.requirements,
    )
    config = SimConfig(
        latitude_rad=math.radians(lat), height_m=h, sample_rate_hz=sample_rate_hz, gravity_mps2=gravity_mps2
    )
    info(f"verifying {seq.name}: {options.runs} runs, profile {prof.name}")
    return run_verify(
        seq,
        prof,
        replace(options, extras=load_optional_terms(with_terms)),
        config=config,
        predicted_sigma=prediction.robustness.per_parameter_worst_sigma,
        errors=errors,
        progress=RunsProgress(),
    )


class RunsProgress:
    """A Monte Carlo's progress on stderr, as ``design`` says its own: runs done, time, time left.

    At most one line every ``every_s`` seconds, and always the last; a run of tens of
    seconds each would otherwise leave the terminal silent for minutes.
    """

    def __init__(self, every_s: float = 5.0):
        self.every_s = every_s
        self.t0 = time.monotonic()
        self.last = -math.inf

    def __call__(self, done: int, runs: int) -> None:
        now = time.monotonic()
        if done < runs and now - self.last < self.every_s:
            return
        self.last = now
        elapsed = now - self.t0
        left = f", about {_duration(elapsed / done * (runs - done))} left" if done < runs else ""
        info(f"  {done} of {runs} runs done ({_duration(elapsed)}{left})")
