"""The search's segments: the linear action of one rest or turn on the lifted state.

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
from dataclasses import dataclass

import numpy as np

from calib.model import params as P
from calib.nav import earth
from calib.nav.jacobian import (
    N_UNKNOWN,
    ObservationGrid,
    moment_inputs,
    observation_matrix,
    propagate,
    state_matrix,
    trajectory_moments,
)
from calib.nav.site import Site
from calib.nav.transform import AXES
from calib.noise.profiles import NoiseProfile
from calib.noise.whitening import interval_models, noise_model, whiten, whitener
from calib.sequence.definition import Timeline, nominal_attitude
from calib.sequence.kinematics import body_integrals

from .gm import SegmentColumns, noise_blocks
from .graph import attitude_of

SEARCH_REST_INTERVALS = 12  # per rest, whatever its length: smooth in the dwell for IPOPT
SEARCH_MOVE_STEP_S = 0.5  # observation interval while turning (0.1 s changes sigmas < 0.2 %)
SEARCH_SUB_DEG = 2.0  # sub-samples while turning
# With GM each interval costs a Riccati step per candidate; 2 s intervals in turns move the
# search score of designed-30min by 0.2 % against 0.5 s (measured under navigation-gm).
SEARCH_GM_MOVE_STEP_S = 1.0


@dataclass(frozen=True)
class SegmentEffect:
    """Linear action of one segment on the lifted state and the information."""

    A: np.ndarray  # (h, h); h = 6 + filter states (9, or 15 with GM)
    B: np.ndarray  # (h, 24)
    M1: np.ndarray  # (h, h)
    M2: np.ndarray  # (h, 24)
    M3: np.ndarray  # (24, 24)


@dataclass(frozen=True)
class Segment:
    """One rest or turn of a walk: what its matrices depend on besides the site and the noise."""

    C: np.ndarray  # (3, 3) attitude at its start
    duration: float  # s
    rate: float = 0.0  # rad/s; 0: a rest
    axis: int = -1  # the body axis turned about (-1: a rest)

    def timeline(self) -> Timeline:
        """The segment as a one-step :class:`calib.sequence.definition.Timeline`."""
        return Timeline(
            t0=np.array([0.0]),
            t1=np.array([self.duration]),
            rate=np.array([self.rate]),
            axis=np.array([self.axis]),
            C0=self.C[None],
            position=np.array([1]),
            step=np.array([-1]),
            C_end=self.C,
        )


def rest_at(node, duration: float) -> Segment:
    """A rest of ``duration`` s at grid attitude ``node``."""
    return Segment(attitude_of(node), duration)


def turn_from(node, mv, duration: float, rate: float) -> Segment:
    """Move ``mv`` from grid attitude ``node``, ``duration`` s at ``rate`` rad/s."""
    return Segment(attitude_of(node), duration, rate, AXES.index(mv.axis))


def _segment_inputs(seg: Segment, site: Site, profile: NoiseProfile, n_intervals: int | None):
    """Model inputs (K, 6, 24), interval lengths and (with GM) mid-interval attitudes."""
    tl = seg.timeline()
    duration, rate = seg.duration, seg.rate
    if n_intervals is None:
        n_intervals = max(1, int(round(duration / SEARCH_MOVE_STEP_S)))
    sub = (
        4
        if rate == 0.0
        else max(1, int(math.ceil(abs(math.degrees(rate)) * duration / n_intervals / SEARCH_SUB_DEG)))
    )
    t_nav = np.linspace(0.0, duration, n_intervals * sub + 1)
    flip, E = body_integrals(tl, t_nav[1:])
    dtheta = flip + E @ site.omega_ie_n
    dv = E @ earth.specific_force_n(site.gravity_mps2)
    grid = ObservationGrid(np.arange(0, n_intervals * sub + 1, sub))
    moments = trajectory_moments(nominal_attitude(tl, t_nav), dtheta, dv, t_nav, grid)
    inputs = moment_inputs(moments, site)  # (K, 6, 24)
    T = np.diff(t_nav[grid.bounds])
    C_mid = None
    if profile.has_gauss_markov:  # bias-instability weights follow each interval's attitude
        b = grid.bounds
        C_mid = nominal_attitude(tl, t_nav)[(b[:-1] + b[1:]) // 2]
    return inputs, T, C_mid


def segment_columns(
    seg: Segment, site: Site, profile: NoiseProfile, n_intervals: int | None = None
) -> SegmentColumns:
    """A segment's unwhitened observation columns and noise blocks (exact GM search)."""
    inputs, T, C_mid = _segment_inputs(seg, site, profile, n_intervals)
    A6 = state_matrix(site)
    Phi_vv = np.array([m.Phi[3:6, 3:6] for m in interval_models(A6, T, profile, C_mid)])
    S0 = np.zeros((6, 6 + N_UNKNOWN))
    S0[:, :6] = np.eye(6)
    all_inputs = np.zeros((len(T), 6, 6 + N_UNKNOWN))
    all_inputs[:, :, 6:] = inputs
    S_v, S_end = propagate(all_inputs, T, S0, site, return_final=True)
    H = observation_matrix(S_v, Phi_vv)
    return SegmentColumns(H, S_end[:, :6], S_end[:, 6:], *noise_blocks(A6, T, profile, C_mid))


