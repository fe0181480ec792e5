"""The candidate pipeline after the beams: propose, screen, box, refine, select.

The beams' finalists and their motif repetitions are *proposals*; each is scored
exactly at the nominal mounting (the *screen*), the best :data:`SCREEN_KEEP` over the
whole tolerance box (*boxed*), the best of those IPOPT-refined, and the answers get a
final check with IPOPT looking inside the box (:func:`select`). Every exact score goes
through one :class:`ExactScores`, which runs each distinct job once on the workers.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from calib.analysis.gm_mounting import release_caches
from calib.analysis.worst_case import OptionalTermsCost, Robustness, analyze_extras, analyze_tolerance
from calib.errors import CalibError
from calib.gimbal.rule import plan_sequence
from calib.model import params as P
from calib.model.optional_terms import NONE as NO_EXTRAS, OptionalTerms
from calib.model.requirements import PAPER, Requirements
from calib.nav.site import Site
from calib.noise.profiles import NoiseProfile
from calib.sequence.definition import Sequence

from .constraints import Constraints, to_sequence, turn_seconds
from .graph import Move
from .parallel import map_jobs
from .refine import refine_dwells

MOTIF_REPEATS = (2, 3, 4)  # a finalist's walk also played 2-4 times, with shorter dwells
SCHEDULER_BATCH = 4  # candidates re-scored at once on a dask cluster (its size is unknown here)
SCREEN_KEEP = 6  # candidates re-scored over the whole box after the nominal-mounting screen

# The phases of a design, in order: what each is called and what its best figure is.
PHASES = {
    "search": ("search", "search score"),  # the beams' own model of the objective
    "screen": ("screening", "worst ratio at the nominal mounting"),
    "box": ("worst-case re-scoring", "worst ratio over the tolerance box"),
    "refine": ("refinement", "worst ratio over the box, refined dwells"),
    "check": ("final check", "worst ratio, IPOPT inside the box"),
    "done": ("done", "worst ratio, IPOPT inside the box"),
}


@dataclass(frozen=True)
class Progress:
    """One report of a running design, handed to its ``progress`` callback.

    ``done`` of ``total`` units of the phase's work are finished (candidates, or for the
    search the beams' width x depth); ``scored`` candidates were scored in the phase so
    far; ``best`` is the best figure so far, in the phase's sense (:data:`PHASES`).
    A report with ``done == 0`` starts its phase.
    """

    phase: str
    message: str
    done: int = 0
    total: int = 0
    scored: int = 0
    best: float | None = None


@dataclass(frozen=True)
class Proposal:
    """A walk handed to the exact scoring, at one uniform dwell."""

    walk: tuple[Move, ...]
    dwell_s: float
    repeats: int  # how many times the walk plays its motif (1: a beam's own walk)


@dataclass(frozen=True)
class Finalist:
    """A walk with its dwells and its exact worst ratio: nominal mounting when screened, box after."""

    ratio: float  # worst 3 sigma / requirement of the 21
    label: str  # the walk's moves, "(refined)" after IPOPT
    dwells: tuple[float, ...]  # initial dwell first, s
    walk: tuple[Move, ...]
    repeats: int

    @property
    def order(self) -> tuple[float, str]:
        """Sort key: best ratio first, ties by label."""
        return (self.ratio, self.label)


@dataclass(frozen=True)
class ExactJob:
    """One exact re-scoring: a walk, its dwells, IPOPT inside the box or not, the box half-width."""

    walk: tuple[Move, ...]
    dwells: tuple[float, ...]
    search: bool
    tolerance_deg: float


@dataclass(frozen=True)
class ExactScore:
    """The exact analyser's verdict on an :class:`ExactJob`."""

    ratio: float  # worst 3 sigma / requirement of the 21 (with the extras fitted)
    worst_name: str  # the parameter it belongs to
    robustness: Robustness | None  # None with extras, or kept only after a search
    extras_cost: OptionalTermsCost | None  # with extras
    sequence: Sequence


@dataclass(frozen=True)
class Rescored:
    """A finalist and its exact score (what :func:`pruned` and :func:`select` return)."""

    exact: ExactScore
    finalist: Finalist


