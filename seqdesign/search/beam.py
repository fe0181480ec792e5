"""The beam search over flip walks: candidates, the precomputed search model, and brute force for tests."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from calib.model.requirements import PAPER, Requirements
from calib.nav.jacobian import N_UNKNOWN
from calib.nav.site import Site
from calib.noise.gm_filter import gm_start_covariance
from calib.noise.profiles import NoiseProfile

from .constraints import Constraints, turn_rate, turn_seconds
from .gimbal import at_home, home_reachable, next_encoders
from .gm import SegmentColumns, fold, fold_block, segment_blocks, stack, start_state, then
from .graph import Move, Node, apply_move, as_node, attitude_of, flip_graph, moves as all_moves
from .objective import score
from .segments import (
    SEARCH_REST_INTERVALS,
    SegmentEffect,
    rest_at,
    rest_columns,
    rest_steady_state,
    segment_effect,
    start_covariance,
    turn_columns,
    turn_from,
)


@dataclass
class Candidate:
    """A walk being searched: its moves, where it ends, its segment state and information."""

    walk: tuple[Move, ...]
    node: Node
    X: np.ndarray
    N: np.ndarray
    time_s: float
    score: float = math.inf
    P: np.ndarray | None = None  # filter covariance (exact-noise search only)
    enc: tuple | None = None  # encoder angles (rad, continuous) with a gimbal
    label: str = ""  # the moves' labels joined by spaces (the ranking's tie-break), grown move by move


def _segments(c: Constraints, dwell_s: float, site: Site, profile: NoiseProfile, graph, moves):
    """The initial rest's, every rest's and every turn's :class:`SegmentEffect` (white noise)."""
    P_ss = rest_steady_state(site, profile, dwell_s)
    rest = {
        node: segment_effect(
            rest_at(node, dwell_s),
            site,
            profile,
            start_covariance(P_ss, attitude_of(node)),
            SEARCH_REST_INTERVALS,
        )
        for node in graph.nodes
    }
    initial = segment_effect(
        rest_at(c.start, dwell_s), site, profile, None, SEARCH_REST_INTERVALS, initial=True
    )
    turn = {}
    for node in graph.nodes:
        C = attitude_of(node)
        for mv in moves:
            seg = turn_from(node, mv, turn_seconds(mv, c), turn_rate(mv, c))
            turn[(node, mv)] = segment_effect(seg, site, profile, start_covariance(P_ss, C))
    return initial, rest, turn


def _exact_segments(c: Constraints, dwell_s: float, site: Site, profile: NoiseProfile, graph, moves):
    """The initial rest's, every rest's and every turn's observation columns (GM: exact noise)."""
    rest = {node: rest_columns(node, dwell_s, site, profile) for node in graph.nodes}
    turn = {
        (node, mv): turn_columns(node, mv, turn_seconds(mv, c), turn_rate(mv, c), site, profile)
        for node in graph.nodes
        for mv in moves
    }
    return rest[as_node(c.start)], rest, turn


