"""The linearised error-to-observation Jacobian (casadi), shared by the estimator and the analyser.

Error state ``x = [phi, dv]`` (attitude error with ``C~ = (I - [phi x]) C``,
velocity error), ENU, on a stationary base::

    phi' = -omega_ie x phi - C_b_n d_omega
    dv'  =  f_n x phi + C_b_n d_f - 2 omega_ie x dv

with ``f_n = [0, 0, g]`` and the sensor errors ``d_omega = E_g omega + b_g``,
``d_f = E_a f + b_a`` of :mod:`calib.model.error_model`. The dynamics are
time-invariant; only the input ``C_b_n (E w + b)`` varies. Over an
observation interval ``[t_{k-1}, t_k]`` the input of every sample is
propagated to ``t_k`` with ``exp(A tau)`` expanded to second order in
``tau`` (the neglected terms are ``(omega_ie tau)^2 ~ 1e-7`` relative), so
the interval needs only kinematic *moments* of the trajectory::

    sum_j tau_j^w  C_j[:, i] dtheta_j[m]   and   sum_j tau_j^w C_j[:, i] h_j

Casadi differentiates the interval step (error model composed with the
propagation) with respect to the state and the parameters; the sensitivity
``S = dx / d(params, phi0)`` is then carried through the intervals.

The optional terms of :mod:`calib.model.optional_terms` are accelerometer errors with
known per-sample sensitivities ``D_j``; their moments ``sum tau^w C D`` go
through the same accelerometer channel of the step and add columns after
``phi0``.

Observations: the navigation velocity at the interval ends ``y_k``, taken as
``z_k = y_k - Phi_vv(T_k) y_{k-1}``, so that ``z_k = H_k p + Phi_vphi phi_noise
+ w_k`` with ``H_k = E S_k - Phi_vv E S_{k-1}`` (see :mod:`calib.noise.whitening`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi as ca
import numpy as np

from calib.model import params as P
from calib.model.optional_terms import NONE as NO_EXTRAS, OptionalTerms, dv_sensitivity, earth_turn

from . import earth
from .site import Site
from .transform import skew

N_UNKNOWN = P.N_PARAMS + 3  # the 21 parameters and the initial attitude error phi0
PHI0 = slice(P.N_PARAMS, N_UNKNOWN)
N_MOMENTS = 5 * 36  # gyro (1, tau, tau^2) and accel (1, tau), 27 + 9 each
REST_STEP_S = 1.0  # observation interval at rest; 0.25 s changes no sigma by 1e-4
MOVE_STEP_S = 0.1  # observation interval while turning


@dataclass(frozen=True)
class ObservationGrid:
    """Interval ends as sample indices into the navigation arrays (0 = start)."""

    bounds: np.ndarray  # (K + 1,), increasing, bounds[0] == 0

    @property
    def n_intervals(self) -> int:
        return len(self.bounds) - 1


def observation_grid(moving: np.ndarray, rest_step: int, move_step: int) -> ObservationGrid:
    """Split samples into intervals: ``rest_step`` samples at rest, ``move_step`` while turning.

    Parameters
    ----------
    moving : ndarray of bool, shape (n,)
        Per sample, whether the IMU is turning.
    rest_step, move_step : int
        Interval lengths in samples.
    """
    n = len(moving)
    change = np.flatnonzero(np.diff(moving.astype(np.int8))) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [n]])
    bounds = [0]
    for a, b in zip(starts, ends, strict=True):
        step = move_step if moving[a] else rest_step
        m = max(1, int(round((b - a) / step)))
        bounds.extend(np.round(np.linspace(a, b, m + 1)[1:]).astype(int))
    return ObservationGrid(np.unique(np.array(bounds)))


def default_grid(moving: np.ndarray, sample_rate_hz: float) -> ObservationGrid:
    """The observation intervals the estimator and the analyser both use."""
    return observation_grid(
        moving, max(1, round(REST_STEP_S * sample_rate_hz)), max(1, round(MOVE_STEP_S * sample_rate_hz))
    )


def state_matrix(site: Site) -> np.ndarray:
    """Continuous error-state matrix ``A`` (6 x 6) at a site (its latitude and gravity)."""
    W = skew(earth.omega_ie_n(site.latitude_rad))
    F = skew(earth.specific_force_n(site.gravity_mps2))
    A = np.zeros((6, 6))
    A[:3, :3] = -W
    A[3:, :3] = F
    A[3:, 3:] = -2.0 * W
    return A


@dataclass(frozen=True)
class Trajectory:
    """A trajectory the linear model is evaluated along (:func:`observation_jacobian`).

    The estimator's is a navigation of the log, the analyser's a sequence's nominal
    motion (:class:`calib.analysis.nominal.NominalRun`).
    """

    time_nav: np.ndarray  # (n + 1,) sample boundary times
    C_b_n: np.ndarray  # (n + 1, 3, 3) attitude at the sample boundaries
    dtheta: np.ndarray  # (n, 3) the samples' increments (compensated, as navigated)
    dv: np.ndarray  # (n, 3)
    grid: ObservationGrid


@dataclass(frozen=True)
class SampleLayout:
    """Per-sample quantities of the samples ``grid`` covers, shared by every moment."""

    C_mid: np.ndarray  # (m, 3, 3) mid-sample attitude
    h: np.ndarray  # (m,) sample lengths
    tau: np.ndarray  # (m,) time from the sample's middle to its interval's end
    starts: np.ndarray  # (K,) first sample of each interval, for np.add.reduceat
    samples: slice  # which samples of the trajectory these are


def sample_layout(C_b_n: np.ndarray, time_s: np.ndarray, grid: ObservationGrid) -> SampleLayout:
    """The :class:`SampleLayout` of a trajectory sampled at ``time_s`` (boundaries, 0 first)."""
    b = grid.bounds
    sl = slice(b[0], b[-1])
    interval = np.repeat(np.arange(len(b) - 1), np.diff(b))
    s_mid = 0.5 * (time_s[1:] + time_s[:-1])[sl]
    return SampleLayout(
        C_mid=0.5 * (C_b_n[1:] + C_b_n[:-1])[sl],
        h=np.diff(time_s)[sl],
        tau=time_s[b[1:]][interval] - s_mid,
        starts=b[:-1] - b[0],
        samples=sl,
    )


def trajectory_moments(
    C_b_n: np.ndarray,
    dtheta: np.ndarray,
    dv: np.ndarray,
    time_s: np.ndarray,
    grid: ObservationGrid,
    layout: SampleLayout | None = None,
) -> np.ndarray:
    """Kinematic moments of every interval, shape ``(K, N_MOMENTS)``.

    Parameters
    ----------
    C_b_n : ndarray, shape (n + 1, 3, 3)
        Attitude at the sample boundaries (index 0 = start).
    dtheta, dv : ndarray, shape (n, 3)
        Increments of the samples (compensated, as navigated).
    time_s : ndarray, shape (n + 1,)
        Sample boundary times.
    layout : SampleLayout, optional
        :func:`sample_layout` of the same trajectory, if already computed.
    """
    L = layout or sample_layout(C_b_n, time_s, grid)
    sl, tau = L.samples, L.tau

    def block(inc):
        K = np.einsum("nai,nm->naim", L.C_mid, inc[sl]).reshape(-1, 27)
        B = (L.C_mid * L.h[:, None, None]).reshape(-1, 9)
        return np.hstack([K, B])

    gyro, accel = block(dtheta), block(dv)
    out = [
        np.add.reduceat(gyro, L.starts, axis=0),
        np.add.reduceat(gyro * tau[:, None], L.starts, axis=0),
        np.add.reduceat(gyro * (tau**2)[:, None], L.starts, axis=0),
        np.add.reduceat(accel, L.starts, axis=0),
        np.add.reduceat(accel * tau[:, None], L.starts, axis=0),
    ]
    return np.hstack(out)


def _sensor_terms(moments, values, sensor: str, K_off: int):
    """``sum C (E inc + b h)`` written with casadi: moments (27 + 9) and parameter symbols."""
    bias = P.GYRO_BIAS if sensor == "gyro" else P.ACCEL_BIAS
    K = moments[K_off : K_off + 27]
    B = moments[K_off + 27 : K_off + 36]
    out = ca.SX.zeros(3)
    for p in P.PARAMETERS:
        if p.sensor != sensor or p.kind == "bias":
            continue
        # K is laid out [a, i, m] -> a*9 + i*3 + m: nav axis a, sensor i, body axis m.
        out += ca.vertcat(*[K[a * 9 + p.row * 3 + p.col] for a in range(3)]) * values[p.index]
    for i, idx in enumerate(range(bias.start, bias.stop)):
        out += ca.vertcat(*[B[a * 3 + i] for a in range(3)]) * values[idx]
    return out


@dataclass(frozen=True)
class StepModel:
    """Derivatives of the interval step, from casadi's AD of the symbolic step.

    ``x_next = Phi(T) x + u(moments, params)``; the step is affine, so its
    derivatives are exact: ``Phi(T) = d x_next / d x`` (a function of the
    interval length) and ``d x_next / d params = input_map . moments``.
    An optional term (:mod:`calib.model.optional_terms`) is one more accelerometer error
    whose nav-frame moments ``[sum C D, sum tau C D]`` enter through the same
    accelerometer channel: ``d x_next / d q = extra_map . moments``.
    """

    transition: ca.Function  # T -> Phi (6 x 6)
    input_map: np.ndarray  # (N_MOMENTS, 6 * N_UNKNOWN), column-major blocks of d x_next / d p
    extra_map: np.ndarray  # (6, 6): [sum C D (3), sum tau C D (3)] -> d x_next / d q


@functools.lru_cache(maxsize=16)
def step_model(site: Site) -> StepModel:
    """Build the symbolic interval step for a site and differentiate it (cached per site)."""
    A = state_matrix(site)
    W = skew(site.omega_ie_n)
    F = skew(earth.specific_force_n(site.gravity_mps2))
    A2_vphi = -F @ W - 2.0 * W @ F

    def accel_input(a0, a1):
        """Velocity input of an accelerometer error with moments (1, tau)."""
        return a0 - 2.0 * ca.mtimes(ca.DM(W), a1)

    x = ca.SX.sym("x", 6)
    p = ca.SX.sym("p", N_UNKNOWN)
    m = ca.SX.sym("m", N_MOMENTS)
    T = ca.SX.sym("T")
    g0, g1, g2 = (_sensor_terms(m, p, "gyro", 36 * w) for w in range(3))
    a0, a1 = (_sensor_terms(m, p, "accel", 36 * (3 + w)) for w in range(2))
    AT = ca.DM(A) * T
    Phi: ca.DM | ca.SX = ca.DM.eye(6)
    term: ca.DM | ca.SX = ca.DM.eye(6)
    for k in range(1, 6):  # (omega_ie T)^5 terms are far below rounding
        term = ca.mtimes(term, AT) / k
        Phi = Phi + term
    u_phi = -(g0 - ca.mtimes(ca.DM(W), g1) + 0.5 * ca.mtimes(ca.DM(W @ W), g2))
    u_v = -(ca.mtimes(ca.DM(F), g1) + 0.5 * ca.mtimes(ca.DM(A2_vphi), g2)) + accel_input(a0, a1)
    x_next = ca.mtimes(Phi, x) + ca.vertcat(u_phi, u_v)
    transition = ca.Function("Phi", [T], [ca.jacobian(x_next, x)])
    # d x_next / d p is linear in the moments: its Jacobian w.r.t. them is constant.
    dx_dp = ca.vec(ca.jacobian(x_next, p))
    input_map = ca.Function("G", [m], [ca.jacobian(dx_dp, m)])(np.zeros(N_MOMENTS))
    mx = ca.SX.sym("mx", 6)
    q = ca.SX.sym("q")
    x_extra = ca.vertcat(ca.SX.zeros(3), accel_input(mx[:3] * q, mx[3:] * q))
    extra_map = ca.Function("Gx", [mx], [ca.jacobian(ca.jacobian(x_extra, q), mx)])(np.zeros(6))
    return StepModel(
        transition=transition,
        input_map=np.ascontiguousarray(np.asarray(ca.DM(input_map)).T),
        extra_map=np.asarray(ca.DM(extra_map)),
    )


def propagate(
    inputs: np.ndarray,
    T: np.ndarray,
    S0: np.ndarray,
    site: Site,
    return_final: bool = False,
    compiled: bool = False,
):
    """Velocity rows of ``S_k = Phi(T_k) S_{k-1} + inputs_k`` for any number of columns.

    ``compiled``: the recursion compiled (:func:`calib.noise.kernels.propagate_columns`, the
    same to rounding, ~7 x faster over a 30-min run), for the Gauss-Markov paths that
    load the compiled kernels anyway (their start-up is ~0.5 s once per process).

    Parameters
    ----------
    inputs : ndarray, shape (K, 6, c)
    T : ndarray, shape (K,)
    S0 : ndarray, shape (6, c)

    Returns
    -------
    ndarray, shape (K + 1, 3, c)
        And, with ``return_final``, the whole final ``S`` (6, c).
    """
    model = step_model(site)
    # Interval lengths repeat up to rounding; 1 ns changes Phi by ~1e-8 of its g T block.
    keys, index = np.unique(np.round(T, 9), return_inverse=True)
    Phis = [np.asarray(model.transition(t)) for t in keys]
    S = S0.copy()
    out = np.empty((len(T) + 1, 3, S0.shape[1]))
    if compiled:
        from calib.noise.kernels import compiled_arg, propagate_columns

        S = compiled_arg(S)
        Phi = np.array(Phis).reshape(len(keys), 6, 6)
        propagate_columns(Phi, compiled_arg(index, np.int64), compiled_arg(inputs), S, out)
        return (out, S) if return_final else out
    out[0] = S[3:]
    for k in range(len(T)):
        S = Phis[index[k]] @ S + inputs[k]
        out[k + 1] = S[3:]
    return (out, S) if return_final else out


def moment_inputs(moments: np.ndarray, site: Site) -> np.ndarray:
    """``d x_next / d(params, phi0)`` of each interval from its moments: ``(..., 6, N_UNKNOWN)``."""
    G = step_model(site).input_map
    lead = moments.shape[:-1]
    return (moments @ G).reshape(lead + (N_UNKNOWN, 6)).swapaxes(-1, -2)


def extra_inputs(
    dtheta: np.ndarray,
    dv: np.ndarray,
    layout: SampleLayout,
    extras: OptionalTerms,
    site: Site,
) -> np.ndarray:
    """``d x_next / d(extra parameters)`` of every interval: shape ``(K, 6, extras.n)``.

    The moments ``sum_j tau_j^w C_j D_j`` (w = 0, 1) of the per-sample
    sensitivities ``D_j`` of :func:`calib.model.optional_terms.dv_sensitivity`, mapped by
    the step model's accelerometer channel.
    """
    L, sl = layout, layout.samples
    if extras.n == 0:
        return np.zeros((len(L.starts), 6, 0))
    turn = earth_turn(L.C_mid, site.omega_ie_n, L.h)
    CD = np.einsum("nai,nic->nac", L.C_mid, dv_sensitivity(extras, dtheta[sl], dv[sl], L.h, turn))
    moments = np.concatenate(
        [np.add.reduceat(CD, L.starts, axis=0), np.add.reduceat(CD * L.tau[:, None, None], L.starts, axis=0)],
        axis=1,
    )
    G = step_model(site).extra_map
    return np.einsum("sm,kmc->ksc", G, moments)


def sensitivities(
    moments: np.ndarray,
    T: np.ndarray,
    site: Site,
    extra: np.ndarray | None = None,
    compiled: bool = False,
) -> np.ndarray:
    """``d(dv at each interval end) / d(params, phi0[, extras])``, shape ``(K + 1, 3, N_UNKNOWN [+ e])``.

    Carries ``S = dx / d(params, phi0)`` through the intervals:
    ``S_k = Phi(T_k) S_{k-1} + input_map . moments_k``, starting from
    ``dx/dphi0 = [I; 0]``. The inputs of all intervals are one matrix product;
    only the 6 x 24 recursion is a loop. (Measured: a casadi ``mapaccum`` of
    the same step took 33 ms for the paper's 1044 intervals against 15 ms
    here, most of it in casadi's VM and DM-to-numpy conversion.) ``extra``
    (``(K, 6, e)`` from :func:`extra_inputs`) appends the optional terms' columns;
    ``compiled`` as in :func:`propagate`.
    """
    inputs = moment_inputs(moments, site)
    if extra is not None and extra.shape[-1]:
        inputs = np.concatenate([inputs, extra], axis=2)
    S0 = np.zeros((6, inputs.shape[-1]))
    S0[:3, PHI0] = np.eye(3)
    return propagate(inputs, T, S0, site, compiled=compiled)


def observation_matrix(S_v: np.ndarray, Phi_vv: np.ndarray) -> np.ndarray:
    """``H_k = S_v[k] - Phi_vv[k] S_v[k-1]``, shape ``(K, 3, columns)``."""
    return S_v[1:] - np.einsum("kij,kjn->kin", Phi_vv, S_v[:-1])


def observation_jacobian(
    trajectory: Trajectory,
    site: Site,
    Phi_vv: np.ndarray,
    extras: OptionalTerms = NO_EXTRAS,
    compiled: bool = False,
) -> np.ndarray:
    """``H`` of every interval along a trajectory, shape ``(K, 3, N_UNKNOWN + extras.n)``.

    The one linear model of the tool: the estimator evaluates it along the
    navigated trajectory, the analyser along the nominal one. Columns: the
    21 parameters, the initial attitude error, then the switched-on extras.
    ``compiled`` as in :func:`propagate`.
    """
    tr = trajectory
    layout = sample_layout(tr.C_b_n, tr.time_nav, tr.grid)
    moments = trajectory_moments(tr.C_b_n, tr.dtheta, tr.dv, tr.time_nav, tr.grid, layout)
    T = np.diff(tr.time_nav[tr.grid.bounds])
    extra = extra_inputs(tr.dtheta, tr.dv, layout, extras, site)
    S_v = sensitivities(moments, T, site, extra, compiled)
    return observation_matrix(S_v, Phi_vv)