def by_order(finalists) -> list[Finalist]:
    """Finalists best first (ratio, then label)."""
    return sorted(finalists, key=lambda f: f.order)


def _exact_worst(
    seq: Sequence,
    profile,
    site: Site,
    tolerance_deg,
    search,
    requirements: Requirements = PAPER,
    extras: OptionalTerms = NO_EXTRAS,
):
    """Worst 3 sigma/requirement of the 21 over the box, with ``extras`` fitted beside them.

    The same figures as ``seqdesign analyze`` (with ``--with``): with ``search``, IPOPT
    then looks inside the box from its worst point. Returns ``(ratio, parameter, Robustness
    or None, OptionalTermsCost or None)``: with ``extras`` the OptionalTermsCost alone (it holds the 21's
    sigma with and without the terms at the same mountings).
    """
    if extras.n:
        cost = analyze_extras(seq, profile, site, extras, tolerance_deg, requirements, search=search)
        r = requirements.ratio(cost.sigma_with)
        i = int(np.argmax(r))
        return float(r[i]), P.NAMES[i], None, cost
    rob = analyze_tolerance(seq, profile, site, tolerance_deg, search=search, requirements=requirements)
    r = rob.per_parameter_worst_ratio
    i = int(np.argmax(r))
    return float(r[i]), P.NAMES[i], rob, None


@dataclass(frozen=True)
class ExactScorer:
    """What the exact re-scoring of a walk needs besides the walk: picklable, so that the
    candidates can be scored on the same workers (or dask cluster) as the beams.
    """

    c: Constraints
    name: str
    written: tuple  # (latitude deg, height m), written into each sequence
    profile: NoiseProfile
    site: Site  # where it is scored: the latitude written, normal gravity at the height written
    requirements: Requirements
    extras: OptionalTerms

    def __call__(self, job: ExactJob) -> ExactScore:
        seq = to_sequence(job.walk, self.c, list(job.dwells), self.name, None, *self.written)
        try:
            worst, wname, rob, cost = _exact_worst(
                seq, self.profile, self.site, job.tolerance_deg, job.search, self.requirements, self.extras
            )
        finally:
            # each job scores its own sequence: its cached basis serves no later job, and the
            # workers are kept for all of a design's rounds (parallel.worker_pool)
            release_caches()
        return ExactScore(worst, wname, rob, cost, seq)


@dataclass
class ExactScores:
    """Exact scores of jobs, each distinct job run once (on the workers) and remembered.

    The narrow beams' candidates are mostly the wide ones': they cost nothing twice.
    """

    scorer: ExactScorer
    workers: int = 1
    scheduler: str | None = None
    memo: dict = field(default_factory=dict)

    def __call__(self, jobs: list[ExactJob]) -> list[ExactScore]:
        todo = list(dict.fromkeys(j for j in jobs if j not in self.memo))
        for job, out in zip(todo, map_jobs(self.scorer, todo, self.workers, self.scheduler), strict=True):
            # without the search inside the box only the figure and the sequence are used
            self.memo[job] = out if job.search else replace(out, robustness=None, extras_cost=None)
        return [self.memo[j] for j in jobs]


def motif_dwell(walk, c: Constraints, repeats: int) -> float | None:
    """Uniform dwell that fits ``repeats`` plays of ``walk`` in the budget (None if none does).

    Why repeat: a Gauss-Markov accelerometer bias looks like a scale factor unless
    gravity changes sign on each axis much faster than its correlation time, and
    playing a good motif several times with short dwells does exactly that.
    """
    n = len(walk) * repeats
    if n > c.max_flips:
        return None
    turn = repeats * sum(turn_seconds(m, c) for m in walk)
    d = math.floor(10.0 * (c.budget_s - turn) / (n + 1)) / 10.0
    if d < c.min_dwell_s:
        return None
    return float(min(d, c.max_dwell_s))


