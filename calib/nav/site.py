"""The stationary base a run was recorded on: latitude, height and gravity, and where the gravity came from.

One :class:`Site` value for the estimator (:mod:`calib.fit.estimator`, the
navigation passes of :mod:`calib.nav.chunk_pass`), the calibration policy
(:mod:`calib.calibration.entry`) and the result (:mod:`calib.calibration.result`). Gravity
is the user's, else the log's measured ``gravity_mps2``, else WGS-84
normal gravity at the site (:func:`site_of`); a gravity error of ``dg`` is
a common accelerometer scale-factor error ``dg / g`` no sequence separates
(:func:`ppm_per_mgal`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import earth

# 1 mGal = 1e-5 m/s^2 of gravity error is a common accelerometer scale-factor error of
# 1e-5 / g: about 1.02 ppm at the Earth's surface.
MGAL = 1e-5


def ppm_per_mgal(gravity_mps2: float) -> float:
    """How far 1 mGal of gravity error moves every accelerometer scale factor, ppm."""
    return MGAL / gravity_mps2 * 1e6


@dataclass(frozen=True)
class Site:
    """Latitude (rad), gravity (m/s^2) and its source: "measured" (the log's or the user's) or "normal".

    What travels where a site's latitude and gravity are needed together (the error model's
    state matrix, the Jacobian, the analyser's and the design search's chains). Height is not
    kept: the physics sees it only through normal gravity (:meth:`at`), and where a height is
    recorded (a sequence file, a report) it stays a value of its own.
    """

    latitude_rad: float
    gravity_mps2: float
    # Where the gravity came from is a label, not physics: two sites of the same numbers are the
    # same site to every computation and cache keyed on one.
    gravity_source: str = field(default="measured", compare=False)

    @classmethod
    def at(cls, latitude_rad: float, height_m: float = 0.0) -> Site:
        """The site with WGS-84 normal gravity at ``latitude_rad`` (rad) and ``height_m`` (m).

        The one way a latitude and a height become a :class:`Site`: gravity is
        :func:`calib.nav.earth.gravity` of exactly these two values.
        """
        return cls(latitude_rad, earth.gravity(latitude_rad, height_m), "normal")

    @property
    def omega_ie_n(self) -> np.ndarray:
        """The Earth rate in ENU at the site, rad/s."""
        return earth.omega_ie_n(self.latitude_rad)

    @property
    def ppm_per_mgal(self) -> float:
        """How far 1 mGal of gravity error moves every accelerometer scale factor, ppm."""
        return ppm_per_mgal(self.gravity_mps2)


def site_of(run, gravity_mps2: float | None = None, latitude_deg: float | None = None) -> Site:
    """The site of a run log (anything with ``latitude_deg``, ``height_m``, ``gravity_mps2``).

    Gravity given by the user, else the log's measured one, else normal
    gravity at its latitude and height (the height is read only then).
    ``latitude_deg`` overrides the log's.
    """
    lat = math.radians(run.latitude_deg if latitude_deg is None else float(latitude_deg))
    if gravity_mps2 is not None:
        return Site(lat, float(gravity_mps2), "measured")
    if run.gravity_mps2 is not None:
        return Site(lat, float(run.gravity_mps2), "measured")
    return Site.at(lat, run.height_m)
