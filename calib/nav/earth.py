"""Earth model of the conventions: WGS-84 rotation rate and normal gravity, ENU."""

from __future__ import annotations

import numpy as np

from calib.errors import CalibError

RATE = 7.292115e-5  # rad/s, WGS-84
A = 6378137.0  # m, semi-major axis
F = 1.0 / 298.257223563
M = 0.00344978650684  # omega^2 a^2 b / GM
_GE = 9.7803253359
_K = 0.00193185265241
_E2 = 0.00669437999013


def gravity(latitude_rad: float, height_m: float = 0.0) -> float:
    """WGS-84 normal gravity magnitude (Somigliana plus second-order height term).

    Parameters
    ----------
    latitude_rad : float
        Geodetic latitude.
    height_m : float
        Ellipsoidal height.

    Returns
    -------
    float
        Gravity in m/s^2 (the specific force a body at rest senses, upward).
    """
    s2 = np.sin(latitude_rad) ** 2
    g0 = _GE * (1.0 + _K * s2) / np.sqrt(1.0 - _E2 * s2)
    return float(g0 * (1.0 - 2.0 * height_m / A * (1.0 + F + M - 2.0 * F * s2) + 3.0 * height_m**2 / A**2))


def omega_ie_n(latitude_rad: float) -> np.ndarray:
    """Earth rate in the ENU navigation frame, rad/s."""
    return np.array([0.0, RATE * np.cos(latitude_rad), RATE * np.sin(latitude_rad)])


def specific_force_n(gravity_mps2: float) -> np.ndarray:
    """Specific force sensed at rest, ENU: ``[0, 0, +g]``."""
    return np.array([0.0, 0.0, gravity_mps2])


# A stationary calibration needs a horizontal Earth rate to gyrocompass (not at a pole),
# and a site on the Earth's surface (Dead Sea to Everest, with margin): far outside,
# normal gravity is meaningless and its formula overflows.
MAX_LATITUDE_DEG = 89.0
HEIGHT_RANGE_M = (-1000.0, 10000.0)


def check_site(latitude_deg: float, height_m: float) -> None:
    """Refuse a site where a stationary calibration is meaningless, naming the limit."""
    if not -MAX_LATITUDE_DEG <= latitude_deg <= MAX_LATITUDE_DEG:
        raise CalibError(
            f"latitude {latitude_deg} deg is outside [-{MAX_LATITUDE_DEG:g}, {MAX_LATITUDE_DEG:g}]",
            "latitude",
            "stationary calibration needs the Earth rate to have a horizontal part",
        )
    low, high = HEIGHT_RANGE_M
    if not low <= height_m <= high:
        raise CalibError(
            f"height {height_m} m is outside [{low:g}, {high:g}]",
            "height",
            "give the ellipsoidal height of the site in metres",
        )