@dataclass
class SearchModel:
    """Everything a search at one dwell needs, precomputed."""

    constraints: Constraints
    dwell_s: float
    site: Site
    profile: NoiseProfile
    graph: object
    moves: list[Move]
    initial: SegmentEffect | SegmentColumns  # SegmentColumns with exact_noise
    rest: dict
    turn: dict = field(default_factory=dict)
    requirements: Requirements = PAPER
    exact_noise: bool = False  # GM: each candidate carries its filter covariance (gmsearch)

    @classmethod
    def build(
        cls,
        c: Constraints,
        dwell_s: float,
        site: Site,
        profile: NoiseProfile,
        requirements: Requirements = PAPER,
    ) -> SearchModel:
        """The search model at one uniform dwell: every segment of the walk graph, precomputed.

        Under a GM profile the segments are observation columns, each candidate carrying
        its filter covariance (:func:`_exact_segments`); else the segment matrices with
        the filter at its rest steady state (:func:`_segments`).
        """
        graph = flip_graph(c.start, c.axes)
        moves = all_moves(c.axes, c.max_quarters)
        exact = profile.has_gauss_markov
        initial, rest, turn = (_exact_segments if exact else _segments)(
            c, dwell_s, site, profile, graph, moves
        )
        return cls(c, dwell_s, site, profile, graph, moves, initial, rest, turn, requirements, exact)

    def turn_time(self, mv: Move) -> float:
        return turn_seconds(mv, self.constraints)

    def start_candidate(self) -> Candidate:
        """After the initial rest (its effect already holds the run's start state)."""
        if self.exact_noise:
            X, N, P0 = start_state(gm_start_covariance(self.profile), N_UNKNOWN)
            assert isinstance(self.initial, SegmentColumns)  # as _exact_segments makes it (SearchModel.build)
            X, N, P0 = fold(self.initial, X[None], N[None], P0[None])
            return Candidate(
                walk=(),
                node=as_node(self.constraints.start),
                X=X[0],
                N=N[0],
                time_s=self.dwell_s,
                P=P0[0],
                enc=self._enc0(),
            )
        e = self.initial
        assert isinstance(e, SegmentEffect)  # as build makes it without exact_noise
        return Candidate(
            walk=(),
            node=as_node(self.constraints.start),
            X=e.B.copy(),
            N=e.M3.copy(),
            time_s=self.dwell_s,
            enc=self._enc0(),
        )

    def _enc0(self):
        return None if self.constraints.gimbal is None else (0.0, 0.0, 0.0)

    def _gimbal_child(self, par: Candidate, mv: Move, t: float):
        """``(True, encoders)`` after ``mv`` when the gimbal plays it and can still get home."""
        c = self.constraints
        if c.gimbal is None:
            return True, None
        assert par.enc is not None  # _enc0 starts every walk with encoders when there is a gimbal
        enc = next_encoders(c, par.enc, mv)
        if "_min_turn" not in self.__dict__:
            self.__dict__["_min_turn"] = min(self.turn_time(m) for m in self.moves)
        quarter = self.__dict__["_min_turn"]
        ok = enc is not None and home_reachable(c, enc, len(par.walk) + 1, t, quarter)
        return ok, enc

    def extend(self, parents: list[Candidate], objective: str, prior: bool = True) -> list[Candidate]:
        """All feasible children of ``parents``, scored (batched)."""
        c = self.constraints
        kids, effs, keys = [], [], []
        # per move, once per step (not per parent): its time and label
        step = {mv: (self.turn_time(mv), mv.label()) for mv in self.moves}
        for par in parents:
            if len(par.walk) >= c.max_flips:
                continue
            for mv in self.moves:
                turn, label = step[mv]
                t = par.time_s + turn + self.dwell_s
                if t > c.budget_s + 1e-9:
                    continue
                ok, enc = self._gimbal_child(par, mv, t)
                if not ok:
                    continue
                end = apply_move(self.graph, par.node, mv)
                label = f"{par.label} {label}" if par.walk else label
                kids.append(Candidate(par.walk + (mv,), end, par.X, par.N, t, P=par.P, enc=enc, label=label))
                keys.append((par.node, mv))
                if not self.exact_noise:
                    effs.append((self.turn[(par.node, mv)], self.rest[end]))
        if not kids:
            return []
        if self.exact_noise:
            return self._fold_exact(kids, [(par_node, mv) for par_node, mv in keys], objective, prior)
        X = np.stack([k.X for k in kids])
        N = np.stack([k.N for k in kids])
        for part in (0, 1):
            A = np.stack([e[part].A for e in effs])
            B = np.stack([e[part].B for e in effs])
            M1 = np.stack([e[part].M1 for e in effs])
            M2 = np.stack([e[part].M2 for e in effs])
            M3 = np.stack([e[part].M3 for e in effs])
            XM2 = np.swapaxes(X, 1, 2) @ M2
            N = N + np.swapaxes(X, 1, 2) @ M1 @ X + XM2 + np.swapaxes(XM2, 1, 2) + M3
            X = A @ X + B
        s = score(N, objective, prior, self.requirements)
        for k, x, n, v in zip(kids, X, N, s, strict=True):
            k.X, k.N, k.score = x, n, float(v)
        return kids

    def _fold_exact(self, kids, keys, objective, prior):
        """Fold each kid's turn and rest with its own filter covariance.

        Kids are batched by move, each with its own start node's segment; the turn and
        the rest after it are one closed-form step (:func:`.gm.fold_block` of
        :func:`.gm.then`), not a loop over their intervals.
        """
        X = np.stack([k.X for k in kids])
        N = np.stack([k.N for k in kids])
        P = np.stack([k.P for k in kids])
        stacks = self._stacks()
        by_move: dict = {}
        for i, (_node, mv) in enumerate(keys):
            by_move.setdefault(mv, []).append(i)
        blocks = stacks["blocks"]
        for mv, idx in by_move.items():  # the turn and the rest after it: one block
            nodes = np.array([stacks["index"][keys[i][0]] for i in idx])
            X[idx], N[idx], P[idx] = fold_block(blocks[mv], X[idx], N[idx], P[idx], nodes)
        s = score(N, objective, prior, self.requirements)
        for k, x, n, p, v in zip(kids, X, N, P, s, strict=True):
            k.X, k.N, k.P, k.score = x, n, p, float(v)
        return kids

    def _stacks(self) -> dict:
        """Per move, the turn and the rest after it from every node, as one block (built once)."""
        if "_stacked" not in self.__dict__:
            nodes = list(self.rest)
            # Each move's turn and the rest after it as one segment, stacked over the start
            # nodes, its effect in closed form for any filter covariance (gm.SegmentBlock):
            # one step per candidate, not two.
            self.__dict__["_stacked"] = {
                "index": {n: i for i, n in enumerate(nodes)},
                "blocks": {
                    mv: segment_blocks(
                        then(
                            stack([self.turn[(n, mv)] for n in nodes]),
                            stack([self.rest[apply_move(self.graph, n, mv)] for n in nodes]),
                        )
                    )
                    for mv in self.moves
                },
            }
        return self.__dict__["_stacked"]

    def complete(self, cand: Candidate) -> bool:
        g = self.constraints.gimbal
        if g is not None and g.end_at_home:
            if not at_home(cand.enc):
                return False
        return len(cand.walk) > 0 and (
            self.constraints.end is None or cand.node == tuple(self.constraints.end)
        )


