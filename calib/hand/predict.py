"""The sigmas a pose plan will give, fast: the fit's own rows, without a simulated run.

:func:`calib.hand.joint_fit` linearises rests and moves; here the same function is handed what a
recording of a plan would give it at the truth (no errors): each rest's mean specific force and
rate (gravity and the Earth rate in the rest's attitude) and each move's gyro increments along its
tip, sampled finely enough for the move's sensitivity (the rotation is exact whatever the
sampling). The rests gain the still ends of the moves and lose :data:`TRIM_S` at each end to the
rest finder, and the moves the reverse, as on the simulator's run. ``seqdesign.hand.prediction``
predicts through the simulator and the rest finder; this is the design search's fast path,
checked against it in the tests (1.5 %).
"""

from __future__ import annotations

import math

import numpy as np

from calib.model import params as P
from calib.model.information import scaled_inverse
from calib.model.requirements import Requirements
from calib.nav import earth
from calib.nav.site import Site
from calib.nav.transform import dcm_to_rotvec, rotvec_to_dcm
from calib.noise.profiles import NoiseProfile

from .fit_options import HandSamples
from .joint_fit import FitState, HandData, Layout, linearise, unknown_scales
from .plan import min_jerk
from .poses import TURN_FRACTION
from .rests import Rests

TRIM_S = 0.35  # what the rest finder takes from each end of a rest, noise free (its reach; fitted
# to the simulated prediction of a twelve-pose plan: 1.2 % at most apart, 3-5 % at 0.25 or 0.45)
MOVE_SAMPLES = 48  # samples along a tip: its sensitivity converges far below a per cent


def plan_sigma(
    C_b_n: np.ndarray,
    hold_s: np.ndarray,
    move_s: np.ndarray,
    profile: NoiseProfile,
    requirements: Requirements,
    site: Site,
    g_sensitivity: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Predicted sigma (SI, inf where not estimable) of the 21 and whether each is estimable at ``site``."""
    omega_n = site.omega_ie_n
    f_n = earth.specific_force_n(site.gravity_mps2)
    K = len(C_b_n)
    # The hand is still for part of each move (reaching, letting go): the rest finder counts that
    # to the rests, and takes its reach from each end of the turn.
    still = (1.0 - TURN_FRACTION) / 2.0 * np.asarray(move_s, float)
    rest_time = np.asarray(hold_s, float) - 2 * TRIM_S
    rest_time[:-1] += still
    rest_time[1:] += still
    rest_time[0] += TRIM_S  # the first rest starts with the log, the last ends with it
    rest_time[-1] += TRIM_S
    rest_time = np.maximum(rest_time, 0.2)
    rest_rate = np.einsum("kji,j->ki", C_b_n, omega_n)
    rest_force = np.einsum("kji,j->ki", C_b_n, f_n)
    dtheta, dv, dt, slices = [], [], [], []
    n = 0
    for k in range(K - 1):
        T = TURN_FRACTION * float(move_s[k]) + 2 * TRIM_S
        h = T / MOVE_SAMPLES
        phi = dcm_to_rotvec(C_b_n[k].T @ C_b_n[k + 1])
        s_edges = np.linspace(0.0, 1.0, MOVE_SAMPLES + 1)
        sigma = min_jerk(s_edges)[0]
        # The increments along the tip (Earth rate aside: 1e-4 rad over a move), and the specific
        # force in the turning attitude (midpoints).
        steps = np.outer(np.diff(sigma), phi)
        mid = 0.5 * (sigma[1:] + sigma[:-1])
        C_mid = C_b_n[k] @ rotvec_to_dcm(np.outer(mid, phi))
        forces = np.einsum("nji,j->ni", C_mid, f_n) * h
        dtheta += [rest_rate[k] * h, *steps]
        dv += [rest_force[k] * h, *forces]
        dt += [h] * (MOVE_SAMPLES + 1)
        slices.append(slice(n + 1, n + 1 + MOVE_SAMPLES))
        n += MOVE_SAMPLES + 1
    none = np.zeros(0, dtype=int)
    data = HandData(
        Rests(none, none, np.zeros(0, bool), 0.0, 0.0),
        rest_time,
        rest_rate,
        rest_force,
        slices,
        np.ones(K - 1, dtype=bool),
        np.array([np.linalg.norm(np.array(dtheta[sl]), axis=1).sum() for sl in slices]),
        np.ones((K, 2)),
    )
    layout = Layout(K, g_sensitivity)
    state = FitState(np.zeros(P.N_PARAMS), np.zeros((3, 3)), omega_n[:2].copy(), np.array(C_b_n, dtype=float))
    samples = HandSamples(np.array(dtheta), np.array(dv), np.array(dt))
    _, s, jac, _ = linearise(data, samples, state, layout, site, profile)
    scale = unknown_scales(layout, requirements, site.latitude_rad)
    Jw = jac / s[:, None] * scale
    M = Jw.T @ Jw
    # The rests' attitudes and the Earth rate eliminated first (Schur complement): the observability
    # rule then looks at the parameters' own information, as the fit's does through its pseudo-inverse.
    p = layout.h.start
    try:
        marginal = M[:p, :p] - M[:p, p:] @ np.linalg.solve(M[p:, p:], M[p:, :p])
    except np.linalg.LinAlgError:
        marginal = None
    if marginal is None or not np.all(np.isfinite(marginal)):
        inv = scaled_inverse(M, names=layout.names())
        cov, estimable = inv.covariance[:p, :p], inv.estimable[:p]
    else:
        inv = scaled_inverse(marginal, names=layout.names()[:p])
        cov, estimable = inv.covariance, inv.estimable
    sigma = scale[: P.N_PARAMS] * np.sqrt(np.diag(cov)[: P.N_PARAMS])
    estimable = estimable[: P.N_PARAMS]
    return np.where(estimable, sigma, math.inf), estimable