def proposals(results, c: Constraints) -> list[Proposal]:
    """Distinct (walk, dwell) pairs from the beams' results, and each walk's motif repetitions."""
    out, seen = [], set()
    for res in results:
        for walk in res.walks:
            if (walk, res.dwell_s) not in seen:
                seen.add((walk, res.dwell_s))
                out.append(Proposal(walk, res.dwell_s, 1))
    for p in list(out):
        for r in MOTIF_REPEATS:
            d = motif_dwell(p.walk, c, r)
            if d is not None and (p.walk * r, d) not in seen:
                seen.add((p.walk * r, d))
                out.append(Proposal(p.walk * r, d, r))
    if c.gimbal is not None:  # a motif's later plays start where the first ended: replay all
        out = [
            p
            for p in out
            if plan_sequence(to_sequence(p.walk, c, [p.dwell_s] * (len(p.walk) + 1), "x"), c.gimbal).playable
        ]
    return out


def screen(candidates: list[Proposal], exact: ExactScores, progress, chunk: int = 1) -> list[Finalist]:
    """Every proposal scored exactly at the nominal mounting, best first.

    Scored ``chunk`` at a time (the workers' batch) so that progress is reported as it goes;
    each job is computed alone, so the chunks do not change the figures.
    """
    if not candidates:
        raise CalibError(
            "no walk fits the constraints",
            "design",
            "raise --budget-min or --max-flips, or lower --min-dwell-s",
        )
    jobs = [ExactJob(p.walk, (p.dwell_s,) * (len(p.walk) + 1), False, 0.0) for p in candidates]
    n = len(jobs)
    if progress:
        progress(Progress("screen", f"screening {n} candidates at the nominal mounting", 0, n))
    screened: list[Finalist] = []
    for k in range(0, n, max(1, chunk)):
        for p, out in zip(candidates[k : k + chunk], exact(jobs[k : k + chunk]), strict=True):
            label = " ".join(m.label() for m in p.walk)
            screened.append(Finalist(out.ratio, label, (p.dwell_s,) * (len(p.walk) + 1), p.walk, p.repeats))
        if progress:
            progress(
                Progress(
                    "screen",
                    f"screened {len(screened)} of {n} ({len(p.walk)} moves, {p.dwell_s:g} s dwells)",
                    len(screened),
                    n,
                    len(screened),
                    min(f.ratio for f in screened),
                )
            )
    return by_order(screened)


def pruned(order, score, batch: int):
    """Score entries (sorted by a lower bound ``f.ratio`` of their score) ``batch`` at a time,
    skipping those whose bound is not below the best score so far.

    ``score(entries)`` returns one result per entry, each with a ``ratio``. Returns
    ``(best, scored)``: ``best`` the :class:`Rescored` of the best score (ties by
    ``label``), ``scored`` every :class:`Rescored`, in order. Exact: ``score(f).ratio >=
    f.ratio`` for every entry.
    """
    best, scored, k = None, [], 0
    while k < len(order):
        todo = [
            f
            for f in order[k : k + batch]
            if best is None or (f.ratio, f.label) < (best.exact.ratio, best.finalist.label)
        ]
        k += batch
        if not todo:
            break  # sorted by bound: nothing later can win either
        for f, out in zip(todo, score(todo), strict=True):
            scored.append(Rescored(out, f))
            if best is None or (out.ratio, f.label) < (best.exact.ratio, best.finalist.label):
                best = Rescored(out, f)
    return best, scored


def boxed(screened, exact: ExactScores, tolerance_deg, progress, batch: int = 1) -> list[Finalist]:
    """The best of the :data:`SCREEN_KEEP` screened candidates, worst over the box, best first.

    The nominal mounting is one of the box's points, so a candidate's nominal figure is
    a lower bound of its box figure: one whose nominal figure is not below the best box
    figure so far cannot come first and is not re-scored (only the first is used).
    """
    top = screened[:SCREEN_KEEP]
    n = len(top)
    if progress:
        progress(Progress("box", f"worst-case re-scoring of the best {n} over +-{tolerance_deg:g} deg", 0, n))
    pool: list[Finalist] = []

    def score(fs):
        out = exact([ExactJob(f.walk, f.dwells, False, tolerance_deg) for f in fs])
        pool.extend(replace(f, ratio=o.ratio) for f, o in zip(fs, out, strict=True))
        if progress:
            progress(
                Progress(
                    "box",
                    f"re-scored {len(pool)} of {n} over the box",
                    len(pool),
                    n,
                    len(pool),
                    min(p.ratio for p in pool),
                )
            )
        return out

    _, scored = pruned(top, score, batch)
    if progress and len(scored) < n:
        progress(
            Progress(
                "box",
                f"{n - len(scored)} candidates skipped: their nominal figure is "
                f"already above the best box worst",
                n,
                n,
                len(pool),
                min(p.ratio for p in pool),
            )
        )
    return by_order(pool)


