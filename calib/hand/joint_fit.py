"""The 21 parameters of a run placed by hand: rests and moves, fitted together.

A person turns the unit between still poses, fast and about any axis, and
carries it on the way: its velocity is zero only at the rests. The fit uses
what holds whatever the hand did:

* at each rest ``r``, the mean specific force and the mean rate are gravity
  and the Earth rate seen in the rest's attitude ``C_r`` through the sensor
  errors: ``f = A_a C_r^T (0, 0, g) + b_a``, ``w = A_g C_r^T omega_ie + b_g``,
  weighted by the profile's VRW and ARW over the rest's length;
* across each move, the compensated gyro increments chained by the coning rule
  (:mod:`calib.hand.moves`) turn ``C_r`` into ``C_{r+1}`` (with the Earth's turn
  over the move), weighted by the ARW over the move's length. The accelerometers
  during a move (the hand's translation) are not used.

Optional terms the data may ask for (:mod:`calib.hand.calibrate` chooses them): the gyros'
g-sensitivity ``G`` (the rest rates and the moves' increments read ``+ G f``), and the
accelerometers' bias drift ``d``: at a rest of middle time ``tau`` (from the rests' middle)
the specific force reads ``+ d tau`` (the moves use the bias at the rests' middle: over a
move of seconds the drift is micro-g); and the gyros' bias drift ``d_g``: the rest rates read
``+ d_g tau`` and each move's increments lose the bias at the move's middle
(:mod:`calib.hand.drift`). With a drift, the biases reported are the last rest's.

The unknowns are the 21, each rest's attitude and the horizontal Earth rate in
the first rest's heading frame (a MEMS gyro cannot see it: it carries the prior
of an unknown heading, each component ``Omega cos(lat) / sqrt(2)``; a
navigation-grade one finds it, gyrocompassing). The first rest's heading is
the frame's, so its attitude has two unknowns (tilts), the others three.
Gauss-Newton iterates from a start built by chaining the moves and levelling
each rest on its accelerometers, until each step is below 1e-3 sigma.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from calib.errors import CalibError
from calib.model import params as P
from calib.model.error_model import ErrorModel, error_matrix_jacobian
from calib.model.information import scaled_inverse
from calib.model.optional_terms import G_SENSITIVITY_SI_PER_UNIT
from calib.model.requirements import Requirements
from calib.nav import earth
from calib.nav.site import Site
from calib.nav.transform import dcm_to_rotvec, rotvec_to_dcm, skew
from calib.noise.profiles import NoiseProfile

from . import weights as W
from .chain import chained_start, compensated
from .data import POSE_APART_DEG, HandData, distinct_poses, hand_data
from .drift import at_last_rest, drift_times
from .fit_options import HAND_FIT, HandFitOptions, HandSamples
from .moves import move_rotation, move_sensitivity, right_jacobian_inverse
from .rests import brief_new_faces, brief_pose_lines
from .rounding import consider_rounding
from .weak import split_weak
from .weights import Weights, component_sizes, components, profile_outliers, redundancy, refuted, reweighted

N = P.N_PARAMS
N_GS = 9  # the gyro g-sensitivity matrix, when fitted
N_DRIFT = 3  # the accelerometer's bias drift, per second, when fitted
MAX_ITERATIONS = 30
MAX_REWEIGHTS = 12  # the weights settle in 3-6 rounds on the real recordings
STEP_TOL_SIGMA = 1e-3
ATTITUDE_SCALE = 1e-3  # rad: the size an attitude unknown is judged at by the observability rule
_ACCEL_DA = error_matrix_jacobian("accel")
_GYRO_DA = error_matrix_jacobian("gyro")


@dataclass
class HandFit:
    """The fit's result (SI).

    ``covariance`` is over all unknowns (:class:`Layout`); ``rest_chi2`` and ``move_chi2`` are each
    observation group's whitened residual power (6 and 3 scalars).
    """

    values: np.ndarray
    g_sensitivity: np.ndarray | None  # (3, 3) (rad/s)/(m/s^2), when fitted
    covariance: np.ndarray
    C_rest: np.ndarray  # (K, 3, 3) body to ENU at each rest
    earth_rate_h: np.ndarray  # (2,) horizontal Earth rate in the first rest's heading frame
    converged: bool
    iterations: int
    chi2: float
    dof: int
    rest_chi2: np.ndarray
    move_chi2: np.ndarray
    residual_rms_mps2: float
    data: HandData
    layout: Layout
    estimable: np.ndarray  # over the 21 and the g-sensitivity
    null_directions: list = field(default_factory=list)  # over the parameters' names alone
    loose_rests: list = field(default_factory=list)  # blocks of rests no fitting move ties (calib.hand.weak)
    history: list = field(default_factory=list)
    weights: Weights = field(default_factory=Weights)
    log_likelihood: float = 0.0  # Gaussian, at the weights earned (up to a constant): compares models
    weight_sizes: dict = field(default_factory=dict)  # the non-white components in the user's units
    bias_drift: np.ndarray | None = None  # (3,) accelerometer bias drift, m/s^2 per s, when fitted
    gyro_drift: np.ndarray | None = None  # (3,) gyro bias drift, rad/s per s, when fitted

    @property
    def chi2_per_dof(self) -> float:
        return self.chi2 / max(self.dof, 1)

    @property
    def n_observations(self) -> int:
        return self.dof + len(self.covariance)


@dataclass(frozen=True)
class Layout:
    """Where each unknown sits: ``[21, g-sensitivity (9 or none), accelerometer bias drift (3 or
    none), gyro bias drift (3 or none), h_E, h_N, rest 0's two tilts, three per further rest]``.
    """

    rests: int
    g_sensitivity: bool
    bias_drift: bool = False
    gyro_drift: bool = False

    @property
    def gs(self) -> slice:
        return slice(N, N + (N_GS if self.g_sensitivity else 0))

    @property
    def drift(self) -> slice:
        return slice(self.gs.stop, self.gs.stop + (N_DRIFT if self.bias_drift else 0))

    @property
    def gdrift(self) -> slice:
        return slice(self.drift.stop, self.drift.stop + (N_DRIFT if self.gyro_drift else 0))

    @property
    def h(self) -> slice:
        return slice(self.gdrift.stop, self.gdrift.stop + 2)

    @property
    def n(self) -> int:
        return self.h.stop + 2 + 3 * (self.rests - 1)

    def columns(self, r: int) -> tuple[np.ndarray, np.ndarray]:
        """Columns of rest ``r``'s attitude unknowns and the map from them to its 3-vector."""
        first = self.h.stop
        if r == 0:
            return np.array([first, first + 1]), np.eye(3)[:, :2]
        c = first + 2 + 3 * (r - 1)
        return np.arange(c, c + 3), np.eye(3)

    def names(self) -> tuple:
        gs = [f"gs{i}{m}" for i in "xyz" for m in "xyz"] if self.g_sensitivity else []
        dr = [f"dba{a}" for a in "xyz"] if self.bias_drift else []
        dr += [f"dbg{a}" for a in "xyz"] if self.gyro_drift else []
        rest = [f"rest0_tilt_{a}" for a in "EN"]
        rest += [f"rest{r}_{a}" for r in range(1, self.rests) for a in "ENU"]
        return (*P.NAMES, *gs, *dr, "earth_rate_E", "earth_rate_N", *rest)


@dataclass
class FitState:
    """The unknowns of one iteration (SI): the 21, the g-sensitivity, the Earth rate, the attitudes."""

    values: np.ndarray  # (21,)
    G: np.ndarray  # (3, 3) gyro g-sensitivity, (rad/s)/(m/s^2)
    h: np.ndarray  # (2,)
    C: np.ndarray  # (K, 3, 3)
    D: np.ndarray = field(default_factory=lambda: np.zeros(N_DRIFT))  # accelerometer bias drift, (m/s^2)/s
    Dg: np.ndarray = field(default_factory=lambda: np.zeros(N_DRIFT))  # gyro bias drift, (rad/s)/s

    def omega_n(self, latitude_rad: float) -> np.ndarray:
        return np.array([self.h[0], self.h[1], earth.RATE * math.sin(latitude_rad)])

    def update(self, step: np.ndarray, layout: Layout) -> None:
        self.values = self.values + step[:N]
        if layout.g_sensitivity:
            self.G = self.G + step[layout.gs].reshape(3, 3)
        if layout.bias_drift:
            self.D = self.D + step[layout.drift]
        if layout.gyro_drift:
            self.Dg = self.Dg + step[layout.gdrift]
        self.h = self.h + step[layout.h]
        for r in range(layout.rests):
            cols, Smap = layout.columns(r)
            self.C[r] = rotvec_to_dcm(Smap @ step[cols]) @ self.C[r]


def linearise(
    data: HandData,
    samples: HandSamples,
    state: FitState,
    layout: Layout,
    site: Site,
    profile,
    heading_prior=True,
):
    """Residuals, their sigmas, the Jacobian of the predictions, and each row's group."""
    dtheta, dv, dt = samples.dtheta, samples.dv, samples.dt
    latitude_rad = site.latitude_rad
    model = ErrorModel(state.values)
    A_g, A_a, G, C = model.gyro_matrix, model.accel_matrix, state.G, state.C
    omega_n = state.omega_n(latitude_rad)
    f_n = earth.specific_force_n(site.gravity_mps2)
    rows, res, sig, group = [], [], [], []
    drifts = layout.bias_drift or layout.gyro_drift
    tau, tau_move = drift_times(data, dt) if drifts else (np.zeros(data.count), np.zeros(data.count - 1))

    def add(jac, r, s, grp):
        rows.append(jac)
        res.append(r)
        sig.append(s)
        group.append(grp)

    for r in range(data.count):
        cols, Smap = layout.columns(r)
        T = data.rest_time_s[r]
        u_f, u_w = C[r].T @ f_n, C[r].T @ omega_n
        J = np.zeros((3, layout.n))
        J[:, :N] = np.einsum("pjk,k->jp", _ACCEL_DA, u_f)
        J[:, P.ACCEL_BIAS] = np.eye(3)
        J[:, cols] = (A_a @ C[r].T @ skew(f_n)) @ Smap
        if layout.bias_drift:
            J[:, layout.drift] = np.eye(3) * tau[r]
        noise_f, noise_w = data.rest_noise[r]
        add(
            J,
            data.rest_force[r] - (A_a @ u_f + model.accel_bias + state.D * tau[r]),
            noise_f * profile.vrw / math.sqrt(T),
            ("force", r),
        )
        J = np.zeros((3, layout.n))
        J[:, :N] = np.einsum("pjk,k->jp", _GYRO_DA, u_w)
        J[:, P.GYRO_BIAS] = np.eye(3)
        if layout.g_sensitivity:
            J[:, layout.gs] = np.kron(np.eye(3), u_f)
        J[:, layout.h] = A_g @ C[r].T[:, :2]
        J[:, cols] = (A_g @ C[r].T @ skew(omega_n) + G @ C[r].T @ skew(f_n)) @ Smap
        if layout.gyro_drift:
            J[:, layout.gdrift] = np.eye(3) * tau[r]
        pred = A_g @ u_w + model.gyro_bias + state.Dg * tau[r] + G @ u_f
        add(J, data.rest_rate[r] - pred, noise_w * profile.arw / math.sqrt(T), ("rate", r))
    for r, sl in enumerate(data.move_slices):
        if not data.move_used[r]:
            continue
        at_move = model
        if layout.gyro_drift:  # the gyro's bias at the move's middle
            values = state.values.copy()
            values[P.GYRO_BIAS] += state.Dg * tau_move[r]
            at_move = ErrorModel(values)
        dth, dv_true, before, A_inv = compensated(dtheta, dv, dt, sl, at_move, G)
        R, Q, phi = move_rotation(dth, before)
        T = float(dt[sl].sum())
        R_E = rotvec_to_dcm(-omega_n * T)
        E = R.T @ C[r].T @ R_E.T @ C[r + 1]
        G_b, G_A, G_G = move_sensitivity(dth, dt[sl], A_inv, R, Q, phi, dv_true)
        J = np.zeros((3, layout.n))
        J[:, :N] = E.T @ np.einsum("ajk,pjk->ap", G_A, _GYRO_DA)
        J[:, P.GYRO_BIAS] = E.T @ G_b
        if layout.gyro_drift:
            J[:, layout.gdrift] = E.T @ G_b * tau_move[r]
        if layout.g_sensitivity:
            J[:, layout.gs] = E.T @ G_G.reshape(3, 9)
        J[:, layout.h] = T * C[r + 1].T[:, :2]
        c0, S0 = layout.columns(r)
        c1, S1 = layout.columns(r + 1)
        J[:, c0] = -(C[r + 1].T @ R_E) @ S0
        J[:, c1] = C[r + 1].T @ S1
        e0 = dcm_to_rotvec(E)
        # Each unknown turns E on its right (E exp(x)): the residual moves by J_r^-1(e0) x.
        add(right_jacobian_inverse(e0) @ J, -e0, profile.arw * math.sqrt(T), ("move", r))
    if heading_prior:  # the prior of an unknown heading on the horizontal Earth rate
        J = np.zeros((2, layout.n))
        J[:, layout.h] = np.eye(2)
        add(J, -state.h, earth.RATE * math.cos(latitude_rad) / math.sqrt(2.0), ("prior", 0))
    jac = np.vstack(rows)
    e = np.concatenate(res)
    s = np.concatenate([np.full(len(x), sg) for x, sg in zip(res, sig, strict=True)])
    groups = [grp for x, grp in zip(res, group, strict=True) for _ in range(len(x))]
    return e, s, jac, groups


def unknown_scales(layout: Layout, req: Requirements, latitude_rad: float) -> np.ndarray:
    """The size each unknown is judged at: requirements, 10 deg/h/g, the Earth rate, a milliradian."""
    scale = np.full(layout.n, ATTITUDE_SCALE)
    scale[:N] = req.si
    scale[layout.gs] = 10.0 * G_SENSITIVITY_SI_PER_UNIT
    if layout.bias_drift:  # a bias's requirement over 100 s
        scale[layout.drift] = req.si[P.ACCEL_BIAS] / 100.0
    if layout.gyro_drift:
        scale[layout.gdrift] = req.si[P.GYRO_BIAS] / 100.0
    scale[layout.h] = earth.RATE * max(math.cos(latitude_rad), 0.1)
    return scale


def fit_by_hand(
    samples: HandSamples,
    site: Site,
    profile: NoiseProfile,
    options: HandFitOptions = HAND_FIT,
    *,
    weights: Weights | None = None,
    where: str = "run",
) -> HandFit:
    """Fit the 21 parameters of a run placed by hand (see the module's model).

    Parameters
    ----------
    samples : HandSamples
        The run's increments, sample intervals and clipped samples.
    site : Site
        Latitude and gravity.
    profile : NoiseProfile
        White noise that finds the rests and weights the fit.
    options : HandFitOptions
        What is fitted and how (g-sensitivity, requirements, partial, heading prior,
        earned weights, the rest finder's loosening).
    weights : Weights, optional
        The weights to start from (default: the profile's).
    where : str
        The run's name in messages.
    """
    if profile.has_gauss_markov:
        raise CalibError(
            f"profile {profile.name!r} has a Gauss-Markov bias; the fit of a run placed by hand "
            "weights rests and moves with white noise only",
            where,
            "give its white part (calib.noise.profiles.white_part; calibrate does so itself)",
        )
    o = options
    data = hand_data(samples.dtheta, samples.dv, samples.dt, profile, samples.clipped, where, o.loosen)
    alone = replace(data, move_used=np.zeros_like(data.move_used))
    if not o.use_moves:
        return _fit(alone, samples, site, profile, o, weights, where)
    force_confirmed = None
    if o.earn_weights and data.move_used.any():
        # The rests alone say which rests' specific force is outlying (weights.confirmed).
        view = replace(o, use_moves=False, partial=True, g_sensitivity=False)
        blocks = _fit(alone, samples, site, profile, view, None, where).weights.block
        force_confirmed = frozenset(lab for lab in blocks if lab[0] == "force")
    return _fit(data, samples, site, profile, o, weights, where, force_confirmed)


def _held_too_briefly(data: HandData, samples: HandSamples) -> str:
    """The brief poses said where one holds a face no rest does: held longer, not added."""
    if not brief_new_faces(data.rests, samples.dv / samples.dt[:, None]):
        return ""
    return "; " + brief_pose_lines(data.rests, np.concatenate([[0.0], np.cumsum(samples.dt)]))[0]


def _fit(
    data: HandData,
    samples: HandSamples,
    site: Site,
    profile: NoiseProfile,
    o: HandFitOptions,
    weights: Weights | None,
    where: str,
    force_confirmed: frozenset | None = None,
) -> HandFit:
    """:func:`fit_by_hand` on the rests and moves ``data`` holds (a move not used is not chained)."""
    latitude_rad = site.latitude_rad
    dtheta, dv, dt = samples.dtheta, samples.dv, samples.dt
    layout = Layout(data.count, o.g_sensitivity, o.bias_drift, o.gyro_drift)
    values = np.zeros(N)
    values[P.GYRO_BIAS] = np.average(data.rest_rate, axis=0, weights=data.rest_time_s)
    G = np.zeros((3, 3))
    omega_n = np.array([0.0, 0.0, earth.RATE * math.sin(latitude_rad)])
    C_start, gross = chained_start(data, dtheta, dv, dt, values, G, omega_n)
    state = FitState(values, G, np.zeros(2), C_start)
    scale = unknown_scales(layout, o.requirements, latitude_rad)
    names = layout.names()
    problem = _Problem(data, samples, layout, site, profile, o.heading_prior)
    history: list = []
    preset: set = set()
    if weights is None:
        # A gross move is weighted by its miss from the first step: at the profile's weights its
        # tens of degrees would drag every unknown before the outlier test could see it.
        weights = Weights()
        if o.earn_weights:
            for r, miss in gross.items():
                move_sigma = profile.arw * math.sqrt(float(dt[data.move_slices[r]].sum()))
                weights.block[("move", r)] = max(miss / move_sigma, 1.0)
            preset = set(weights.block)
    converged = False
    for rounds in range(MAX_REWEIGHTS if o.earn_weights else 1):
        converged = _gauss_newton(problem, state, weights, scale, names, history)
        if not o.earn_weights:
            break
        e, s, jac, labels = problem.linearised(state)
        shapes = components(labels, s, data.move_turn_rad)
        Jw = jac / weights.sigma(shapes, s, labels)[:, None] * scale
        inv = scaled_inverse(Jw.T @ Jw, names=names)
        red = redundancy(Jw, inv.covariance)
        if not weights.earning and set(weights.block) <= preset and rounds == 0:
            outliers = profile_outliers(e, red, labels, s, force_confirmed)
            weights = Weights(earning=refuted(e, red, labels, s, outliers))
        new = reweighted(weights, e, red, labels, shapes, s, force_confirmed)
        done = new.settled(weights, shapes, s, labels)
        # Settled: a group the others' misfit hid from the first look is judged again.
        weights = (W.refuted_later(new, e, red, labels, s) if done else None) or new
        if done and weights is new:
            break
    e, s, jac, labels = problem.linearised(state)
    shapes = components(labels, s, data.move_turn_rad)
    s = weights.sigma(shapes, s, labels)
    Jw = jac / s[:, None] * scale
    inv = scaled_inverse(Jw.T @ Jw, names=names)
    estimable = inv.estimable[: layout.h.start]
    unobserved, loose = split_weak(inv, layout.h.start, [layout.columns(r)[0] for r in range(data.count)])
    if not estimable.all() and not o.partial:
        missing = [n for n, ok in zip(names, estimable, strict=False) if not ok]
        raise CalibError(
            f"the poses do not separate every parameter ({data.count} rests in "
            f"{(n := distinct_poses(data.rest_force))} pose{'s' * (n != 1)} {POSE_APART_DEG:g} deg apart, "
            f"{int(data.move_used.sum())} of {len(data.move_used)} moves used): "
            + ("none is estimable" if not estimable.any() else "not estimable " + ", ".join(missing))
            + "; unobserved combinations: "
            + "; ".join(unobserved),
            where,
            "add poses that excite them (other faces up, turns about other axes), or --partial"
            + _held_too_briefly(data, samples),
        )
    z2 = (e / s) ** 2
    kind = np.array([g[0] for g in labels])
    index = np.array([g[1] for g in labels])
    at_rest = (kind == "force") | (kind == "rate")
    rest_chi2 = np.bincount(index[at_rest], z2[at_rest], minlength=data.count)
    move_chi2 = np.bincount(index[kind == "move"], z2[kind == "move"], minlength=data.count - 1).astype(float)
    move_chi2[~data.move_used] = np.nan
    force_rows = np.flatnonzero(kind == "force")
    inv_cov = consider_rounding(inv.covariance, Jw, s, labels, data.rest_rate_rounding)
    covariance = scale[:, None] * inv_cov * scale[None, :]
    values, covariance = at_last_rest(state, covariance, layout, data, samples.dt)
    return HandFit(
        values=values,
        g_sensitivity=state.G if o.g_sensitivity else None,
        covariance=covariance,
        C_rest=state.C.copy(),
        earth_rate_h=state.h,
        converged=converged,
        iterations=len(history),
        chi2=float(z2.sum()),
        log_likelihood=float(-0.5 * z2.sum() - np.log(s).sum()),
        dof=len(e) - inv.rank,
        rest_chi2=rest_chi2,
        move_chi2=move_chi2,
        residual_rms_mps2=float(np.sqrt(np.mean(e[force_rows] ** 2))),
        data=data,
        layout=layout,
        estimable=estimable,
        null_directions=unobserved,
        loose_rests=loose,
        history=history,
        weights=weights,
        weight_sizes=component_sizes(weights, shapes, labels, data.move_turn_rad),
        bias_drift=state.D.copy() if o.bias_drift else None,
        gyro_drift=state.Dg.copy() if o.gyro_drift else None,
    )


class _Problem(NamedTuple):
    """What stays fixed while the hand fit iterates: the data, its layout of unknowns, the site."""

    data: HandData
    samples: HandSamples
    layout: Layout
    site: Site
    profile: NoiseProfile
    heading_prior: bool

    def linearised(self, state: FitState):
        """:func:`linearise` of the problem at ``state``."""
        return linearise(
            self.data, self.samples, state, self.layout, self.site, self.profile, self.heading_prior
        )


def _gauss_newton(problem: _Problem, state: FitState, weights: Weights, scale, names, history) -> bool:
    """Iterate the unknowns at fixed weights until every step is below `STEP_TOL_SIGMA`."""
    data, layout = problem.data, problem.layout
    for _ in range(MAX_ITERATIONS):
        e, s, jac, labels = problem.linearised(state)
        s = weights.sigma(components(labels, s, data.move_turn_rad), s, labels)
        Jw = jac / s[:, None] * scale
        inv = scaled_inverse(Jw.T @ Jw, names=names)
        step = scale * (inv.covariance @ (Jw.T @ (e / s)))
        sigma = scale * np.sqrt(np.diag(inv.covariance))
        state.update(step, layout)
        max_step = float(np.max(np.abs(step) / np.where(sigma > 0, sigma, np.inf)))
        history.append({"iteration": len(history) + 1, "max_step_sigma": max_step})
        if max_step < STEP_TOL_SIGMA:
            return True
    return False
