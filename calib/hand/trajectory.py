"""The continuous truth trajectory of a run placed by hand, in closed form.

The navigation frame ``n`` is ENU fixed to the Earth at the site; positions
are relative to the table spot, so the frame has no transport rate. At time
``t`` (rest ``k``, or move ``k`` from rest ``k`` to rest ``k + 1``):

* rest: ``C_b_n = C_k``; the unit is still, ``omega_nb = 0``, ``p = v = a = 0``;
* move: with ``s_r`` the normalised time of the turn (clipped to ``[0, 1]``),
  ``phi = log(C_k^T C_{k+1})``, ``e`` the wobble axis (body, perpendicular to
  ``phi``) and ``a`` its amplitude::

      C_b_n = C_k exp(sigma(s_r) [phi x]) exp(a bump(s_r) [e x])
      omega_nb_b = (sigma'(s_r) exp(-a bump(s_r) [e x]) phi + a bump'(s_r) e) / turn_s

  (from ``C^T dC/dt``: ``G = exp(sigma [phi x])`` gives ``G^T G' = sigma' [phi x]``,
  and the wobble ``W`` turns it into ``W^T [phi x] W = [(W^T phi) x]``); and with
  ``s`` the normalised time of the move and ``d`` its displacement vector::

      p = d bump(s),   v = d bump'(s) / move_s,   a = d bump''(s) / move_s^2.

The sensed quantities (``omega_ie`` the Earth rate in ENU, ``g`` the site's
gravity magnitude, uniform over the few tens of cm the unit is carried)::

    omega_ib_b = omega_nb_b + C_b_n^T omega_ie
    f_b = C_b_n^T (a + 2 omega_ie x v + (0, 0, g))
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.nav import earth
from calib.nav.site import Site
from calib.nav.strapdown import cross3
from calib.nav.transform import rotvec_to_dcm

from .plan import HandPlan, bump, min_jerk
from .tremor import Tremor, held_at, tremor_state


@dataclass(frozen=True)
class HandState:
    """The trajectory at ``m`` instants (SI, ENU, body axes).

    Attributes
    ----------
    C_b_n : ndarray, shape (m, 3, 3)
        Attitude, body to ENU.
    omega_nb_b : ndarray, shape (m, 3)
        Body rate relative to the Earth-fixed ENU frame, rad/s.
    p_n, v_n, a_n : ndarray, shape (m, 3)
        Position from the table spot, velocity, acceleration relative to the Earth.
    """

    C_b_n: np.ndarray
    omega_nb_b: np.ndarray
    p_n: np.ndarray
    v_n: np.ndarray
    a_n: np.ndarray


def segment_of(plan: HandPlan, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each time: the index ``k`` of the last rest begun, and whether ``t`` is in move ``k``.

    A time at a rest's end counts as in the rest (the motion is continuous there).
    """
    t = np.asarray(t, dtype=float)
    k = np.clip(np.searchsorted(plan.rest_start_s, t, side="right") - 1, 0, plan.n_poses - 1)
    moving = (t > plan.rest_end_s[k]) & (k < plan.n_poses - 1)
    return k, moving


def hand_state(plan: HandPlan, t: np.ndarray, tremor: Tremor | None = None) -> HandState:
    """The trajectory at times ``t`` (s from the start of the run), shape ``(m,)``.

    With a ``tremor`` (:mod:`calib.hand.tremor`), its held rests wobble and shake:
    ``C_b_n = C_k exp([theta x])``, ``omega_nb_b = J_r(theta) theta'``, ``p, v, a`` its shake's.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    k, moving = segment_of(plan, t)
    m = len(t)
    C = plan.C_b_n[k].copy()
    w_nb = np.zeros((m, 3))
    p, v, a = np.zeros((m, 3)), np.zeros((m, 3)), np.zeros((m, 3))
    j = k[moving]
    if j.size:
        tm = t[moving]
        phi = plan.rotvec[j]
        e = plan.wobble_axis[j]
        amp = plan.wobble_rad[j]
        turn = plan.turn_s[j]
        s_r = (tm - plan.turn_start_s[j]) / turn
        sigma, d_sigma, _ = min_jerk(s_r)
        b, d_b, _ = bump(s_r)
        wobble = (amp * b)[:, None] * e
        W = rotvec_to_dcm(wobble)
        G = rotvec_to_dcm(sigma[:, None] * phi)
        C[moving] = plan.C_b_n[j] @ G @ W
        w_turn = np.einsum("nji,nj->ni", W, phi)  # W^T phi
        w_nb[moving] = (d_sigma[:, None] * w_turn + (amp * d_b)[:, None] * e) / turn[:, None]
        move = plan.move_s[j]
        s = (tm - plan.rest_end_s[j]) / move
        h, d_h, dd_h = bump(s)
        d = plan.translation_m[j]
        p[moving] = h[:, None] * d
        v[moving] = (d_h / move)[:, None] * d
        a[moving] = (dd_h / move**2)[:, None] * d
    if tremor is not None:
        held = held_at(tremor, t)
        sel = held >= 0
        if sel.any():
            tr = tremor_state(tremor, held[sel], t[sel])
            C[sel] = C[sel] @ rotvec_to_dcm(tr.theta)
            w_nb[sel], p[sel], v[sel], a[sel] = tr.omega_nb_b, tr.p_n, tr.v_n, tr.a_n
    return HandState(C_b_n=C, omega_nb_b=w_nb, p_n=p, v_n=v, a_n=a)


def sensed(state: HandState, site: Site) -> tuple[np.ndarray, np.ndarray]:
    """What ideal sensors at ``site`` see: ``omega_ib_b`` (rad/s) and ``f_b`` (m/s^2), shape (m, 3) each."""
    w_ie = site.omega_ie_n
    C_n_b = state.C_b_n.transpose(0, 2, 1)
    omega_ib = state.omega_nb_b + C_n_b @ w_ie
    f_n = state.a_n + 2.0 * cross3(np.broadcast_to(w_ie, state.v_n.shape), state.v_n)
    f_n = f_n + earth.specific_force_n(site.gravity_mps2)
    return omega_ib, np.einsum("nij,nj->ni", C_n_b, f_n)