def refined(best: Finalist, c, site: Site, profile, objective, requirements, exact, progress):
    """The best candidate with IPOPT-refined dwells, exactly re-scored ([] if unchanged).

    ``site`` the latitude and gravity the search scores at; ``exact(walk, dwells)`` is the
    :class:`ExactScore` over the box.
    """
    if progress:
        progress(Progress("refine", f"refining the dwells of {best.label} with IPOPT", 0, 1, 0, best.ratio))
    new_dwells, _, _ = refine_dwells(
        best.walk, c, best.dwells[0], site, profile, objective, requirements, best.repeats
    )
    if tuple(new_dwells) == best.dwells:
        if progress:
            progress(Progress("refine", "refinement kept the uniform dwells", 1, 1, 1, best.ratio))
        return []
    out = exact(best.walk, tuple(new_dwells))
    if progress:
        progress(
            Progress(
                "refine",
                f"refined: {out.ratio:.3f} ({out.worst_name}) against {best.ratio:.3f} uniform",
                1,
                1,
                1,
                min(out.ratio, best.ratio),
            )
        )
    return [Finalist(out.ratio, best.label + " (refined)", tuple(new_dwells), best.walk, best.repeats)]


@dataclass
class Pipeline:
    """Screen, box and refine the proposals of a set of beams, sharing the exact scores."""

    c: Constraints
    exact: ExactScores
    tolerance_deg: float
    batch: int
    progress: object
    refine: Callable[[Finalist], list[Finalist]] | None = None  # None: --no-refine
    _refined: dict = field(default_factory=dict)

    def pools(self, results) -> tuple[list[Finalist], list[Finalist]]:
        """``(pool, with_refined)``: the box scores best first, and the same with the refined best."""
        return self.with_refined(self.boxed_pool(results))

    def boxed_pool(self, results) -> list[Finalist]:
        """The beams' proposals screened, the best re-scored over the box: best first."""
        # chunks of the batch, several per map on the workers (progress said between maps)
        chunk = self.batch if self.batch == 1 else 4 * self.batch
        found = screen(proposals(results, self.c), self.exact, self.progress, chunk)
        return boxed(found, self.exact, self.tolerance_deg, self.progress, self.batch)

    def with_refined(self, pool: list[Finalist]) -> tuple[list[Finalist], list[Finalist]]:
        """``(pool, pool with its best refined)``; a best refined before is not refined again."""
        key = (pool[0].walk, pool[0].dwells)
        if self.refine is not None and key not in self._refined:
            self._refined[key] = self.refine(pool[0])
        extra = self._refined[key] if self.refine is not None else []
        return pool, by_order(pool + extra)


def select(answers, exact: ExactScores, tolerance_deg, batch: int = 1, progress=None) -> Rescored:
    """The final check (IPOPT inside the box) of each distinct answer; the best final figure.

    The search inside the box can only raise an answer's box figure (``ratio``), so an
    answer whose box figure is not below the best final figure so far cannot win and
    is not checked; answers go best box figure first, ``batch`` at a time (the workers).
    """
    first: dict[tuple, Finalist] = {}
    for f in answers:
        first.setdefault((f.walk, f.dwells), f)
    order = by_order(first.values())
    n, finals = len(order), []
    if progress:
        progress(Progress("check", f"final check of {n} answers (IPOPT inside the box)", 0, n))

    def score(fs):
        out = exact([ExactJob(f.walk, f.dwells, True, tolerance_deg) for f in fs])
        finals.extend(o.ratio for o in out)
        if progress:
            progress(
                Progress("check", f"checked {len(finals)} of {n}", len(finals), n, len(finals), min(finals))
            )
        return out

    return pruned(order, score, batch)[0]
