"""Sequence design: a search over flip walks, then dwell refinement with casadi/IPOPT.

The search scores thousands of candidate walks per second with the same
linear model and noise whitening as the analyser, cut into *segments* (a
move from one grid attitude, or a rest at one): every segment acts on the
lifted state ``X = [S; phi_hat]`` (9 x 24: sensitivities and the whitening
filter's state) linearly, and adds a quadratic form in ``X`` to the
information::

    X_out = A X + B,     dN = X' M1 X + X' M2 + M2' X + M3

The segment matrices depend only on the segment's attitude and move, so
they are computed once per search; a candidate is scored by a few small
matrix products, batched over all children of a beam. The one
approximation is that the noise filter's covariance is at its rest steady
state at each segment start (the first rest starts from zero exactly); the
finalists are then re-scored with the exact analyser, worst case over the
mounting tolerance, which is the figure reported.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from calib import earth
from calib import params as P
from calib.errors import CalibError
from calib.extras import NONE as NO_EXTRAS
from calib.extras import Extras
from calib.information import inverse_diagonal, marginal
from calib.jacobian import (
    N_UNKNOWN,
    ObservationGrid,
    moment_inputs,
    observation_matrix,
    propagate,
    state_matrix,
    trajectory_moments,
)
from calib.noise import interval_models, noise_model, whiten, whitener
from calib.profiles import NoiseProfile
from calib.requirements import PAPER, Requirements
from calib.sequence import Sequence, Step, Timeline, nominal_attitude
from calib.sim import body_integrals
from calib.start import FIRST_REST_MARGIN_S, MIN_ALIGN_S
from calib.transform import AXES

from .gmsearch import SegmentColumns, fold, noise_blocks, stack, start_state
from .graph import Move, Node, apply_move, attitude_of, flip_graph
from .graph import moves as all_moves

SEARCH_REST_INTERVALS = 12  # per rest, whatever its length: smooth in the dwell for IPOPT
SEARCH_MOVE_STEP_S = 0.5  # observation interval while turning (0.1 s changes sigmas < 0.2 %)
SEARCH_SUB_DEG = 2.0  # sub-samples while turning
# With GM each interval costs a Riccati step per candidate; 2 s intervals in turns move the
# search score of designed-30min by 0.2 % against 0.5 s (measured under navigation-gm).
SEARCH_GM_MOVE_STEP_S = 1.0
PRIOR_RATIO = 1e4  # partial walks: a prior of 1e4 x each requirement keeps them rankable
OBJECTIVES = ("worst", "D", "A", "E")


@dataclass(frozen=True)
class SegmentEffect:
    """Linear action of one segment on the lifted state and the information."""

    A: np.ndarray  # (h, h); h = 6 + filter states (9, or 15 with GM)
    B: np.ndarray  # (h, 24)
    M1: np.ndarray  # (h, h)
    M2: np.ndarray  # (h, 24)
    M3: np.ndarray  # (24, 24)


def _segment_timeline(C: np.ndarray, duration: float, rate: float = 0.0, axis: int = -1) -> Timeline:
    return Timeline(
        t0=np.array([0.0]),
        t1=np.array([duration]),
        rate=np.array([rate]),
        axis=np.array([axis]),
        C0=C[None],
        position=np.array([1]),
        step=np.array([-1]),
        C_end=C,
    )


def _segment_inputs(
    C: np.ndarray,
    duration: float,
    rate: float,
    axis: int,
    latitude_rad: float,
    gravity_mps2: float,
    profile: NoiseProfile,
    n_intervals: int | None,
):
    """Model inputs (K, 6, 24), interval lengths and (with GM) mid-interval attitudes."""
    tl = _segment_timeline(C, duration, rate, axis)
    if n_intervals is None:
        n_intervals = max(1, int(round(duration / SEARCH_MOVE_STEP_S)))
    sub = (
        4
        if rate == 0.0
        else max(1, int(math.ceil(abs(math.degrees(rate)) * duration / n_intervals / SEARCH_SUB_DEG)))
    )
    t_nav = np.linspace(0.0, duration, n_intervals * sub + 1)
    flip, E = body_integrals(tl, t_nav[1:])
    dtheta = flip + E @ earth.omega_ie_n(latitude_rad)
    dv = E @ earth.specific_force_n(gravity_mps2)
    grid = ObservationGrid(np.arange(0, n_intervals * sub + 1, sub))
    moments = trajectory_moments(nominal_attitude(tl, t_nav), dtheta, dv, t_nav, grid)
    inputs = moment_inputs(moments, latitude_rad, gravity_mps2)  # (K, 6, 24)
    T = np.diff(t_nav[grid.bounds])
    C_mid = None
    if profile.has_gauss_markov:  # bias-instability weights follow each interval's attitude
        b = grid.bounds
        C_mid = nominal_attitude(tl, t_nav)[(b[:-1] + b[1:]) // 2]
    return inputs, T, C_mid


def segment_columns(
    C: np.ndarray,
    duration: float,
    rate: float,
    axis: int,
    latitude_rad: float,
    gravity_mps2: float,
    profile: NoiseProfile,
    n_intervals: int | None = None,
) -> SegmentColumns:
    """A segment's unwhitened observation columns and noise blocks (exact GM search)."""
    inputs, T, C_mid = _segment_inputs(
        C, duration, rate, axis, latitude_rad, gravity_mps2, profile, n_intervals
    )
    A6 = state_matrix(latitude_rad, gravity_mps2)
    Phi_vv = np.array([m.Phi[3:6, 3:6] for m in interval_models(A6, T, profile, C_mid)])
    S0 = np.zeros((6, 6 + N_UNKNOWN))
    S0[:, :6] = np.eye(6)
    all_inputs = np.zeros((len(T), 6, 6 + N_UNKNOWN))
    all_inputs[:, :, 6:] = inputs
    S_v, S_end = propagate(all_inputs, T, S0, latitude_rad, gravity_mps2, return_final=True)
    H = observation_matrix(S_v, Phi_vv)
    return SegmentColumns(H, S_end[:, :6], S_end[:, 6:], *noise_blocks(A6, T, profile, C_mid))