def segment_effect(
    seg: Segment,
    site: Site,
    profile: NoiseProfile,
    P0: np.ndarray | None,
    n_intervals: int | None = None,
    initial: bool = False,
) -> SegmentEffect:
    """The segment matrices of one rest or turn, by running the model on basis columns."""
    inputs, T, C_mid = _segment_inputs(seg, site, profile, n_intervals)
    noise = noise_model(state_matrix(site), T, profile, P0, C_mid)
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
    S_v, S_end = propagate(all_inputs, T, S0, site, return_final=True)
    w, phi_end = whiten(noise.whitener, observation_matrix(S_v, noise.Phi_vv), phi0, return_final=True)
    Wh, Wp = w[:, :, :n_hom], w[:, :, n_hom:]
    M1 = np.einsum("kia,kib->ab", Wh, Wh)
    M2 = np.einsum("kia,kib->ab", Wh, Wp)
    M3 = np.einsum("kia,kib->ab", Wp, Wp)
    X = np.vstack([S_end, phi_end])
    return SegmentEffect(A=X[:, :n_hom], B=X[:, n_hom:], M1=M1, M2=M2, M3=M3)


def rest_steady_state(site: Site, profile: NoiseProfile, dwell_s: float) -> np.ndarray:
    """Noise-filter covariance after a long rest observed with the search's rest intervals.

    With Gauss-Markov biases the filter state is ``[phi, b_g, b_a]`` (body frame); the
    rest is then taken at the identity attitude, which makes the result the covariance
    with the biases in the navigation frame: :func:`start_covariance` rotates it into
    any attitude's body frame (the model is rotation-invariant in that frame, see
    :func:`calib.noise.whitening.gm_interval_nav`).
    """
    T = np.full(40 * SEARCH_REST_INTERVALS, dwell_s / SEARCH_REST_INTERVALS)
    C = np.broadcast_to(np.eye(3), (len(T), 3, 3)) if profile.has_gauss_markov else None
    return whitener(interval_models(state_matrix(site), T, profile, C)).P_end


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


@functools.lru_cache(maxsize=4096)
def rest_columns(node, duration, site: Site, profile):
    """A rest's observation columns at grid attitude ``node`` (cached: exact GM search)."""
    return segment_columns(rest_at(node, duration), site, profile, SEARCH_REST_INTERVALS)


@functools.lru_cache(maxsize=4096)
def turn_columns(node, mv, duration, rate, site: Site, profile):
    """A turn's observation columns from ``node`` (cached: exact GM search)."""
    n_intervals = max(1, int(round(duration / SEARCH_GM_MOVE_STEP_S)))
    return segment_columns(turn_from(node, mv, duration, rate), site, profile, n_intervals)


@functools.lru_cache(maxsize=4096)
def turn_effect(node, mv, duration, rate, site: Site, profile, P_bytes):
    """A turn's segment matrices from ``node``, the rest steady state ``P_ss`` as bytes (cached)."""
    n = int(round(math.sqrt(len(P_bytes) // 8)))
    P_ss = np.frombuffer(P_bytes).reshape(n, n)
    seg = turn_from(node, mv, duration, rate)
    return segment_effect(seg, site, profile, start_covariance(P_ss, seg.C))
