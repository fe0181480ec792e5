"""``seqdesign design``: search, re-score and refine sequences for a time budget."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from calib.errors import CalibError

from . import options
from .tools import emit_json, guarded, info, provenance


@click.command(short_help="Search for a sequence that beats the paper's, robust to the mounting tolerance.")
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
@options.with_terms("Fit these beside the 21 in the objective: lever-arm,k2,time-offset or all.")
@click.option(
    "--objective",
    type=click.Choice(["worst", "D", "A", "E"]),
    default="worst",
    show_default=True,
    help="worst 3 sigma/requirement, or D-, A-, E-optimal.",
)
@options.profile()
@options.latitude("Site latitude, deg.", default=40.0)
@options.tolerance()
@options.requirements
@click.option("--beam-width", type=click.IntRange(min=1), default=200, show_default=True)
@click.option("--no-refine", is_flag=True, help="Keep uniform dwells (skip the IPOPT refinement).")
@click.option("-o", "--output", help="Sequence file to write (default: designed-<budget>min.toml).")
@click.option("--pareto", is_flag=True, help="Sweep budgets and print/save the time vs worst-ratio front.")
@click.option(
    "--budgets", default="10,15,20,25,30", show_default=True, help="Budgets (min) of the --pareto sweep."
)
@click.option("--workers", type=click.IntRange(min=1), default=1, show_default=True, help="Local processes.")
@click.option("--scheduler", default=None, help="dask.distributed scheduler address.")
@options.as_json
@options.gimbal(
    "Only moves this gimbal plays (docs/gimbal.md); --rate-dps defaults to its rate.", metavar="FILE|NAME"
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
