"""The whole design: beams at a few dwells, exact re-scoring of their walks, refinement of the best.

The search model ranks walks (:mod:`.beam`); the walks it proposes are then
re-scored with the exact analyser, worst case over the mounting tolerance, which
is the figure reported (:mod:`.pipeline`).
"""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

from calib.analysis.worst_case import OptionalTermsCost, Robustness
from calib.errors import CalibError
from calib.nav.site import Site
from calib.noise.profiles import NoiseProfile
from calib.noise.wander import check_wander
from calib.sequence.definition import Sequence

from .beam import BeamJob, search_at_dwell
from .constraints import Constraints, DesignOptions, check_constraints, uniform_dwell
from .gimbal import check_sequence_plays
from .objective import OBJECTIVES
from .parallel import map_jobs, worker_pool
from .pipeline import (
    SCHEDULER_BATCH,
    ExactJob,
    ExactScorer,
    ExactScores,
    Finalist,
    Pipeline,
    Progress,
    by_order,
    refined,
    select,
)

SHORT_WALK_FLIPS = 10  # the classic space: up to 10 moves at long dwells
# Many short moves: beams at these dwells walk until the budget is spent.
# Under Gauss-Markov accelerometer bias they win: gravity must reverse on each axis
# much faster than tau, and 450 deg turns sweep it round while turning.
LONG_WALK_DWELLS_S = (10.0, 15.0, 20.0)
NARROW_BEAM = 20


@dataclass
class DesignResult:
    """A designed sequence and the figures that justify it."""

    sequence: Sequence
    worst_ratio: float  # exact, worst case over the tolerance box
    worst_name: str
    uniform_worst_ratio: float  # exact, same walk with uniform dwells
    evaluated: int  # candidates scored by the search
    search_seconds: float
    finalists: list[Finalist]  # every candidate re-scored over the box, best first
    robustness: Robustness | None  # of the 21 alone (None with --with)
    extras_cost: OptionalTermsCost | None = None  # of the winner when --with was given
    repeats: int = 1  # how many times the winner plays its motif


