"""Where Gauss-Newton starts: the one start of the in-memory and the chunked paths.

Levelling and gyrocompassing on the first rest (:func:`coarse_alignment`);
a gyro bias beyond the Earth rate (a MEMS unit's, :func:`start_from_rests`)
is taken out first and then solved with the heading from all rests
(:func:`calib.fit.gyrocompass.gyrocompass_rests`). :func:`start_attitude` takes
what it needs of the run -- the first rest's samples, the mean rate over all
rests, and the rests themselves when the bias needs them -- so that a run in
memory and a run read chunk by chunk start from the same values.
"""

from __future__ import annotations

import numpy as np

from calib.errors import CalibError
from calib.model import params as P
from calib.model.requirements import PAPER, Requirements
from calib.nav import earth
from calib.nav.site import Site
from calib.sequence.definition import MIN_ALIGN_S

from . import sanity
from .gyrocompass import gyrocompass_rests


def coarse_alignment(dtheta: np.ndarray, dv: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """``C_b_n`` from levelling and gyrocompassing over a rest segment."""
    T = dt.sum()
    f = dv.sum(axis=0) / T
    w = dtheta.sum(axis=0) / T
    up = f / np.linalg.norm(f)
    east = np.cross(w, up)
    east /= np.linalg.norm(east)
    north = np.cross(up, east)
    return np.vstack([east, north, up])


def mean_rest_rate(dtheta_m: np.ndarray, dt: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """Mean gyro rate over all rests of a run in memory, rad/s."""
    rest = ~moving
    return dtheta_m[rest].sum(axis=0) / dt[rest].sum()


def start_values(dtheta_m: np.ndarray, dt: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """Where Gauss-Newton starts, from the mean gyro rate over all rests (:func:`start_from_rests`)."""
    return start_from_rests(mean_rest_rate(dtheta_m, dt, moving))


def start_from_rests(mean_rate: np.ndarray) -> np.ndarray:
    """Where Gauss-Newton starts: zero, or the gyro biases when they dwarf the Earth rate.

    A gyro bias of 1000 deg/h (a MEMS unit) tilts an uncompensated navigation
    by hundreds of degrees in half an hour, far outside what a linearisation
    can correct. The mean rate over all rests (``mean_rate``, rad/s) is the
    bias to within the Earth rate (15 deg/h), which the rests' different
    attitudes average down: from there the fit is in its linear range. A
    navigation-grade unit, whose biases are far below the Earth rate, starts
    from zero as it always did.
    """
    values = np.zeros(P.N_PARAMS)
    if np.linalg.norm(mean_rate) > 2.0 * earth.RATE:
        values[P.GYRO_BIAS] = mean_rate
    return values


def check_first_rest(
    dtheta_m: np.ndarray,
    dv_m: np.ndarray,
    dt: np.ndarray,
    rest: slice,
    gravity_mps2: float,
    where: str,
    requirements: Requirements = PAPER,
) -> None:
    """Refuse a first rest (samples ``rest``) too short to align on or that is no rest.

    What is plausible follows the unit's class (its requirements): a MEMS
    unit's biases of 1000 deg/h and 20 mg are not a log in wrong units.
    """
    req = requirements.si
    t_align = float(dt[rest].sum())
    if t_align < MIN_ALIGN_S:
        raise CalibError(
            f"the first rest lasts {t_align:.1f} s, too short to align (needs >= {MIN_ALIGN_S:.0f} s)",
            where,
            "start the run with the IMU at rest",
        )
    sanity.check_rest_rate(dtheta_m, dt, rest, where, float(req[P.GYRO_BIAS].max()))
    accel_class = sanity.CLASS_FACTOR * float(
        req[P.ACCEL_BIAS].max() / gravity_mps2 + req[P.ACCEL_SCALE].max()
    )
    sanity.check_gravity(dv_m, dt, rest, gravity_mps2, where, accel_class)


def start_attitude(
    first_rest: tuple[np.ndarray, np.ndarray, np.ndarray], mean_rate: np.ndarray, rests, site: Site
) -> tuple[np.ndarray, np.ndarray]:
    """The start values of the 21 and ``C_b_n`` at the run's start.

    Parameters
    ----------
    first_rest : tuple of ndarray
        ``(dtheta_m, dv_m, dt)`` of the first rest's samples.
    mean_rate : ndarray, shape (3,)
        Mean gyro rate over all rests, rad/s (:func:`start_from_rests`).
    rests : callable
        ``rests()`` gives the run's :class:`calib.fit.gyrocompass.Rests`; called
        only when the gyro bias dwarfs the Earth rate.
    site : Site
        Where the run was recorded (the Earth rate at its latitude).
    """
    dtheta, dv, dt = first_rest
    start = start_from_rests(mean_rate)
    C0 = coarse_alignment(dtheta - start[P.GYRO_BIAS] * dt[:, None], dv, dt)
    if np.any(start[P.GYRO_BIAS]):  # a bias beyond the Earth rate: bias and heading from all rests
        start[P.GYRO_BIAS], C0 = gyrocompass_rests(rests(), C0, site, start[P.GYRO_BIAS])
    return start, C0
