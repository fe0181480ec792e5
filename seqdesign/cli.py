"""The ``seqdesign`` command line: show, simulate, calibrate, analyze, compare.

Every command refuses bad input with one line on stderr naming what, where
and how to fix it, and exits non-zero without a traceback. ``--json`` puts a
single JSON document on stdout; progress and logs go to stderr.
"""

from __future__ import annotations

from seqdesign import blas  # noqa: F401  first: one BLAS thread before numpy loads

# isort: split
import math
import sys
from pathlib import Path

import click
import numpy as np

from calib.errors import CalibError
from seqdesign.clitools import emit_json, guarded, info, provenance, tool_version


class _Group(click.Group):
    """The command group; a usage error (a bad option value) also honours ``--json``."""

    def invoke(self, ctx):
        raw = list(ctx.args)  # the group empties it before parsing the command's options
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            if "--json" in raw:
                where = exc.ctx.command_path if exc.ctx else "seqdesign"
                emit_json(
                    {"error": {"what": exc.format_message(), "where": where, "fix": f"see '{where} --help'"}}
                )
            raise


@click.group(name="seqdesign", cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(tool_version(), prog_name="seqdesign")
def main():
    """Self-calibration of a three-axis hybrid INS: design, analyse, simulate,
    calibrate and view multi-position sequences (21 IMU error parameters).
    """


# ---------------------------------------------------------------------------
# show


@main.command(short_help="Print a sequence's rest positions: axes, gimbal angles, times.")
@click.argument("sequence")
@click.option(
    "--gimbal",
    "gimbal_file",
    type=click.Path(dir_okay=False),
    help="Gimbal description (TOML): list its counter-rotations and flag violations.",
)
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def show(sequence, gimbal_file, as_json):
    """Print where body X, Y, Z point at every rest position of SEQUENCE (a
    file or a shipped name such as paper-9pos), its gimbal angles (outer,
    middle, inner; continuous along the run) and its start and end times.
    """
    from calib.encoders import rest_positions
    from calib.gimbal import plan_sequence
    from calib.gimbalfile import load_gimbal
    from calib.sequence import load_sequence
    from seqdesign.cli_gimbal import LOCK_NOTE, gimbal_summary

    seq = load_sequence(sequence)
    gimbal = load_gimbal(gimbal_file)
    positions = rest_positions(seq, gimbal)
    gimbal_doc, gimbal_lines = gimbal_summary(seq, gimbal, plan_sequence(seq, gimbal))
    if as_json:
        emit_json(
            {
                **gimbal_doc,
                "sequence": seq.name,
                "duration_s": seq.duration_s,
                "positions": [
                    {
                        "position": p.number,
                        "x": p.directions[0],
                        "y": p.directions[1],
                        "z": p.directions[2],
                        "outer_deg": float(p.gimbal_deg[0]),
                        "middle_deg": float(p.gimbal_deg[1]),
                        "inner_deg": float(p.gimbal_deg[2]),
                        "start_s": p.start_s,
                        "end_s": p.end_s,
                        "gimbal_lock": p.gimbal_lock,
                        "on_grid": p.on_grid,
                    }
                    for p in positions
                ],
            }
        )
        return
    click.echo(f"{seq.name}: {seq.description}".rstrip(": "))
    w = max(6, *(len(d) + 1 for p in positions for d in p.directions))  # off-grid axes are vectors
    click.echo(
        f"{'pos':>3}  {'X':<{w}}{'Y':<{w}}{'Z':<{w}} {'outer':>8}{'middle':>8}{'inner':>8}"
        f"  {'start s':>8}{'end s':>8}"
    )
    for p in positions:
        lock = "  GIMBAL LOCK" if p.gimbal_lock else ""
        click.echo(
            f"{p.number:>3}  {p.directions[0]:<{w}}{p.directions[1]:<{w}}{p.directions[2]:<{w}}"
            f" {p.gimbal_deg[0]:8.1f}{p.gimbal_deg[1]:8.1f}{p.gimbal_deg[2]:8.1f}"
            f"  {p.start_s:8.1f}{p.end_s:8.1f}{lock}"
        )
    if not all(p.on_grid for p in positions):
        click.echo("off-grid axes are shown as [east north up] components")
    if any(p.gimbal_lock for p in positions):
        click.echo(LOCK_NOTE)
    click.echo("\n".join(gimbal_lines))
    click.echo(
        f"{len(positions)} rest positions, {len(seq.steps)} flips, "
        f"total {seq.duration_s:.1f} s ({seq.duration_s / 60:.1f} min)"
    )


# ---------------------------------------------------------------------------
# simulate


def _run_suffix(path: str, option: str) -> None:
    if Path(path).suffix.lower() not in (".csv", ".npz"):
        raise CalibError(f"unknown run format {Path(path).suffix!r}", option, "name the file .csv or .npz")


@main.command(short_help="Simulate a calibration run of a sequence to a run log + truth file.")
@click.argument("sequence")
@click.option("-o", "--output", required=True, help="Run log to write: .csv or .npz.")
@click.option(
    "--profile", default="navigation", show_default=True, help="Noise profile: built-in name or TOML file."
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
@click.option(
    "--random-setup", is_flag=True, help="Draw the mounting rotation uniformly within the +-3 deg tolerance."
)
@click.option("--seed", type=int, default=None, help="Random seed (noise, setup, flip errors).")
@click.option("--latitude", type=float, help="Site latitude, deg (default: sequence, else 40).")
@click.option("--height", type=float, help="Site height, m (default: sequence, else 0).")
@click.option(
    "--gravity",
    "gravity_mps2",
    type=click.FloatRange(9.7, 9.9, min_open=True, max_open=True),
    help="Measured site gravity, m/s^2 (default: WGS-84 normal gravity).",
)
@click.option("--sample-rate-hz", type=click.FloatRange(1.0, 10000.0), default=200.0, show_default=True)
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
@click.option(
    "--gimbal",
    "gimbal_file",
    type=click.Path(dir_okay=False),
    help="Gimbal description (TOML): refuse moves it cannot play; its limits pace "
    "the lock counter-rotations in the encoder channels.",
)
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
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
):
    """Simulate the IMU increments of SEQUENCE on a stationary base with exact
    kinematics, the 21 errors and white noise; write the run log (-o) and its
    truth file beside it (run.truth.toml).
    """
    from calib.errormodel import ErrorModel
    from calib.extras import parse_values
    from calib.profiles import load_profile
    from calib.runlog import write_run
    from calib.sequence import load_sequence
    from calib.sim import SimConfig
    from calib.sim import simulate as run_simulation
    from calib.truth import read_errors, truth_path_for, write_truth
    from seqdesign.analysis import resolve_site

    _run_suffix(output, "-o/--output")
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
    extra = parse_values(extra_text)
    seq = load_sequence(sequence)
    from calib.gimbal import check_playable, plan_sequence
    from calib.gimbalfile import load_gimbal

    gimbal = load_gimbal(gimbal_file)
    check_playable(plan_sequence(seq, gimbal), f"{sequence} on gimbal {gimbal.name!r}")
    prof = load_profile(profile)
    errors = (
        read_errors(errors_file) if errors_file else ErrorModel.from_table2() if table2 else ErrorModel.zero()
    )
    lat, h = resolve_site(seq, latitude, height)
    cfg = SimConfig(
        latitude_rad=math.radians(lat), height_m=h, sample_rate_hz=sample_rate_hz, gravity_mps2=gravity_mps2
    )
    run, truth = run_simulation(
        seq,
        cfg,
        errors,
        prof,
        setup_rotvec=np.radians(setup_deg) if setup_deg else (0, 0, 0),
        flip_error_deg=flip_error_deg,
        noise=not noise_free,
        seed=seed,
        random_setup_deg=3.0 if random_setup else None,
        extra=extra,
        gimbal=gimbal,
    )
    truth_path = truth_path_for(output)
    prov = provenance(
        {
            "sequence": sequence,
            "errors": errors_file,
            "gimbal": gimbal.path,
            "profile": profile if Path(profile).exists() else None,
        },
        sequence=seq.name,
        profile=prof.name,
    )
    run.meta.update(
        {
            "tool_version": prov["tool_version"],
            "command": prov["command"],
            "sequence_sha256": prov["sequence_sha256"],
            "profile": prof.name,
        }
    )
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


# ---------------------------------------------------------------------------
# analyze / compare

TOLERANCE = click.FloatRange(0.0, 10.0)


@main.command(short_help="Predict sigma and separability of the 21 parameters for a sequence.")
@click.argument("sequence")
@click.option("--profile", default="navigation", show_default=True, help="Noise profile.")
@click.option("--latitude", type=float, help="Site latitude, deg (default: sequence, else 40).")
@click.option(
    "--tolerance-deg",
    type=TOLERANCE,
    default=3.0,
    show_default=True,
    help="Base mounting tolerance; the figures are the worst over the box (0: nominal only).",
)
@click.option(
    "--requirements",
    "requirements",
    default=None,
    metavar="FILE|NAME",
    help="Accuracy requirements: a TOML file with a [requirements] table (spec names and "
    "units; missing ones keep the paper's) or paper, tactical, mems.",
)
@click.option(
    "--view",
    "view_path",
    is_flag=False,
    flag_value="",
    default=None,
    metavar="[FILE.rrd]",
    help="Also write a rerun recording (default: <sequence>-analysis.rrd).",
)
@click.option(
    "--with",
    "with_terms",
    metavar="TERMS",
    help="Also fit a real unit's terms beyond the 21 (lever-arm, k2, time-offset, "
    "comma-separated, or all): sigma of each of the 21 with and without them, "
    "and whether the sequence observes them.",
)
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def analyze(sequence, profile, latitude, tolerance_deg, requirements, view_path, with_terms, as_json):
    """Fisher information of SEQUENCE under a noise profile: predicted sigma of
    each parameter against its requirement (3 sigma / requirement), which
    parameters are estimable, correlated pairs, unobservable directions,
    worst case over the +-tolerance mounting box.
    """
    from seqdesign.analysis import analyze as run_analysis

    if view_path and Path(view_path).suffix != ".rrd":
        raise CalibError(f"recording {view_path!r} must end in .rrd", "--view")
    result = run_analysis(
        sequence,
        profile,
        latitude_deg=latitude,
        tolerance_deg=tolerance_deg,
        extras=with_terms,
        requirements=requirements,
    )
    doc = result.to_json()
    if view_path is not None:
        from viz.record import record_analysis

        path = view_path or f"{result.sequence.name}-analysis.rrd"
        record_analysis(result, path)
        doc["recording"] = str(path)
        info(f"wrote {path} (open it with: rerun {path})")
    if as_json:
        emit_json(doc)
        return
    click.echo(result.to_text())


@main.command(short_help="Compare sequences side by side, or two calibrations of one unit.")
@click.argument("sequences", nargs=-1, required=True)
@click.option("--profile", default="navigation", show_default=True, help="Noise profile.")
@click.option("--latitude", type=float, help="Site latitude, deg (default: each sequence's, else 40).")
@click.option("--tolerance-deg", type=TOLERANCE, default=3.0, show_default=True)
@click.option(
    "--requirements",
    "requirements",
    default=None,
    metavar="FILE|NAME",
    help="Accuracy requirements: a TOML file with a [requirements] table (spec names and "
    "units; missing ones keep the paper's) or paper, tactical, mems.",
)
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def compare(sequences, profile, latitude, tolerance_deg, requirements, as_json):
    """Analyse several sequences and print their 3 sigma / requirement ratios side by side.

    Given two calibration results (result TOML files) instead, put them side by
    side: each difference against the combined sigma, and a chi-square
    over all of them (the repeatability check of the paper's Table 3).
    """
    from calib.filekind import kind_of
    from calib.profiles import as_profile
    from calib.requirements import load_requirements
    from seqdesign.analysis import analyze as run_analysis
    from seqdesign.analysis import compare_text

    kinds = {kind_of(s) for s in sequences}
    if "result" in kinds:
        if kinds != {"result"} or len(sequences) != 2:
            raise CalibError(
                "compare takes sequences, or exactly two result files",
                "compare",
                "give two results of calibrate (A B), or only sequences",
            )
        from seqdesign.repeatability import compare_results

        rep = compare_results(sequences)
        if as_json:
            emit_json(rep.to_json())
        else:
            click.echo(rep.to_text())
        return

    prof = as_profile(profile)
    req = load_requirements(requirements)
    analyses = [
        run_analysis(s, prof, latitude_deg=latitude, tolerance_deg=tolerance_deg, requirements=req)
        for s in sequences
    ]
    if as_json:
        emit_json({"sequences": [a.to_json() for a in analyses]})
        return
    click.echo(compare_text(analyses))


# ---------------------------------------------------------------------------
# design


@main.command(short_help="Search for a sequence that beats the paper's, robust to the mounting tolerance.")
@click.option(
    "--budget-min",
    type=click.FloatRange(min=0.5),
    default=15.0,
    show_default=True,
    help="Total time budget, minutes.",
)
@click.option(
    "--max-flips",
    type=click.IntRange(min=1),
    default=60,
    show_default=True,
    help="Most moves (continuous turns); the budget ends most walks sooner.",
)
@click.option(
    "--max-quarters",
    type=click.IntRange(min=1),
    default=5,
    show_default=True,
    help="Longest move in quarter turns (5 = a turn and a quarter).",
)
@click.option("--start", default="east,up,south", show_default=True, help="Where X, Y, Z point at the start.")
@click.option("--end", default=None, help='Required final attitude (optional), e.g. "east,up,south".')
@click.option("--axes", default="XYZ", show_default=True, help="Body axes the gimbal may turn about.")
@click.option("--rate-dps", type=float, default=10.0, show_default=True, help="Rotation rate, deg/s.")
@click.option("--min-dwell-s", type=float, default=10.0, show_default=True)
@click.option("--max-dwell-s", type=float, default=300.0, show_default=True)
@click.option(
    "--with",
    "with_terms",
    default=None,
    metavar="TERMS",
    help="Fit these beside the 21 in the objective: lever-arm,k2,time-offset or all.",
)
@click.option(
    "--objective",
    type=click.Choice(["worst", "D", "A", "E"]),
    default="worst",
    show_default=True,
    help="worst 3 sigma/requirement, or D-, A-, E-optimal.",
)
@click.option("--profile", default="navigation", show_default=True, help="Noise profile.")
@click.option(
    "--latitude",
    type=click.FloatRange(-89.0, 89.0),
    default=40.0,
    show_default=True,
    help="Site latitude, deg.",
)
@click.option("--tolerance-deg", type=TOLERANCE, default=3.0, show_default=True)
@click.option(
    "--requirements",
    "requirements",
    default=None,
    metavar="FILE|NAME",
    help="Accuracy requirements: a TOML file with a [requirements] table (spec names and "
    "units; missing ones keep the paper's) or paper, tactical, mems.",
)
@click.option("--beam-width", type=click.IntRange(min=1), default=200, show_default=True)
@click.option("--no-refine", is_flag=True, help="Keep uniform dwells (skip the IPOPT refinement).")
@click.option("-o", "--output", help="Sequence file to write (default: designed-<budget>min.toml).")
@click.option("--pareto", is_flag=True, help="Sweep budgets and print/save the time vs worst-ratio front.")
@click.option(
    "--budgets", default="10,15,20,25,30", show_default=True, help="Budgets (min) of the --pareto sweep."
)
@click.option("--workers", type=click.IntRange(min=1), default=1, show_default=True, help="Local processes.")
@click.option("--scheduler", default=None, help="dask.distributed scheduler address.")
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@click.option(
    "--gimbal",
    "gimbal_file",
    default=None,
    metavar="FILE|NAME",
    help="Only moves this gimbal plays (docs/gimbal.md); --rate-dps defaults to its rate.",
)
@guarded
def design(
    budget_min,
    max_flips,
    max_quarters,
    start,
    end,
    axes,
    rate_dps,
    min_dwell_s,
    max_dwell_s,
    objective,
    profile,
    latitude,
    tolerance_deg,
    requirements,
    beam_width,
    no_refine,
    output,
    pareto,
    budgets,
    workers,
    scheduler,
    as_json,
    with_terms=None,
    gimbal_file=None,
):
    """Search flip walks on the graph of the 24 grid attitudes (beam search with
    incremental information), re-score the finalists exactly at the worst
    case of the mounting tolerance, refine the best's dwells with IPOPT, and
    write it as a sequence file with its provenance.
    """
    from calib.fileio import check_writable_dir
    from seqdesign.search import design_budgets, design_steps, parse_node

    constraints = dict(
        start=parse_node(start, "--start"),
        end=parse_node(end, "--end") if end else None,
        max_flips=max_flips,
        axes=axes.upper(),
        max_quarters=max_quarters,
        rate_dps=rate_dps,
        min_dwell_s=min_dwell_s,
        max_dwell_s=max_dwell_s,
    )
    if (
        gimbal_file
        and click.get_current_context().get_parameter_source("rate_dps") is click.core.ParameterSource.DEFAULT
    ):
        constraints["rate_dps"] = None  # the gimbal's own rate
    from seqdesign.search import resolve_gimbal

    _, constraints = resolve_gimbal(gimbal_file, constraints)  # refused before the search
    sweep = _budgets(budgets) if pareto else [budget_min]
    paths = {b: _design_path(b, output, pareto) for b in sweep}
    for path in set(paths.values()) | ({str(output or "pareto")} if pareto else set()):
        check_writable_dir(path, "-o/--output")  # before minutes of search, not after
    from seqdesign.search import Constraints

    bars = {}

    def progress(b, msg, n):
        if b not in bars:
            info(f"designing for {b:g} min (objective {objective}) ...")
            c = Constraints(budget_s=b * 60.0, **constraints)
            bars[b] = click.progressbar(
                length=design_steps(c, 4),
                label=f"{b:g} min",
                file=sys.stderr,
                item_show_func=lambda m: m,
                show_pos=True,
            )
            bars[b].__enter__()
        bars[b].update(n, msg)

    try:
        report = design_budgets(
            sweep,
            constraints,
            profile,
            latitude_deg=latitude,
            objective=objective,
            tolerance_deg=tolerance_deg,
            beam_width=beam_width,
            refine=not no_refine,
            workers=workers,
            scheduler=scheduler,
            progress=progress,
            requirements=requirements,
            extras=with_terms,
        )
    finally:
        for bar in bars.values():
            bar.__exit__(None, None, None)
    for row in report.rows:
        report.save_design(row, paths[row.budget_min], provenance())
        info(f"wrote {paths[row.budget_min]}")
    if pareto:
        info("wrote " + " and ".join(report.write_pareto(output or "pareto")))
    if as_json:
        emit_json(report.to_json())
        return
    click.echo(report.to_text())


def _budgets(text: str) -> list[float]:
    try:
        return [float(b) for b in text.split(",") if b.strip()]
    except ValueError:
        raise CalibError(f"--budgets {text!r} is not a list of minutes", "--budgets") from None


def _design_path(budget_min: float, output: str | None, pareto: bool) -> str:
    default = f"designed-{budget_min:g}min.toml"
    if pareto:  # every budget's design goes beside the front's files
        return str(Path(output).parent / default) if output else default
    return output or default


# Commands living in their own modules, registered here (before ``__main__`` runs them).
from seqdesign.cli_calibrate import calibrate, calibrate_stream  # noqa: E402
from seqdesign.cli_gimbal import export  # noqa: E402
from seqdesign.cli_profile import profile  # noqa: E402
from seqdesign.cli_stream import simulate_stream  # noqa: E402
from seqdesign.cli_view import view  # noqa: E402

main.add_command(calibrate)
main.add_command(view)
main.add_command(profile)
main.add_command(export)
main.add_command(simulate_stream)
main.add_command(calibrate_stream)


if __name__ == "__main__":
    main()
