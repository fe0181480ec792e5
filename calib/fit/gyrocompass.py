"""Gyro bias and heading together from every rest of a run (a MEMS unit's start).

Gyrocompassing on one rest takes the mean rate as the Earth rate: it needs
a gyro bias far below the Earth rate. A MEMS gyro's bias (1000 deg/h) is
seventy times it, and removing the mean rate over all rests first leaves the
Earth rate's own average over the rests, as large as the Earth rate, so the
heading of one rest can come out anywhere, 180 deg included, far outside
what the fit's linearisation corrects.

Over several rests at different attitudes the bias and the Earth rate
separate: at rest ``r`` the gyros read

    w_r = b + R_r' C_lev' Rz(psi)' omega_ie_n

with ``R_r`` the body attitude of the rest relative to the body at the run's
start (the integrated gyros; the Earth's turn about its own axis leaves
``omega_ie_n`` unchanged, so no inertial bookkeeping is needed),
``C_lev`` the levelled start attitude with an arbitrary heading and ``psi``
the heading correction about up. With ``a = W cos L sin psi`` and
``c = W cos L cos psi`` this is linear in ``(b, a, c)``: five unknowns from
three equations per rest. The heading is as good as the Earth rate against
the rests' gyro noise allows (tens of degrees for a MEMS unit), which is
inside the fit's reach; the fit then refines it with everything else.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from calib.nav.chunk_pass import quat_scan
from calib.nav.site import Site
from calib.nav.transform import quat_to_dcm, rotvec_to_quat
from calib.sequence.motion import runs_of


@dataclass(frozen=True)
class Rests:
    """What gyrocompassing needs of a run's rests.

    ``T`` (r,) each rest's length (s), ``w`` (r, 3) its mean gyro rate
    (rad/s), ``attitudes(bias)`` the body attitude at each rest's middle
    relative to the start, ``(r, 3, 3)``, integrated with the gyros
    compensated by ``bias`` (:func:`gyrocompass_rests`).
    """

    T: np.ndarray
    w: np.ndarray
    attitudes: Callable[[np.ndarray], np.ndarray]


def rests_in_memory(dtheta_m: np.ndarray, dt: np.ndarray, moving: np.ndarray) -> Rests:
    """The :class:`Rests` of a run held in memory."""
    starts, ends, T, w = rest_rates(dtheta_m, dt, moving)
    return Rests(T, w, lambda bias: rest_attitudes(dtheta_m - bias * dt[:, None], starts, ends))


def rest_attitudes(dtheta: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Body attitude at the middle of each rest relative to the body at the run's start."""
    q = quat_scan(rotvec_to_quat(dtheta))
    return quat_to_dcm(q[(starts + ends) // 2])


def rest_rates(dtheta_m: np.ndarray, dt: np.ndarray, moving: np.ndarray):
    """Each rest's start and end (samples), length (s) and mean gyro rate (rad/s)."""
    starts, ends = runs_of(~moving)
    T = np.array([dt[a:b].sum() for a, b in zip(starts, ends, strict=True)])
    w = np.array([dtheta_m[a:b].sum(axis=0) for a, b in zip(starts, ends, strict=True)]) / T[:, None]
    return starts, ends, T, w


def rest_gyrocompass(
    dtheta_m: np.ndarray,
    dt: np.ndarray,
    moving: np.ndarray,
    C_lev: np.ndarray,
    site: Site,
    bias0: np.ndarray,
    passes: int = 2,
) -> tuple[np.ndarray, np.ndarray]:
    """Gyro bias (rad/s) and start attitude ``C_b_n`` from all rests of a run in memory.

    See :func:`gyrocompass_rests`; the rests' attitudes are integrated here.
    """
    return gyrocompass_rests(rests_in_memory(dtheta_m, dt, moving), C_lev, site, bias0, passes)


def gyrocompass_rests(
    rests: Rests, C_lev: np.ndarray, site: Site, bias0: np.ndarray, passes: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """Gyro bias (rad/s) and start attitude ``C_b_n`` from the rests, by linear least squares.

    Parameters
    ----------
    rests : Rests
        Each rest's length and mean gyro rate, and ``attitudes(bias)``: the body
        attitude at the middle of each rest relative to the body at the run's
        start, integrated from the gyros compensated by ``bias`` (rad/s).
    C_lev : ndarray, shape (3, 3)
        The levelled start attitude (its heading is corrected).
    site : Site
        Where the run was recorded: the Earth rate at its latitude.
    bias0 : ndarray, shape (3,)
        The bias that compensates the gyros for the first integration; each
        pass integrates again with the bias of the last.
    passes : int

    Each rest's mean rate is weighted by its length (its noise variance is
    ``arw^2 / T``).
    """
    omega = site.omega_ie_n
    horizontal, up = float(np.hypot(omega[0], omega[1])), float(omega[2])
    T, w = rests.T, rests.w
    bias = np.asarray(bias0, dtype=float)
    for _ in range(passes):
        R = rests.attitudes(bias)
        to_body = R.transpose(0, 2, 1) @ C_lev.T  # nav (levelled) -> body of each rest
        A = np.concatenate(
            [np.broadcast_to(np.eye(3), to_body.shape), horizontal * to_body[:, :, :2]], axis=2
        ).reshape(-1, 5)
        y = (w - up * to_body[:, :, 2]).reshape(-1)
        sw = np.repeat(np.sqrt(T), 3)
        x = np.linalg.lstsq(A * sw[:, None], y * sw, rcond=None)[0]
        bias, (a, c) = x[:3], x[3:]
    psi = np.arctan2(a, c)
    Rz = np.array([[np.cos(psi), -np.sin(psi), 0.0], [np.sin(psi), np.cos(psi), 0.0], [0.0, 0.0, 1.0]])
    return bias, Rz @ C_lev