def _key(c: Candidate):
    return (c.score, c.label)  # the label is " ".join of the moves' labels


def beam_search(
    model: SearchModel, objective: str = "worst", beam_width: int | None = 200, keep: int = 5, progress=None
) -> tuple[list[Candidate], int]:
    """Best complete walks (``keep`` of them) and the number of candidates scored.

    ``beam_width=None`` keeps every partial walk: an exhaustive search.
    """
    frontier = [model.start_candidate()]
    finals: list[Candidate] = []
    evaluated = 0
    for depth in range(model.constraints.max_flips):
        kids = model.extend(frontier, objective)
        evaluated += len(kids)
        if progress is not None:
            progress(depth + 1, evaluated)
        if not kids:
            break
        finals.extend(k for k in kids if model.complete(k))
        finals = sorted(finals, key=_key)[:keep]
        kids.sort(key=_key)
        frontier = kids if beam_width is None else kids[:beam_width]
    return finals, evaluated


def brute_force(model: SearchModel, depth: int, objective: str = "worst") -> Candidate | None:
    """Every walk of up to ``depth`` moves, each folded from scratch (for tests)."""
    import itertools

    best = None
    for d in range(1, depth + 1):
        for walk in itertools.product(model.moves, repeat=d):
            cand = model.start_candidate()
            ok = True
            for mv in walk:
                kids = [k for k in model.extend([cand], objective) if k.walk[-1] == mv]
                if not kids:
                    ok = False
                    break
                cand = kids[0]
            if ok and model.complete(cand) and (best is None or _key(cand) < _key(best)):
                best = cand
    return best


@dataclass(frozen=True)
class BeamJob:
    """One beam search at one uniform dwell (picklable: run on a worker or a dask cluster)."""

    constraints: Constraints
    dwell_s: float
    site: Site
    profile: NoiseProfile
    objective: str
    beam_width: int | None
    keep: int
    requirements: Requirements = PAPER


@dataclass(frozen=True)
class BeamResult:
    """The best complete walks of one beam, their search scores, and its effort."""

    dwell_s: float
    walks: list  # tuple[Move, ...] each, best first
    scores: list  # search score of each walk
    evaluated: int  # candidates scored
    seconds: float  # wall time


def search_at_dwell(job: BeamJob) -> BeamResult:
    """Build the search model at the job's dwell and run its beam."""
    t = time.perf_counter()
    model = SearchModel.build(job.constraints, job.dwell_s, job.site, job.profile, job.requirements)
    finals, n = beam_search(model, job.objective, job.beam_width, job.keep)
    return BeamResult(
        job.dwell_s, [f.walk for f in finals], [f.score for f in finals], n, time.perf_counter() - t
    )
