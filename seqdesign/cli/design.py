"""``seqdesign design``: search, re-score and refine sequences for a time budget."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import click

from calib.errors import CalibError

from . import options
from .tools import emit_json, guarded, info, provenance

if TYPE_CHECKING:  # the search is imported when a design runs, not for --help
    from seqdesign.search import Progress

PROGRESS_EVERY_S = 2.0  # at most one progress line this often, besides each phase's first


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
@click.option(
    "--min-dwell-s",
    type=float,
    default=10.0,
    show_default=True,
    help="Shortest rest between moves, s: the floor of every dwell the search and the refinement use.",
)
@click.option(
    "--max-dwell-s",
    type=float,
    default=300.0,
    show_default=True,
    help="Longest rest between moves, s: the ceiling of every dwell.",
)
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
@options.tolerance(
    "Mounting tolerance, deg: the finalists are re-scored at the worst mounting within +-this "
    "on each axis (0: the nominal mounting only)."
)
@options.requirements
@click.option(
    "--beam-width",
    type=click.IntRange(min=1),
    default=200,
    show_default=True,
    help="Partial walks the beam search keeps at each depth; wider searches more and takes longer "
    "(a beam of 20 runs beside it, so more never answers worse).",
)
@click.option("--no-refine", is_flag=True, help="Keep uniform dwells (skip the IPOPT refinement).")
@click.option(
    "-o",
    "--output",
    help="Sequence file to write (default: <name>.toml); its stem names the design. With --pareto: "
    "the stem of the front's CSV and PNG, the designs beside it as <stem>-<budget>min.toml.",
)
@click.option(
    "--name",
    default=None,
    help="The design's sequence name (default: the stem of -o, else designed-<budget>min); "
    "with --pareto each is <name>-<budget>min.",
)
@click.option("--pareto", is_flag=True, help="Sweep budgets and print/save the time vs worst-ratio front.")
@click.option(
    "--budgets", default="10,15,20,25,30", show_default=True, help="Budgets (min) of the --pareto sweep."
)
@click.option("--workers", type=click.IntRange(min=1), default=1, show_default=True, help="Local processes.")
@click.option("--scheduler", default=None, help="dask.distributed scheduler address.")
@click.option(
    "--by-hand",
    is_flag=True,
    help="Design a run placed by hand instead (docs/by-hand.md): the poses, their order and holds "
    "within --budget-min, written as a pose list (-o) and a printable protocol (--protocol).",
)
@click.option(
    "--move-s", type=click.FloatRange(0.5, 60.0), default=3.0, show_default=True, help="--by-hand: a move, s."
)
@click.option(
    "--min-hold-s",
    type=click.FloatRange(1.0, 600.0),
    default=5.0,
    show_default=True,
    help="--by-hand: shortest hold, s.",
)
@click.option(
    "--first-rest-s",
    type=click.FloatRange(1.0, 3600.0),
    default=30.0,
    show_default=True,
    help="--by-hand: the static start, s.",
)
@click.option(
    "--pose-set",
    type=click.Choice(["grid", "cube", "icosahedron"]),
    default="grid",
    show_default=True,
    help="--by-hand: candidate poses (grid: faces, edges and corners of a box).",
)
@click.option(
    "--protocol", "protocol_path", metavar="FILE.md", help="--by-hand: also write the protocol (and its PNG)."
)
@options.as_json
@options.gimbal("Only moves this gimbal plays; --rate-dps defaults to its rate.")
@guarded
# over 8 parameters: a click command, whose options arrive one parameter each
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
    name,
    pareto,
    budgets,
    workers,
    scheduler,
    as_json,
    by_hand=False,
    move_s=3.0,
    min_hold_s=5.0,
    first_rest_s=30.0,
    pose_set="grid",
    protocol_path=None,
    with_terms=None,
    gimbal_file=None,
):
    """Search flip walks on the graph of the 24 grid attitudes (beam search with
    incremental information), re-score the finalists exactly at the worst
    case of the mounting tolerance, refine the best's dwells with IPOPT, and
    write it as a sequence file with its provenance.
    """
    if by_hand:
        from seqdesign.hand.pose_search import HandDesignOptions

        from .designhand import design_by_hand

        hand = HandDesignOptions(
            move_s=move_s,
            min_hold_s=min_hold_s,
            first_rest_s=first_rest_s,
            pose_set=pose_set,
            latitude_deg=latitude,
        )
        doc, text = design_by_hand(
            budget_min, hand, profile, requirements, with_terms, output, name, protocol_path
        )
        if as_json:
            emit_json(doc)
            return
        click.echo(text)
        return
    from calib.io.files import check_writable_dir
    from seqdesign.search import DesignOptions, design_budgets, parse_node
    from seqdesign.search.report import design_names

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
    from seqdesign.search import gimbal_constraints

    _, constraints = gimbal_constraints(gimbal_file, constraints)  # refused before the search
    sweep = _budgets(budgets) if pareto else [budget_min]
    profile, requirements = _say_the_bounds(profile, requirements, latitude, sweep)
    base = name if name is not None else (_stem(output) if output else None)
    names = design_names(sweep, base)
    paths = {b: _design_path(names[b], output, pareto) for b in sweep}
    for path in set(paths.values()) | ({str(output or "pareto")} if pareto else set()):
        check_writable_dir(path, "-o/--output")  # before minutes of search, not after
    started = set()
    lines = ProgressLines()

    def progress(b, report):
        if b not in started:
            started.add(b)
            info(f"designing {names[b]} for {b:g} min (objective {objective}) ...")
        lines(b, report)

    chosen = DesignOptions(
        latitude_deg=latitude,
        objective=objective,
        tolerance_deg=tolerance_deg,
        beam_width=beam_width,
        refine=not no_refine,
        workers=workers,
        scheduler=scheduler,
        requirements=requirements,
        extras=with_terms,
    )
    report = design_budgets(sweep, constraints, profile, chosen, progress=progress, name=base)
    _refuse_unobservable(report, requirements)
    for row in report.rows:
        report.save_design(row, paths[row.budget_min], provenance())
        info(f"wrote {paths[row.budget_min]}")
    if pareto:
        info("wrote " + " and ".join(report.write_pareto(output or "pareto")))
    if as_json:
        emit_json(report.to_json())
        return
    click.echo(report.to_text())


def _say_the_bounds(profile, requirements, latitude, budgets_min):
    """The profile and the requirements to design for, after saying what no design can meet.

    Without ``--requirements`` the profile's grade gives them (and it is said). A
    requirement that no sequence of a budget can meet (a bound of :mod:`calib.analysis.bounds`:
    a MEMS gyro's bias wander, gravity the only excitation of the accelerometer scale
    factors) is said before the minutes of search, with the length that would meet it.
    """
    from calib.analysis.bounds import unreachable
    from calib.model.requirements import default_for, load_requirements
    from calib.nav import earth
    from calib.noise.profiles import load_profile

    prof = load_profile(profile)
    requirements, chosen = default_for(prof, requirements)
    if chosen:
        info(chosen)
    req = load_requirements(requirements)
    earth.check_site(latitude, 0.0)
    g = earth.gravity(math.radians(latitude))
    for b in budgets_min:
        for bound in unreachable(b * 60.0, prof, g, req):
            info(f"warning: {bound.text(b * 60.0)}")
    return prof, req


def _refuse_unobservable(report, requirements) -> None:
    """Refuse designs that leave a parameter not estimable at the requirements' scale.

    Judged against requirements far below the unit's own sigmas (a MEMS unit against the
    paper's navigation-grade ones: 3 sigma / requirement in the thousands), every candidate
    scores inf and the search has nothing to choose by: the walk it returns is arbitrary.
    """
    for row in report.rows:
        if not math.isfinite(row.result.worst_ratio):
            name = getattr(requirements, "name", requirements) or "paper"
            raise CalibError(
                f"no {row.budget_min:g}-min design estimates {row.result.worst_name} at the scale "
                f"of the requirements '{name}' under profile {report.profile.name}: every "
                "candidate scores inf, so there is nothing to choose by",
                "--requirements",
                "judge the unit against requirements of its grade (`--requirements mems` for a "
                "MEMS unit, or your own file), or give a longer budget",
            )


def _budgets(text: str) -> list[float]:
    try:
        return [float(b) for b in text.split(",") if b.strip()]
    except ValueError:
        raise CalibError(f"--budgets {text!r} is not a list of minutes", "--budgets") from None


def _stem(output: str) -> str:
    """The name an output file gives a design: ``mine.toml`` -> ``mine``."""
    return Path(output).name.removesuffix(".toml")


def _design_path(name: str, output: str | None, pareto: bool) -> str:
    """Where a design goes: ``-o`` itself, else ``<name>.toml`` (with --pareto, beside -o)."""
    if pareto:  # every budget's design goes beside the front's files
        return str(Path(output).parent / f"{name}.toml") if output else f"{name}.toml"
    return output or f"{name}.toml"


def _duration(seconds: float) -> str:
    """``95`` -> ``1 min 35 s``: a duration a user reads at a glance."""
    s = int(round(seconds))
    return f"{s // 60} min {s % 60:02d} s" if s >= 60 else f"{s} s"


@dataclass
class ProgressLines:
    """A design's progress as lines on stderr: each phase's start, and between, at most one line
    every ``every_s`` seconds with the candidates scored per second, the best figure so far and
    the time left in the phase.

    The time left is the phase's pace so far times the work it has left (candidates; for the
    search, the beams' width x depth, since a beam's work grows with both); the phases to come
    are named, not timed, because their work is known only when they start.
    """

    clock: Callable[[], float] = time.monotonic
    every_s: float = PROGRESS_EVERY_S
    _phase: tuple | None = None
    _phase_t0: float = 0.0
    _t0: dict = field(default_factory=dict)  # when each budget's design started
    _last: float = -math.inf

    def __call__(self, budget_min: float, r: Progress) -> None:
        now = self.clock()
        t0 = self._t0.setdefault(budget_min, now)
        if (budget_min, r.phase) != self._phase:  # a new phase: always said
            self._phase, self._phase_t0, self._last = (budget_min, r.phase), now, now
            info(f"[{budget_min:g} min] {r.message} (at {_duration(now - t0)})")
            return
        if now - self._last < self.every_s:
            return
        self._last = now
        info(f"[{budget_min:g} min] " + "; ".join(self.status(r, now - self._phase_t0)))

    def status(self, r: Progress, elapsed: float) -> list[str]:
        """The parts of a progress line: what was done, pace, best so far, time left."""
        from seqdesign.search.pipeline import PHASES

        parts = [r.message]
        if r.scored and elapsed > 0:
            rate = r.scored / elapsed
            parts.append(f"{rate:.0f} candidates/s" if rate >= 1 else f"{1 / rate:.1f} s per candidate")
        if r.best is not None:
            parts.append(f"best so far {r.best:.3f} ({PHASES[r.phase][1]})")
        if 0 < r.done < r.total:
            left = elapsed * (r.total - r.done) / r.done
            later = [title for title, _ in list(PHASES.values())[list(PHASES).index(r.phase) + 1 : -1]]
            parts.append(
                f"about {_duration(left)} left in this phase (its pace so far)"
                + (f", then {', '.join(later)}" if later else "")
            )
        return parts