def segment_effect(
    C: np.ndarray,
    duration: float,
    rate: float,
    axis: int,
    latitude_rad: float,
    gravity_mps2: float,
    profile: NoiseProfile,
    P0: np.ndarray | None,
    n_intervals: int | None = None,
    initial: bool = False,
) -> SegmentEffect:
    """The segment matrices of one rest (``rate == 0``) or turn, by running the model on basis columns."""
    inputs, T, C_mid = _segment_inputs(
        C, duration, rate, axis, latitude_rad, gravity_mps2, profile, n_intervals
    )
    noise = noise_model(state_matrix(latitude_rad, gravity_mps2), T, profile, P0, C_mid)
    # Columns: 6 + s homogeneous (unit S, unit filter state, no input; s = 3, or 9 with
    # Gauss-Markov biases), then the 24 unknowns' particular responses (zero start, this
    # segment's inputs). The same recursions as the analyser (propagate, whiten) run on
    # all of them at once.
    n_s = noise.whitener.state_size
    n_hom = 6 + n_s
    c = n_hom + N_UNKNOWN
    S0 = np.zeros((6, c))
    phi0 = np.zeros((n_s, c))
    if initial:  # the run's start: S = [I; 0] on phi0, filter state zero, nothing else
        S0[:3, n_hom + P.N_PARAMS :] = np.eye(3)
    else:
        S0[:, :6] = np.eye(6)
        phi0[:, 6:n_hom] = np.eye(n_s)
    all_inputs = np.zeros((len(T), 6, c))
    all_inputs[:, :, n_hom:] = inputs
    S_v, S_end = propagate(all_inputs, T, S0, latitude_rad, gravity_mps2, return_final=True)
    w, phi_end = whiten(noise.whitener, observation_matrix(S_v, noise.Phi_vv), phi0, return_final=True)
    Wh, Wp = w[:, :, :n_hom], w[:, :, n_hom:]
    M1 = np.einsum("kia,kib->ab", Wh, Wh)
    M2 = np.einsum("kia,kib->ab", Wh, Wp)
    M3 = np.einsum("kia,kib->ab", Wp, Wp)
    X = np.vstack([S_end, phi_end])
    return SegmentEffect(A=X[:, :n_hom], B=X[:, n_hom:], M1=M1, M2=M2, M3=M3)


def rest_steady_state(
    latitude_rad: float, gravity_mps2: float, profile: NoiseProfile, dwell_s: float
) -> np.ndarray:
    """Noise-filter covariance after a long rest observed with the search's rest intervals.

    With Gauss-Markov biases the filter state is ``[phi, b_g, b_a]`` (body frame); the
    rest is then taken at the identity attitude, which makes the result the covariance
    with the biases in the navigation frame: :func:`start_covariance` rotates it into
    any attitude's body frame (the model is rotation-invariant in that frame, see
    :func:`calib.noise._gm_interval_nav`).
    """
    T = np.full(40 * SEARCH_REST_INTERVALS, dwell_s / SEARCH_REST_INTERVALS)
    C = np.broadcast_to(np.eye(3), (len(T), 3, 3)) if profile.has_gauss_markov else None
    return whitener(interval_models(state_matrix(latitude_rad, gravity_mps2), T, profile, C)).P_end


def gm_start_covariance(profile: NoiseProfile) -> np.ndarray:
    """Filter covariance at a run's start with GM biases: phi zero (an unknown of the fit),
    the biases at their stationary ``sigma^2 I`` (as :func:`calib.noise.whitener`).
    """
    return np.diag(np.repeat([0.0, profile.gyro_gm_sigma**2, profile.accel_gm_sigma**2], 3))


def start_covariance(P_nav: np.ndarray, C_b_n: np.ndarray) -> np.ndarray:
    """The filter covariance a segment starts from at attitude ``C_b_n`` (body-frame biases).

    ``P_nav`` is :func:`rest_steady_state`'s; the attitude error ``phi`` is in the
    navigation frame already, the biases rotate with ``C_b_n' (.) C_b_n``.
    """
    if len(P_nav) == 3:
        return P_nav
    R = np.eye(9)
    R[3:6, 3:6] = R[6:9, 6:9] = C_b_n
    return R.T @ P_nav @ R


# ---------------------------------------------------------------------------
# Objectives on information matrices (batched)


def scaled_marginal(N: np.ndarray, prior: bool, requirements: Requirements = PAPER) -> np.ndarray:
    """Requirement-scaled information of the 21 after eliminating phi0: ``(..., 21, 21)``."""
    M = marginal(N)
    D = requirements.si
    M = M * np.outer(D, D)
    if prior:
        M = M + np.eye(P.N_PARAMS) * (9.0 / PRIOR_RATIO**2)
    return M


def score(
    N: np.ndarray, objective: str, prior: bool = True, requirements: Requirements = PAPER
) -> np.ndarray:
    """Figure of merit, smaller is better, for ``(..., 24, 24)`` information matrices.

    ``worst``: max 3 sigma / requirement; ``A``: sum of (sigma/requirement)^2;
    ``D``: -log det of the scaled information; ``E``: -smallest eigenvalue.
    """
    M = scaled_marginal(N, prior, requirements)
    M = 0.5 * (M + np.swapaxes(M, -1, -2))
    if objective in ("worst", "A"):
        # With the prior, partial walks must stay rankable and the prior keeps M invertible:
        # a plain batched inverse (3x faster than eigh). Without it, the one observability
        # rule of calib.information: inf for a walk that leaves a direction unobserved.
        d = np.einsum("...ii->...i", np.linalg.inv(M)) if prior else inverse_diagonal(M)
        return 3.0 * np.sqrt(d.max(axis=-1)) if objective == "worst" else d.sum(axis=-1)
    ev = np.linalg.eigvalsh(M)
    if objective == "D":
        return np.where(ev[..., 0] > 0, -np.sum(np.log(np.abs(ev)), axis=-1), np.inf)
    if objective == "E":
        return -ev[..., 0]
    raise CalibError(f"unknown objective {objective!r}", "--objective", "use worst, D, A or E")


# ---------------------------------------------------------------------------
# The search


@dataclass(frozen=True)
class Constraints:
    """What a user may fix about a design (SI: seconds, rad/s)."""

    start: Node = ("east", "up", "south")
    end: Node | None = None
    max_flips: int = 60  # at most; the budget ends most walks sooner
    axes: str = AXES
    max_quarters: int = 5
    rate_dps: float = 10.0
    min_dwell_s: float = 10.0  # as the CLI: short dwells are what GM profiles need
    max_dwell_s: float = 300.0
    budget_s: float = 900.0
    accel_dps2: float | None = None  # every move a trapezoid (None: constant rate)
    jerk_dps3: float | None = None  # and an S-curve
    gimbal: object = None  # calib.gimbal.Gimbal: only moves it plays (seqdesign.gimbalsearch)


