"""The frame a Gauss-Markov noise model is built in, and when it must be built anew.

A Gauss-Markov bias is fixed in the body: the noise model carries it into the
navigation frame along an attitude series. The fit moves that attitude from one
iteration to the next; a turn about the vertical is taken by turning the
observations into the model's frame (:func:`heading_turn`, :func:`to_frame`),
any other move beyond NOISE_MODEL_MAX_ATTITUDE_DEG by building the model anew
(:func:`noise_stale`).
"""

from __future__ import annotations

import math

import numpy as np

from .profiles import NoiseProfile

# Built along an attitude off by a rotation R, the modelled bias turns by C' R C against the
# real one as the unit flips, and the fit takes the constant gyro bias for separable from the
# GM: measured on an ADIS16405-profile run whose navigation had moved 69 deg in heading from the
# attitude its model was built along (a MEMS gyro cannot gyrocompass), gyro-bias sigmas of
# 10 deg/h where the bound of a constant in that GM is 41 deg/h (errors 3-7 sigma). Off by 1 deg
# the sigmas move by 0.5 %, by 3 deg 3 %, by 10 deg 20 %: beyond this tilt (the heading is
# turned into the model's frame instead) the model is built anew.
NOISE_MODEL_MAX_ATTITUDE_DEG = 1.0


def heading_turn(C_built: np.ndarray, C_now: np.ndarray) -> np.ndarray:
    """The turn about the vertical (3, 3) from the attitude series a noise model was built
    along to the navigated one (both (K, 3, 3)): their mean difference in heading.

    A MEMS gyro cannot gyrocompass: the fit moves its heading by degrees from one iteration to
    the next. Turned about the vertical, the Gauss-Markov noise model is the one built along
    the old attitude, turned (gravity is vertical; the Earth's rate, which is not, turns the
    noise by 0.035 rad over 8 min: its effect is second order). The observations and Jacobian
    are taken into the model's frame by ``to_frame(R, .)`` instead of rebuilding the model at
    each heading: rebuilt at each, the fit's weights moved with its heading and the heading
    never settled (measured: +-1-6 deg for 40 iterations on an ADIS16405-profile run).
    """
    R = np.einsum("kij,klj->kil", C_now, C_built)  # C_now C_built^T per interval
    psi = float(np.mean(np.arctan2(R[:, 1, 0] - R[:, 0, 1], R[:, 0, 0] + R[:, 1, 1])))
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def model_frame(profile: NoiseProfile, C_built: np.ndarray | None, C_now: np.ndarray):
    """The turn into the noise model's frame and the attitude series of that frame.

    Only a Gauss-Markov model depends on the attitude; any other is the same in every frame,
    and the fit stays in the navigation frame.
    """
    if not profile.has_gauss_markov or C_built is None:
        return np.eye(3), C_now
    return heading_turn(C_built, C_now), C_built


def to_frame(R: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Navigation-frame vectors ``x`` (K, 3) or matrices (K, 3, n) expressed in the frame turned by ``R``."""
    if x.ndim == 2:
        return x @ R
    return np.einsum("ij,kin->kjn", R, x)


def attitude_moved_deg(C_built: np.ndarray | None, C_now: np.ndarray) -> float:
    """The largest rotation (deg) between two attitude series (K, 3, 3), their mean heading
    difference aside (:func:`heading_turn`); inf without the first.
    """
    if C_built is None:
        return math.inf
    C_built = np.einsum("ij,kjl->kil", heading_turn(C_built, C_now), C_built)
    cos = 0.5 * (np.einsum("kij,kij->k", C_built, C_now) - 1.0)
    return math.degrees(float(np.arccos(np.clip(cos, -1.0, 1.0)).max()))


def noise_stale(profile: NoiseProfile, C_built: np.ndarray | None, C_now: np.ndarray) -> bool:
    """Whether a Gauss-Markov noise model must follow the attitude (NOISE_MODEL_MAX_ATTITUDE_DEG)."""
    return profile.has_gauss_markov and attitude_moved_deg(C_built, C_now) > NOISE_MODEL_MAX_ATTITUDE_DEG