def search_dwells(c: Constraints) -> list[float]:
    """Uniform dwells the search tries.

    Those fitting roughly 10, 6 and 5 moves of three quarter turns (few moves, long
    dwells), and, when ``max_flips`` allows more than 10 moves, the short dwells of
    :data:`LONG_WALK_DWELLS_S` (many moves; each beam walks until the budget is spent).
    """
    n = min(c.max_flips, SHORT_WALK_FLIPS)
    counts = sorted({n, max(1, (2 * n) // 3), max(1, n // 2)})
    out = {round(uniform_dwell(c, k, 3.0), 1) for k in counts}
    if c.max_flips > SHORT_WALK_FLIPS:
        out |= {d for d in LONG_WALK_DWELLS_S if c.min_dwell_s <= d <= c.max_dwell_s}
    return sorted(out)


def _beam_widths(beam_width: int | None) -> list:
    """Beams to run: the one asked for and, when wider, a beam of 20 too.

    The search score is not the exact worst case over the box, so a narrow beam can
    hand a different (sometimes better) walk to the exact re-scoring; running both
    makes more effort never give a worse answer.
    """
    if beam_width is None or beam_width <= NARROW_BEAM:
        return [beam_width]
    return [NARROW_BEAM, beam_width]


def beam_effort(job: BeamJob) -> int:
    """Rough work of a beam, for the time left of the search: its width times the moves that fit.

    Candidates scored grow as width x depth; the time per candidate is measured as the
    search goes (the progress report), so only the proportions between beams matter here.
    """
    c = job.constraints
    depth = min(c.max_flips, max(1, int(c.budget_s // max(job.dwell_s, 1.0))))
    return depth * (job.beam_width if job.beam_width is not None else 1000)


def _best_score(results) -> float | None:
    """The best search score of the beams run so far (None before any walk)."""
    best = [r.scores[0] for r in results if r.scores]
    return min(best) if best else None


def _serial_search(jobs: list[BeamJob], efforts: list[int], progress) -> list:
    """The beams one at a time (what :func:`map_jobs` does serially), each reported as it ends."""
    results: list = []
    for k, job in enumerate(jobs):
        results.append(search_at_dwell(job))
        progress(
            Progress(
                "search",
                f"search at dwell {job.dwell_s:g} s, width {job.beam_width}: beam {k + 1} of {len(jobs)}",
                sum(efforts[: k + 1]),
                sum(efforts),
                sum(r.evaluated for r in results),
                _best_score(results),
            )
        )
    return results


def _search(base: BeamJob, workers, scheduler, progress):
    """Run every beam (``base`` at each search dwell and beam width); returns ``(results,
    evaluated, narrow)``, ``narrow`` the results of the beams of 20 alone (None when that is
    all there is).
    """
    c, beam_width = base.constraints, base.beam_width
    jobs = [
        replace(base, dwell_s=d, beam_width=bw) for d in search_dwells(c) for bw in _beam_widths(beam_width)
    ]
    efforts = [beam_effort(j) for j in jobs]
    if progress:
        where = f" on {workers} workers" if workers > 1 else (" on the dask cluster" if scheduler else "")
        progress(
            Progress(
                "search",
                f"searching {len(jobs)} beams{where} (widths {_beam_widths(beam_width)}, dwells "
                f"{search_dwells(c)} s, up to {c.max_flips} moves of up to {c.max_quarters} quarter turns)",
                0,
                sum(efforts),
            )
        )
    if workers > 1 or scheduler or not progress:
        results = map_jobs(search_at_dwell, jobs, workers, scheduler)
    else:  # one beam at a time (what map_jobs does serially), each reported
        results = _serial_search(jobs, efforts, progress)
    evaluated = sum(r.evaluated for r in results)
    if progress and (workers > 1 or scheduler):
        progress(Progress("search", f"searched {len(jobs)} beams", 1, 1, evaluated, _best_score(results)))
    narrow = None
    if len(_beam_widths(beam_width)) > 1:
        narrow = [r for r, j in zip(results, jobs, strict=True) if j.beam_width == NARROW_BEAM]
    return results, evaluated, narrow


def design(
    c: Constraints,
    profile: NoiseProfile,
    options: DesignOptions | None = None,
    *,
    height_m: float = 0.0,
    keep: int = 4,
    name: str = "designed",
    progress=None,
) -> DesignResult:
    """Search walks, re-score every candidate exactly over the tolerance box, refine the best.

    The candidates are the beams' finalists and their motif repetitions; each is
    re-scored exactly (27 box points, ``options.extras`` fitted beside the 21), the best is
    IPOPT-refined. What ``--beam-width 20`` and ``--no-refine`` would answer comes from the
    same beams and gets the same final check; the best final figure wins
    (:func:`seqdesign.search.pipeline.select`).

    Parameters
    ----------
    c : Constraints
        What is fixed about the design (its ``budget_s`` the budget).
    profile : NoiseProfile
        The noise the design is optimised for.
    options : DesignOptions, optional
        Site latitude, objective, tolerance, beam width, refinement, workers, requirements
        and extra terms.
    height_m : float
        Site height, m.
    keep : int
        Finalists each beam hands to the exact re-scoring.
    name : str
        The designed sequence's name.
    progress : callable, optional
        ``progress(report)``: a :class:`~seqdesign.search.pipeline.Progress` at each phase's
        start and as it goes (search, screen, box, refine, check, done).

    Returns
    -------
    DesignResult
    """
    options = options or DesignOptions()
    objective, tolerance_deg, workers, scheduler = (
        options.objective,
        options.tolerance_deg,
        options.workers,
        options.scheduler,
    )
    requirements, extras = options.judged_by()
    _check_design_args(c, objective)
    # A budget whose attitude wander the fit cannot follow would be designed for sigmas no
    # calibration achieves (calib.noise.wander.MAX_WANDER_DEG).
    check_wander(profile, c.budget_s, "--budget-min")
    t0 = time.perf_counter()
    latitude_rad = math.radians(options.latitude_deg)
    written = (math.degrees(latitude_rad), height_m)  # written into the sequence: analyse it there
    scoring = Site.at(latitude_rad, height_m)
    # one beam per search dwell and width (_search sets them)
    base = BeamJob(c, math.nan, scoring, profile, objective, options.beam_width, keep, requirements)
    results, evaluated, narrow = _search(base, workers, scheduler, progress)
    search_seconds = time.perf_counter() - t0
    scorer = ExactScorer(c, name, written, profile, scoring, requirements, extras)
    batch = max(workers, SCHEDULER_BATCH if scheduler else 1)
    exact = ExactScores(scorer, workers, scheduler)

    def refine_best(best: Finalist) -> list[Finalist]:
        return refined(
            best,
            c,
            scoring,
            profile,
            objective,
            requirements,
            lambda w, d: exact([ExactJob(w, d, False, tolerance_deg)])[0],
            progress,
        )

    # One pool of workers for every exact-scoring round (parallel.worker_pool); not for the
    # search, whose workers cache every segment of the walk graph (~1 GB each at 30 min)
    with worker_pool(workers if scheduler is None else 1):
        pipeline = Pipeline(c, exact, tolerance_deg, batch, progress, refine_best if options.refine else None)
        n_boxed: list[Finalist] | None = None
        if narrow is not None and options.refine and workers > 1 and scheduler is None:
            # The wide beams' refinement (serial IPOPT in this process) beside the narrow beams'
            # screen and box (on the workers): the same jobs, the same answers, no idle core.
            boxed = pipeline.boxed_pool(results)
            with ThreadPoolExecutor(1) as beside:
                wide = beside.submit(pipeline.with_refined, boxed)
                n_boxed = pipeline.boxed_pool(narrow)
                unrefined, pool = wide.result()
        else:
            unrefined, pool = pipeline.pools(results)
            n_boxed = pipeline.boxed_pool(narrow) if narrow is not None else None
        answers = [pool[0], unrefined[0]]  # the default's, and what --no-refine returns
        if n_boxed is not None:  # what --beam-width 20 (with and without --no-refine) returns
            n_unrefined, n_pool = pipeline.with_refined(n_boxed)
            pool = by_order(pool + n_pool)
            answers += [pool[0], n_pool[0], n_unrefined[0]]
        best = select(answers, exact, tolerance_deg, batch, progress)
    winner = best.exact
    check_sequence_plays(winner.sequence, c.gimbal)
    if progress:
        progress(
            Progress(
                "done",
                f"best of {len(pool)}: {best.finalist.label}; worst case over +-{tolerance_deg:g} deg: "
                f"{winner.ratio:.3f} ({winner.worst_name})",
                1,
                1,
                0,
                winner.ratio,
            )
        )
    return DesignResult(
        sequence=winner.sequence,
        worst_ratio=winner.ratio,
        worst_name=winner.worst_name,
        uniform_worst_ratio=unrefined[0].ratio,
        evaluated=evaluated,
        search_seconds=search_seconds,
        finalists=pool,
        robustness=winner.robustness,
        extras_cost=winner.extras_cost,
        repeats=best.finalist.repeats,
    )


def _check_design_args(c: Constraints, objective: str) -> None:
    check_constraints(c)
    if objective not in OBJECTIVES:
        raise CalibError(
            f"unknown objective {objective!r}", "objective (the CLI's --objective)", "use worst, D, A or E"
        )