def turn_seconds(mv: Move, c: Constraints) -> float:
    """How long a move lasts with the design's rate profile (longer with an acceleration limit)."""
    if c.accel_dps2 is None:
        return abs(mv.angle_deg) / c.rate_dps
    from .gimbalsearch import move_profile

    return move_profile(c.rate_dps, c.accel_dps2, c.jerk_dps3).duration_s(math.radians(abs(mv.angle_deg)))


def turn_rate(mv: Move, c: Constraints) -> float:
    """Signed rate (rad/s) of the search's constant-rate segment: the mean over the real move."""
    if c.accel_dps2 is None:
        return mv.sign * math.radians(c.rate_dps)
    return mv.sign * math.radians(abs(mv.angle_deg)) / turn_seconds(mv, c)


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


@dataclass
class SearchModel:
    """Everything a search at one dwell needs, precomputed."""

    constraints: Constraints
    dwell_s: float
    latitude_rad: float
    gravity_mps2: float
    profile: NoiseProfile
    graph: object
    moves: list[Move]
    initial: SegmentEffect
    rest: dict
    turn: dict = field(default_factory=dict)
    requirements: Requirements = PAPER
    exact_noise: bool = False  # GM: each candidate carries its filter covariance (gmsearch)

    @classmethod
    def build(
        cls,
        c: Constraints,
        dwell_s: float,
        latitude_rad: float,
        height_m: float,
        profile: NoiseProfile,
        requirements: Requirements = PAPER,
    ) -> "SearchModel":
        g = earth.gravity(latitude_rad, height_m)
        graph = flip_graph(c.start, c.axes)
        if profile.has_gauss_markov:
            return cls._build_exact(c, dwell_s, latitude_rad, g, profile, requirements, graph)
        P_ss = rest_steady_state(latitude_rad, g, profile, dwell_s)
        rest = {
            node: segment_effect(
                attitude_of(node),
                dwell_s,
                0.0,
                -1,
                latitude_rad,
                g,
                profile,
                start_covariance(P_ss, attitude_of(node)),
                SEARCH_REST_INTERVALS,
            )
            for node in graph.nodes
        }
        initial = segment_effect(
            attitude_of(c.start),
            dwell_s,
            0.0,
            -1,
            latitude_rad,
            g,
            profile,
            None,
            SEARCH_REST_INTERVALS,
            initial=True,
        )
        model = cls(
            c,
            dwell_s,
            latitude_rad,
            g,
            profile,
            graph,
            all_moves(c.axes, c.max_quarters),
            initial,
            rest,
            requirements=requirements,
        )
        for node in graph.nodes:
            C = attitude_of(node)
            for mv in model.moves:
                model.turn[(node, mv)] = segment_effect(
                    C,
                    turn_seconds(mv, c),
                    turn_rate(mv, c),
                    AXES.index(mv.axis),
                    latitude_rad,
                    g,
                    profile,
                    start_covariance(P_ss, C),
                )
        return model

    @classmethod
    def _build_exact(cls, c, dwell_s, latitude_rad, g, profile, requirements, graph):
        rest = {
            node: segment_columns(
                attitude_of(node), dwell_s, 0.0, -1, latitude_rad, g, profile, SEARCH_REST_INTERVALS
            )
            for node in graph.nodes
        }
        model = cls(
            c,
            dwell_s,
            latitude_rad,
            g,
            profile,
            graph,
            all_moves(c.axes, c.max_quarters),
            rest[tuple(c.start)],
            rest,
            requirements=requirements,
            exact_noise=True,
        )
        for node in graph.nodes:
            for mv in model.moves:
                model.turn[(node, mv)] = _turn_columns(
                    node, mv, turn_seconds(mv, c), turn_rate(mv, c), latitude_rad, g, profile
                )
        return model

    def turn_time(self, mv: Move) -> float:
        return turn_seconds(mv, self.constraints)

    def start_candidate(self) -> Candidate:
        """After the initial rest (its effect already holds the run's start state)."""
        if self.exact_noise:
            X, N, P0 = start_state(gm_start_covariance(self.profile), N_UNKNOWN)
            X, N, P0 = fold(self.initial, X[None], N[None], P0[None])
            return Candidate(
                walk=(),
                node=tuple(self.constraints.start),
                X=X[0],
                N=N[0],
                time_s=self.dwell_s,
                P=P0[0],
                enc=self._enc0(),
            )
        e = self.initial
        return Candidate(
            walk=(),
            node=tuple(self.constraints.start),
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
        from .gimbalsearch import home_reachable, next_encoders

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
        for par in parents:
            if len(par.walk) >= c.max_flips:
                continue
            for mv in self.moves:
                t = par.time_s + self.turn_time(mv) + self.dwell_s
                if t > c.budget_s + 1e-9:
                    continue
                ok, enc = self._gimbal_child(par, mv, t)
                if not ok:
                    continue
                end = apply_move(self.graph, par.node, mv)
                kids.append(Candidate(par.walk + (mv,), end, par.X, par.N, t, P=par.P, enc=enc))
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
        for k, x, n, v in zip(kids, X, N, s):
            k.X, k.N, k.score = x, n, float(v)
        return kids

    def _fold_exact(self, kids, keys, objective, prior):
        """Fold each kid's turn and rest with its own filter covariance.

        Kids are batched by move (equal interval counts), each with its own
        start node's columns; all rests have the same count and fold at once.
        """
        X = np.stack([k.X for k in kids])
        N = np.stack([k.N for k in kids])
        P = np.stack([k.P for k in kids])
        stacks = self._stacks()
        by_move: dict = {}
        for i, (node, mv) in enumerate(keys):
            by_move.setdefault(mv, []).append(i)
        for mv, idx in by_move.items():
            nodes = np.array([stacks["index"][keys[i][0]] for i in idx])
            X[idx], N[idx], P[idx] = fold(stacks[mv], X[idx], N[idx], P[idx], nodes)
        nodes = np.array([stacks["index"][k.node] for k in kids])
        X, N, P = fold(stacks["rest"], X, N, P, nodes)
        s = score(N, objective, prior, self.requirements)
        for k, x, n, p, v in zip(kids, X, N, P, s):
            k.X, k.N, k.P, k.score = x, n, p, float(v)
        return kids

    def _stacks(self) -> dict:
        """Per move, and for the rests, every node's columns stacked (built once)."""
        if "_stacked" not in self.__dict__:
            nodes = list(self.rest)
            st = {"index": {n: i for i, n in enumerate(nodes)}, "rest": stack([self.rest[n] for n in nodes])}
            for mv in self.moves:
                st[mv] = stack([self.turn[(n, mv)] for n in nodes])
            self.__dict__["_stacked"] = st
        return self.__dict__["_stacked"]

    def complete(self, cand: Candidate) -> bool:
        g = self.constraints.gimbal
        if g is not None and g.end_at_home:
            from .gimbalsearch import at_home

            if not at_home(cand.enc):
                return False
        return len(cand.walk) > 0 and (
            self.constraints.end is None or cand.node == tuple(self.constraints.end)
        )


def _key(c: Candidate):
    return (c.score, " ".join(m.label() for m in c.walk))


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


def brute_force(model: SearchModel, depth: int, objective: str = "worst") -> Candidate:
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


def to_sequence(
    walk,
    c: Constraints,
    dwells: list[float],
    name: str,
    provenance: dict | None = None,
    latitude_deg: float | None = None,
    height_m: float | None = None,
) -> Sequence:
    """A sequence file's content for a walk and its dwells (initial first), with its site."""
    steps = tuple(
        Step(mv.axis, mv.angle_deg, c.rate_dps, float(d), c.accel_dps2, c.jerk_dps3)
        for mv, d in zip(walk, dwells[1:])
    )
    return Sequence(
        name=name,
        start=tuple(c.start),
        steps=steps,
        initial_dwell_s=float(dwells[0]),
        description=f"designed: {' '.join(m.label() for m in walk)}",
        latitude_deg=latitude_deg,
        height_m=height_m,
        provenance=provenance or {},
    )


# ---------------------------------------------------------------------------
# Dwell refinement (casadi + IPOPT)


def walk_information(
    walk,
    c: Constraints,
    dwells,
    latitude_rad: float,
    gravity_mps2: float,
    profile: NoiseProfile,
    P_ss: np.ndarray,
) -> np.ndarray:
    """Search-model information of a walk with individual dwells (smooth in the dwells)."""
    graph = flip_graph(c.start, c.axes)
    node = tuple(c.start)
    if profile.has_gauss_markov:
        return _walk_information_exact(walk, c, dwells, latitude_rad, gravity_mps2, profile)
    e = segment_effect(
        attitude_of(node),
        dwells[0],
        0.0,
        -1,
        latitude_rad,
        gravity_mps2,
        profile,
        None,
        SEARCH_REST_INTERVALS,
        initial=True,
    )
    X, N = e.B, e.M3
    for mv, d in zip(walk, dwells[1:]):
        parts = [
            _turn_effect(
                node,
                mv,
                turn_seconds(mv, c),
                turn_rate(mv, c),
                latitude_rad,
                gravity_mps2,
                profile,
                P_ss.tobytes(),
            )
        ]
        node = apply_move(graph, node, mv)
        parts.append(
            segment_effect(
                attitude_of(node),
                d,
                0.0,
                -1,
                latitude_rad,
                gravity_mps2,
                profile,
                start_covariance(P_ss, attitude_of(node)),
                SEARCH_REST_INTERVALS,
            )
        )
        for eff in parts:
            XM2 = X.T @ eff.M2
            N = N + X.T @ eff.M1 @ X + XM2 + XM2.T + eff.M3
            X = eff.A @ X + eff.B
    return N


def _walk_information_exact(
    walk, c: Constraints, dwells, latitude_rad: float, gravity_mps2: float, profile: NoiseProfile
) -> np.ndarray:
    """:func:`walk_information` with the filter covariance carried along (GM profiles)."""
    return walk_informations_exact(walk, c, [dwells], latitude_rad, gravity_mps2, profile)[0]


def walk_informations_exact(
    walk, c: Constraints, dwell_sets, latitude_rad: float, gravity_mps2: float, profile: NoiseProfile
) -> np.ndarray:
    """Information ``(B, 24, 24)`` of one walk under ``B`` sets of dwells, batched (GM).

    The turns are shared; every rest has :data:`SEARCH_REST_INTERVALS` intervals
    whatever its length, so the rests of the ``B`` candidates stack and one fold
    carries them all (what IPOPT's finite differences need at once).
    """
    graph = flip_graph(c.start, c.axes)
    node = tuple(c.start)
    B = len(dwell_sets)
    X, N, Pc = (np.repeat(a[None], B, axis=0) for a in start_state(gm_start_covariance(profile), N_UNKNOWN))
    dwell_sets = np.asarray(dwell_sets, dtype=float)
    rows = np.arange(B)

    def rests(node, k):
        return stack(
            [_rest_columns(node, float(d), latitude_rad, gravity_mps2, profile) for d in dwell_sets[:, k]]
        )

    X, N, Pc = fold(rests(node, 0), X, N, Pc, rows)
    for k, mv in enumerate(walk, start=1):
        X, N, Pc = fold(
            _turn_columns(
                node, mv, turn_seconds(mv, c), turn_rate(mv, c), latitude_rad, gravity_mps2, profile
            ),
            X,
            N,
            Pc,
        )
        node = apply_move(graph, node, mv)
        X, N, Pc = fold(rests(node, k), X, N, Pc, rows)
    return N


@functools.lru_cache(maxsize=4096)
def _rest_columns(node, duration, latitude_rad, gravity_mps2, profile):
    return segment_columns(
        attitude_of(node), duration, 0.0, -1, latitude_rad, gravity_mps2, profile, SEARCH_REST_INTERVALS
    )


@functools.lru_cache(maxsize=4096)
def _turn_columns(node, mv, duration, rate, latitude_rad, gravity_mps2, profile):
    return segment_columns(
        attitude_of(node),
        duration,
        rate,
        AXES.index(mv.axis),
        latitude_rad,
        gravity_mps2,
        profile,
        max(1, int(round(duration / SEARCH_GM_MOVE_STEP_S))),
    )


@functools.lru_cache(maxsize=4096)
def _turn_effect(node, mv, duration, rate, latitude_rad, gravity_mps2, profile, P_bytes):
    n = int(round(math.sqrt(len(P_bytes) // 8)))
    P_ss = np.frombuffer(P_bytes).reshape(n, n)
    C = attitude_of(node)
    return segment_effect(
        C, duration, rate, AXES.index(mv.axis), latitude_rad, gravity_mps2, profile, start_covariance(P_ss, C)
    )


def refine_dwells(
    walk,
    c: Constraints,
    dwell0: float,
    latitude_rad: float,
    height_m: float,
    profile: NoiseProfile,
    objective: str = "worst",
    requirements: Requirements = PAPER,
    repeats: int = 1,
) -> tuple[list[float], float, float]:
    """Optimise the dwells of a walk under the time budget (IPOPT).

    The dwells of a motif played ``repeats`` times are tied across the plays, and a
    motif longer than :data:`MAX_REFINE_DWELLS` moves ties them in that many blocks
    (:func:`dwell_groups`: IPOPT's derivatives are finite differences).

    Minimises ``t`` subject to ``ratio_i(dwells) <= t`` for all 21 (the worst ratio,
    smooth in epigraph form), ``sum(dwells) + turns <= budget`` and the dwell bounds;
    ratios from a casadi Callback over the search model.

    Returns the dwells, the objective with uniform dwells and after.
    """
    import casadi as ca

    g = earth.gravity(latitude_rad, height_m)
    P_ss = rest_steady_state(latitude_rad, g, profile, dwell0)
    groups = dwell_groups(len(walk), repeats)
    n = int(groups.max()) + 1
    count = np.bincount(groups, minlength=n).astype(float)
    turn_time = sum(turn_seconds(m, c) for m in walk)
    scale = 100.0  # dwells in units of 100 s for IPOPT

    def ratios_many(D):  # (B, n) dwell variables, s -> (B, 21) ratios
        sets = [list(d[groups]) for d in np.asarray(D, dtype=float)]
        if profile.has_gauss_markov:  # one batched fold for all (finite differences)
            Ns = walk_informations_exact(walk, c, sets, latitude_rad, g, profile)
        else:
            Ns = [walk_information(walk, c, d, latitude_rad, g, profile, P_ss) for d in sets]
        return np.array(
            [3.0 * np.sqrt(inverse_diagonal(scaled_marginal(N, False, requirements))) for N in Ns]
        )

    def ratios(dw):
        return ratios_many(np.asarray(dw, dtype=float)[None])[0]

    cb = _ratios_callback(ratios_many, n, scale)
    x = ca.MX.sym("d", n)
    t = ca.MX.sym("t")
    r = cb(x)
    total = ca.dot(ca.DM(count), x) * scale + turn_time
    if objective == "worst":
        f, gcon = t, ca.vertcat(r - t, total - c.budget_s)
        ubg = np.zeros(P.N_PARAMS + 1)
    else:  # A-optimal in the refinement for the other objectives
        f, gcon = ca.sum1(r**2) / 9.0, ca.vertcat(total - c.budget_s)
        ubg = np.zeros(1)
    uniform = np.full(n, dwell0)
    r0 = ratios(uniform)
    solver = ca.nlpsol(
        "dwells",
        "ipopt",
        {"x": ca.vertcat(x, t), "f": f, "g": gcon},
        {
            "print_time": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.hessian_approximation": "limited-memory",
            "ipopt.max_iter": 40,
            "ipopt.tol": 1e-4,
        },
    )
    sol = solver(
        x0=np.concatenate([uniform / scale, [r0.max()]]),
        lbx=np.concatenate([np.full(n, c.min_dwell_s / scale), [0.0]]),
        ubx=np.concatenate([np.full(n, c.max_dwell_s / scale), [np.inf]]),
        lbg=np.full(len(ubg), -np.inf),
        ubg=ubg,
    )
    dw = np.asarray(sol["x"]).ravel()[:n] * scale
    dw = np.clip(dw, c.min_dwell_s, c.max_dwell_s)
    over = dw[groups].sum() + turn_time - c.budget_s
    if over > 0:  # IPOPT's tolerance: shave the excess off the longest dwell
        i = int(np.argmax(dw))
        dw[i] -= over / count[i]
    r1 = ratios(dw)
    if r1.max() >= r0.max():  # never return worse than the uniform start
        return list(uniform[groups]), float(r0.max()), float(r0.max())
    return (dwells_in_ms(dw[groups], c.budget_s - turn_time), float(r0.max()), float(r1.max()))


def dwells_in_ms(dwells, available_s: float) -> list[float]:
    """Dwells rounded to the millisecond a sequence file holds, their sum within ``available_s``.

    Rounding each of ~60 dwells can add up to 30 ms; what overruns comes off the longest
    dwell (rounded down), so a design never lasts longer than its budget.
    """
    out = [round(float(d), 3) for d in dwells]
    excess = sum(out) - available_s
    if excess > 0:
        i = int(np.argmax(out))
        out[i] = math.floor((out[i] - excess) * 1000.0) / 1000.0
    return out


MAX_REFINE_DWELLS = 8  # IPOPT dwell variables besides the initial dwell


def dwell_groups(n_moves: int, repeats: int = 1) -> np.ndarray:
    """Which IPOPT variable each dwell is (initial dwell first, variable 0).

    One per motif move, tied across the ``repeats`` plays; a motif of more than
    :data:`MAX_REFINE_DWELLS` moves in that many contiguous blocks.
    """
    m = n_moves // repeats
    per_move = np.arange(m) if m <= MAX_REFINE_DWELLS else (np.arange(m) * MAX_REFINE_DWELLS) // m
    return np.concatenate([[0], 1 + np.tile(per_move, repeats)])


REFINE_FD_STEP = 1e-4  # central differences in dwells of 100 s units: 0.01 s


def _ratios_callback(ratios_many, n: int, scale: float):
    """The 21 ratios as a casadi function of ``n`` scaled dwells.

    Its Jacobian is central differences :data:`REFINE_FD_STEP` apart, all ``2 n``
    points in one call of ``ratios_many`` (batched: under GM one fold carries them).
    Truncation ~ step^2 x the third derivative (~1e-8 of a ratio); rounding ~1e-16 / 1e-4.
    """
    import casadi as ca

    class _Jacobian(ca.Callback):
        def __init__(self, name, opts):
            ca.Callback.__init__(self)
            self.construct(name, opts)

        def get_n_in(self):
            return 2  # the point, and the function's value there (unused)

        def get_n_out(self):
            return 1

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(n, 1) if i == 0 else ca.Sparsity.dense(P.N_PARAMS, 1)

        def get_sparsity_out(self, i):
            return ca.Sparsity.dense(P.N_PARAMS, n)

        def eval(self, arg):
            x = np.asarray(arg[0], dtype=float).ravel()
            steps = REFINE_FD_STEP * np.eye(n)
            r = ratios_many(np.vstack([x + steps, x - steps]) * scale)
            return [(r[:n] - r[n:]).T / (2.0 * REFINE_FD_STEP)]

    class _Ratios(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self.construct("ratios", {})

        def get_n_in(self):
            return 1

        def get_n_out(self):
            return 1

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(n, 1)

        def get_sparsity_out(self, i):
            return ca.Sparsity.dense(P.N_PARAMS, 1)

        def eval(self, arg):
            return [ratios_many(np.asarray(arg[0], dtype=float).reshape(1, n) * scale)[0]]

        def has_jacobian(self):
            return True

        def get_jacobian(self, name, inames, onames, opts):
            self.jacobian_callback = _Jacobian(name, opts)  # casadi keeps no reference
            return self.jacobian_callback

    return _Ratios()


def uniform_dwell(c: Constraints, n_moves_guess: int, quarters_guess: float = 2.0) -> float:
    """A dwell that lets ``n_moves_guess`` moves fit the budget."""
    turn = n_moves_guess * quarters_guess * 90.0 / c.rate_dps
    d = (c.budget_s - turn) / (n_moves_guess + 1)
    return float(min(max(d, c.min_dwell_s), c.max_dwell_s))


def check_constraints(c: Constraints) -> None:
    """Refuse constraints no walk can meet, naming the option."""
    if c.budget_s <= 0 or not math.isfinite(c.budget_s):
        raise CalibError(f"budget {c.budget_s} s must be positive", "--budget-min")
    if not 1 <= c.max_flips <= MAX_FLIPS:
        raise CalibError(f"--max-flips {c.max_flips} outside [1, {MAX_FLIPS}]", "--max-flips")
    if not 1 <= c.max_quarters <= 12:
        raise CalibError(f"--max-quarters {c.max_quarters} outside [1, 12]", "--max-quarters")
    if not c.axes or any(a not in AXES for a in c.axes):
        raise CalibError(f"--axes {c.axes!r} must be letters from XYZ", "--axes")
    if not 0 < c.min_dwell_s <= c.max_dwell_s:
        raise CalibError(
            f"dwell range [{c.min_dwell_s}, {c.max_dwell_s}] s is empty", "--min-dwell-s/--max-dwell-s"
        )
    shortest = MIN_ALIGN_S + FIRST_REST_MARGIN_S
    if c.min_dwell_s < shortest:
        raise CalibError(
            f"--min-dwell-s {c.min_dwell_s:g} s is too short: the first rest of a "
            f"run must last {shortest:g} s for calibrate to align on it",
            "--min-dwell-s",
            f"give --min-dwell-s {shortest:g} or more",
        )
    if not 0.1 <= c.rate_dps <= 100:
        raise CalibError(f"--rate-dps {c.rate_dps} outside [0.1, 100]", "--rate-dps")
    if c.min_dwell_s * 2 + 90.0 / c.rate_dps > c.budget_s:
        raise CalibError(
            f"a budget of {c.budget_s:.0f} s cannot hold two dwells of {c.min_dwell_s:.0f} s and one flip",
            "--budget-min",
            "raise the budget or lower --min-dwell-s",
        )


# ---------------------------------------------------------------------------
# The whole design: search at a few dwells, exact re-scoring, refinement


@dataclass
class DesignResult:
    """A designed sequence and the figures that justify it."""

    sequence: Sequence
    worst_ratio: float  # exact, worst case over the tolerance box
    worst_name: str
    uniform_worst_ratio: float  # exact, same walk with uniform dwells
    evaluated: int  # candidates scored by the search
    search_seconds: float
    finalists: list  # (walk label, dwell, exact worst ratio), every candidate re-scored
    robustness: object  # observability.Robustness of the 21 alone (None with --with)
    extras_cost: object = None  # observability.ExtrasCost of the winner when --with was given
    repeats: int = 1  # how many times the winner plays its motif


def _search_at_dwell(args):
    c, dwell, latitude_rad, height_m, profile, objective, beam_width, keep, *rest = args
    requirements = rest[0] if rest else PAPER
    import time as _time

    t = _time.perf_counter()
    model = SearchModel.build(c, dwell, latitude_rad, height_m, profile, requirements)
    finals, n = beam_search(model, objective, beam_width, keep)
    return dwell, [(f.walk, f.score) for f in finals], n, _time.perf_counter() - t


def design_steps(c: Constraints, keep: int) -> int:
    """Progress steps of :func:`design`: searches, finalists, refinement, final check."""
    n = len(search_dwells(c))
    return 2 * n + 2 * n * keep * (1 + len(MOTIF_REPEATS)) + 2 * SCREEN_KEEP + 4


MAX_FLIPS = 60
SHORT_WALK_FLIPS = 10  # the classic space: up to 10 moves at long dwells
# Many short moves (issue 12): beams at these dwells walk until the budget is spent.
# Under Gauss-Markov accelerometer bias they win: gravity must reverse on each axis
# much faster than tau, and 450 deg turns sweep it round while turning.
LONG_WALK_DWELLS_S = (10.0, 15.0, 20.0)


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


def map_jobs(fn, jobs, workers: int = 1, scheduler: str | None = None):
    """Run jobs serially, on local processes, or on a dask.distributed cluster; same order out."""
    if scheduler:
        try:
            from dask.distributed import Client
        except ImportError:
            raise CalibError(
                "--scheduler needs dask.distributed", "--scheduler", "pip install 'seqdesign[dask]'"
            ) from None
        client = scheduler if not isinstance(scheduler, str) else Client(scheduler)
        try:
            return client.gather(client.map(fn, jobs, pure=False))
        finally:
            if isinstance(scheduler, str):
                client.close()
    if workers > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=workers) as pool:
            return list(pool.map(fn, jobs))
    return [fn(j) for j in jobs]


def _exact_worst(
    seq: Sequence,
    profile,
    latitude_rad,
    height_m,
    tolerance_deg,
    search,
    requirements: Requirements = PAPER,
    extras: Extras = NO_EXTRAS,
):
    """Worst 3 sigma/requirement of the 21 over the box, with ``extras`` fitted beside them.

    The same figures as ``seqdesign analyze`` (with ``--with``): with ``search``, IPOPT
    then looks inside the box from its worst point. Returns ``(ratio, parameter, Robustness
    or None, ExtrasCost or None)``: with ``extras`` the ExtrasCost alone (it holds the 21's
    sigma with and without the terms at the same mountings).
    """
    from .observability import analyze_extras, analyze_tolerance

    if extras.n:
        cost = analyze_extras(
            seq, profile, latitude_rad, extras, height_m, tolerance_deg, requirements, search=search
        )
        r = requirements.ratio(cost.sigma_with)
        i = int(np.argmax(r))
        return float(r[i]), P.NAMES[i], None, cost
    rob = analyze_tolerance(
        seq, profile, latitude_rad, height_m, tolerance_deg, search=search, requirements=requirements
    )
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
    site: tuple  # (latitude deg, height m), written into each sequence
    profile: NoiseProfile
    latitude_rad: float
    height_m: float
    requirements: Requirements
    extras: Extras

    def __call__(self, job):
        walk, dwells, search, tol = job
        seq = to_sequence(walk, self.c, list(dwells), self.name, None, *self.site)
        worst, wname, rob, cost = _exact_worst(
            seq, self.profile, self.latitude_rad, self.height_m, tol, search, self.requirements, self.extras
        )
        return worst, wname, rob, cost, seq


MOTIF_REPEATS = (2, 3, 4)  # a finalist's walk also played 2-4 times, with shorter dwells


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


def _candidates(results, c: Constraints):
    """Distinct (walk, dwell) pairs from the beams, and each walk's motif repetitions."""
    out, seen = [], set()
    for dwell, finals, _, _ in results:
        for walk, _score in finals:
            if (walk, dwell) not in seen:
                seen.add((walk, dwell))
                out.append((walk, dwell, 1))
    for walk, _, _ in list(out):
        for r in MOTIF_REPEATS:
            d = motif_dwell(walk, c, r)
            if d is not None and (walk * r, d) not in seen:
                seen.add((walk * r, d))
                out.append((walk * r, d, r))
    if c.gimbal is not None:  # a motif's later plays start where the first ended: replay all
        from calib.gimbal import plan_sequence

        out = [
            x
            for x in out
            if plan_sequence(to_sequence(x[0], c, [x[1]] * (len(x[0]) + 1), "x"), c.gimbal).playable
        ]
    return out


def _beam_widths(beam_width: int | None) -> list:
    """Beams to run: the one asked for and, when wider, a beam of 20 too.

    The search score is not the exact worst case over the box, so a narrow beam can
    hand a different (sometimes better) walk to the exact re-scoring; running both
    makes more effort never give a worse answer.
    """
    if beam_width is None or beam_width <= NARROW_BEAM:
        return [beam_width]
    return [NARROW_BEAM, beam_width]


NARROW_BEAM = 20
SCHEDULER_BATCH = 4  # candidates re-scored at once on a dask cluster (its size is unknown here)
SCREEN_KEEP = 6  # candidates re-scored over the whole box after the nominal-mounting screen


def _search(
    c,
    profile,
    latitude_rad,
    height_m,
    objective,
    beam_width,
    keep,
    requirements,
    workers,
    scheduler,
    progress,
):
    """Run every beam; returns ``(results, evaluated, narrow)``, ``narrow`` the results of the
    beams of 20 alone (None when that is all there is).
    """
    jobs = [
        (c, d, latitude_rad, height_m, profile, objective, bw, keep, requirements)
        for d in search_dwells(c)
        for bw in _beam_widths(beam_width)
    ]
    if progress:
        progress(
            f"searching {len(jobs)} beams (widths {_beam_widths(beam_width)}, dwells "
            f"{search_dwells(c)} s, up to {c.max_flips} moves of up to "
            f"{c.max_quarters} quarter turns)",
            0,
        )
    results = map_jobs(_search_at_dwell, jobs, workers, scheduler)
    evaluated = sum(r[2] for r in results)
    if progress:
        progress(f"searched {evaluated} candidates", len(jobs))
    narrow = None
    if len(_beam_widths(beam_width)) > 1:
        narrow = [r for r, j in zip(results, jobs) if j[6] == NARROW_BEAM]
    return results, evaluated, narrow


def design(
    c: Constraints,
    profile: NoiseProfile,
    latitude_rad: float,
    height_m: float = 0.0,
    objective: str = "worst",
    tolerance_deg: float = 3.0,
    beam_width: int = 200,
    keep: int = 4,
    refine: bool = True,
    name: str = "designed",
    workers: int = 1,
    scheduler=None,
    progress=None,
    requirements: Requirements = PAPER,
    extras: Extras = NO_EXTRAS,
) -> DesignResult:
    """Search walks, re-score every candidate exactly over the tolerance box, refine the best.

    The candidates are the beams' finalists and their motif repetitions; each is
    re-scored exactly (27 box points, ``extras`` fitted beside the 21), the best is
    IPOPT-refined. What ``--beam-width 20`` and ``--no-refine`` would answer comes from the
    same beams and gets the same final check; the best final figure wins (:func:`_select`).
    ``progress(message, steps)``: ``design_steps(c, keep)`` steps in all.
    """
    import time as _time

    _check_design_args(c, objective)
    t0 = _time.perf_counter()
    site = (math.degrees(latitude_rad), height_m)  # written into the sequence: analyse it there
    results, evaluated, narrow = _search(
        c,
        profile,
        latitude_rad,
        height_m,
        objective,
        beam_width,
        keep,
        requirements,
        workers,
        scheduler,
        progress,
    )
    search_seconds = _time.perf_counter() - t0
    scorer = ExactScorer(c, name, site, profile, latitude_rad, height_m, requirements, extras)
    batch = max(workers, SCHEDULER_BATCH if scheduler else 1)
    memo = {}

    def exact(jobs):  # [(walk, dwells, search, tol)] -> [(worst, name, rob, cost, seq)]
        todo = list(dict.fromkeys(j for j in jobs if j not in memo))  # the narrow beams'
        for job, out in zip(todo, map_jobs(scorer, todo, workers, scheduler)):  # are mostly
            memo[job] = out if job[2] else out[:2] + (None, None, out[4])  # the wide ones'
        return [memo[j] for j in jobs]

    def pipeline(res):  # (pool of exact box scores, the same with the refined best)
        pool = _boxed(_screen(_candidates(res, c), exact, progress), exact, tolerance_deg, progress, batch)
        key = (pool[0][3], tuple(pool[0][2]))
        if refine and key not in memo:
            memo[key] = _refined(
                pool[0],
                c,
                latitude_rad,
                height_m,
                profile,
                objective,
                requirements,
                lambda w, d: exact([(w, d, False, tolerance_deg)])[0],
                progress,
            )
        refined = memo[key] if refine else []
        return pool, sorted(pool + refined, key=lambda f: (f[0], f[1]))

    unrefined, pool = pipeline(results)
    answers = [pool[0], unrefined[0]]  # the default's, and what --no-refine returns
    if narrow is not None:  # what --beam-width 20 (with and without --no-refine) returns
        n_unrefined, n_pool = pipeline(narrow)
        pool = sorted(pool + n_pool, key=lambda f: (f[0], f[1]))
        answers += [pool[0], n_pool[0], n_unrefined[0]]
    worst, wname, rob, cost, seq, (_, label, _, _, reps) = _select(answers, exact, tolerance_deg, batch)
    from .gimbalsearch import check_sequence_plays

    check_sequence_plays(seq, c.gimbal)
    if progress:
        progress(
            f"best of {len(pool)}: {label}; worst case over +-{tolerance_deg:g} deg: {worst:.3f} ({wname})", 1
        )
    return DesignResult(
        sequence=seq,
        worst_ratio=worst,
        worst_name=wname,
        uniform_worst_ratio=unrefined[0][0],
        evaluated=evaluated,
        search_seconds=search_seconds,
        finalists=[(f[1], f[2][-1], f[0]) for f in pool],
        robustness=rob,
        extras_cost=cost,
        repeats=reps,
    )


def _check_design_args(c: Constraints, objective: str) -> None:
    check_constraints(c)
    if objective not in OBJECTIVES:
        raise CalibError(f"unknown objective {objective!r}", "--objective", "use worst, D, A or E")


def _select(answers, exact, tolerance_deg, batch: int = 1):
    """The final check (IPOPT inside the box) of each distinct answer; the best final
    figure: ``(worst, name, Robustness, ExtrasCost, Sequence, pool entry)``.

    The search inside the box can only raise an answer's box figure (``f[0]``), so an
    answer whose box figure is not below the best final figure so far cannot win and
    is not checked; answers go best box figure first, ``batch`` at a time (the workers).
    """
    first = {}
    for f in answers:
        first.setdefault((f[3], tuple(f[2])), f)
    order = sorted(first.values(), key=lambda f: (f[0], f[1]))
    return _pruned(order, lambda fs: exact([(f[3], tuple(f[2]), True, tolerance_deg) for f in fs]), batch)[0]


def _pruned(order, score, batch: int):
    """Score entries (sorted by a lower bound ``f[0]`` of their score) ``batch`` at a time,
    skipping those whose bound is not below the best score so far.

    Returns ``(best, scored)``: ``best`` = the best ``score(f) + (f,)``, ``scored`` every
    ``(result, f)`` scored, in order. Exact: ``score(f)[0] >= f[0]`` for every entry.
    """
    best, scored, k = None, [], 0
    while k < len(order):
        todo = [f for f in order[k : k + batch] if best is None or (f[0], f[1]) < (best[0], best[-1][1])]
        k += batch
        if not todo:
            break  # sorted by bound: nothing later can win either
        for f, out in zip(todo, score(todo)):
            scored.append((out, f))
            if best is None or (out[0], f[1]) < (best[0], best[-1][1]):
                best = tuple(out) + (f,)
    return best, scored


def _boxed(screened, exact, tolerance_deg, progress, batch: int = 1) -> list:
    """The best of the :data:`SCREEN_KEEP` screened candidates, worst over the box, best first.

    The nominal mounting is one of the box's points, so a candidate's nominal figure is
    a lower bound of its box figure: one whose nominal figure is not below the best box
    figure so far cannot come first and is not re-scored (only the first is used).
    """
    top = screened[:SCREEN_KEEP]
    _, scored = _pruned(top, lambda fs: exact([(f[3], tuple(f[2]), False, tolerance_deg) for f in fs]), batch)
    pool = []
    for (worst, wname, *_), f in scored:
        pool.append((worst,) + f[1:])
        if progress:
            progress(
                f"box worst of {f[1][:40]}...: {worst:.3f} ({wname}); "
                f"best so far {min(p[0] for p in pool):.3f}",
                1,
            )
    if progress and len(scored) < len(top):
        progress(
            f"{len(top) - len(scored)} candidates skipped: their nominal figure is "
            f"already above the best box worst",
            len(top) - len(scored),
        )
    return sorted(pool, key=lambda f: (f[0], f[1]))


def _screen(candidates, exact, progress) -> list:
    """Every candidate scored exactly at the nominal mounting, best first:
    ``(worst, label, dwells, walk, repeats)``.
    """
    if not candidates:
        raise CalibError(
            "no walk fits the constraints",
            "design",
            "raise --budget-min or --max-flips, or lower --min-dwell-s",
        )
    jobs = [(walk, (dwell,) * (len(walk) + 1), False, 0.0) for walk, dwell, _ in candidates]
    screened = []
    for (walk, dwell, reps), (worst, wname, *_) in zip(candidates, exact(jobs)):
        screened.append((worst, " ".join(m.label() for m in walk), [dwell] * (len(walk) + 1), walk, reps))
        if progress:
            progress(
                f"screened {len(screened)} ({len(walk)} moves, {dwell:g} s dwells): "
                f"{worst:.3f} ({wname}) at the nominal mounting",
                1,
            )
    return sorted(screened, key=lambda f: (f[0], f[1]))


def _refined(best, c, latitude_rad, height_m, profile, objective, requirements, exact, progress):
    """The best candidate with IPOPT-refined dwells, exactly re-scored ([] if unchanged)."""
    worst, label, dwells, walk, reps = best
    if progress:
        progress(f"refining the dwells of {label} with IPOPT", 0)
    new_dwells, _, _ = refine_dwells(
        walk, c, dwells[0], latitude_rad, height_m, profile, objective, requirements, reps
    )
    if new_dwells == dwells:
        return []
    w2, n2, _, _, _ = exact(walk, tuple(new_dwells))
    if progress:
        progress(f"refined: {w2:.3f} ({n2}) against {worst:.3f} uniform", 1)
    return [(w2, label + " (refined)", new_dwells, walk, reps)]
