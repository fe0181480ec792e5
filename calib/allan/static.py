"""What a static unit must read, and its biases after removing it.

At rest the accelerometers read gravity's reaction, ``g`` along the local up,
and the gyros the Earth rate: ``W sin L`` along the up, ``W cos L`` along north.
A MEMS gyro cannot find north (``W cos L`` is 9.4 deg/h at 51 deg, below its
resolution over a log), so only the vertical component is removed, along the
measured up; the horizontal component stays in the gyro bias (a navigation-grade
unit would gyrocompass, as ``calib.fit.estimator.coarse_alignment`` does).

Removing a constant changes no Allan deviation; it changes the biases reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.nav import earth
from calib.nav.site import Site


@dataclass(frozen=True)
class StaticLevel:
    """Biases of a static log after removing gravity and the vertical Earth rate.

    Attributes
    ----------
    up_b : ndarray, shape (3,)
        Unit vector of the local up in the body frame (direction of the mean
        specific force).
    gyro_bias : ndarray, shape (3,)
        Mean rate minus ``W sin L up_b``, rad/s; holds the horizontal Earth rate.
    accel_bias : ndarray, shape (3,)
        Mean specific force minus ``g up_b``, m/s^2: only its component along
        ``up_b`` is a bias estimate (a horizontal bias is the same as a tilt).
    gravity_mps2 : float
        ``g`` removed.
    earth_rate_vertical : float
        ``W sin L`` removed, rad/s.
    earth_rate_horizontal : float
        ``W cos L`` left in the gyro bias, rad/s.
    """

    up_b: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    gravity_mps2: float
    earth_rate_vertical: float
    earth_rate_horizontal: float


def static_level(gyro_rate: np.ndarray, specific_force: np.ndarray, site: Site) -> StaticLevel:
    """Biases of a static log (module docstring).

    Parameters
    ----------
    gyro_rate, specific_force : ndarray, shape (n, 3)
        Body-frame rates (rad/s) and specific force (m/s^2) of each sample.
    site : Site
        Latitude and gravity of the site (normal gravity, or measured).

    Returns
    -------
    StaticLevel
    """
    mean_f = np.mean(specific_force, axis=0)
    up_b = mean_f / np.linalg.norm(mean_f)
    latitude_rad, gravity_mps2 = site.latitude_rad, site.gravity_mps2
    vertical = earth.RATE * math.sin(latitude_rad)
    return StaticLevel(
        up_b=up_b,
        gyro_bias=np.mean(gyro_rate, axis=0) - vertical * up_b,
        accel_bias=mean_f - gravity_mps2 * up_b,
        gravity_mps2=float(gravity_mps2),
        earth_rate_vertical=vertical,
        earth_rate_horizontal=earth.RATE * math.cos(latitude_rad),
    )
