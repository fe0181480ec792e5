"""The kinematics of a sequence: exact body-frame integrals of its nominal motion, sample by sample.

What the simulator, the analyser and the design search all need of a sequence's motion: the flip
angle swept over each sample and ``E = int C_nom^T dt``, through which any constant ENU vector (Earth
rate, gravity) integrates for any base mounting (:func:`body_integrals`), and the exact increments of
an error-free IMU on the rotating Earth (:func:`true_increments`). Closed form over every sample
(split at segment boundaries), so exact to rounding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.nav import earth
from calib.nav.site import Site

from .definition import Timeline


@dataclass(frozen=True)
class SimConfig:
    """Site and sampling of a simulated run (SI inside, degrees only for the setup/flip inputs)."""

    latitude_rad: float
    height_m: float = 0.0
    sample_rate_hz: float = 200.0
    gravity_mps2: float | None = None  # None: WGS-84 normal gravity at the site

    @property
    def gravity(self) -> float:
        if self.gravity_mps2 is not None:
            return self.gravity_mps2
        return earth.gravity(self.latitude_rad, self.height_m)

    @property
    def site(self) -> Site:
        """The site of the run: its latitude and gravity (given, else WGS-84 normal gravity)."""
        return Site(self.latitude_rad, self.gravity, "normal" if self.gravity_mps2 is None else "measured")


GAUSS_NODES = 8  # per sub-interval of an accelerating move; see _cos_sin_integrals


def _cos_sin_integrals(tl: Timeline, seg: np.ndarray, a: np.ndarray, b: np.ndarray):
    """``int cos(theta(t)) dt`` and ``int sin(theta(t)) dt`` over ``[a, b]`` within segments ``seg``.

    Constant rate (theta linear): ``L cos(theta_m) sinc(d/2)`` (and the same
    for sin), exact and accurate for a zero or tiny rate. Accelerating pieces
    (theta a cubic): 8-point Gauss-Legendre. Its error is below
    ``L (d theta)^16 / 16!`` with ``d theta`` the angle swept over the
    sub-interval, at most ~0.01 rad for any sampling used here (a 200 Hz
    sample or an analyser sub-sample of 0.5 deg), i.e. < 1e-40 L: exact to
    rounding.
    """
    theta_a = tl.angle(seg, a - tl.t0[seg])
    theta_b = tl.angle(seg, b - tl.t0[seg])
    length = b - a
    half = 0.5 * (theta_b - theta_a)
    mid = 0.5 * (theta_a + theta_b)
    sinc = np.sinc(half / np.pi)  # numpy's sinc is sin(pi x)/(pi x)
    ic = length * np.cos(mid) * sinc
    is_ = length * np.sin(mid) * sinc
    poly = np.flatnonzero(tl.polynomial[seg])
    if poly.size:
        x, w = np.polynomial.legendre.leggauss(GAUSS_NODES)
        sp, ap, L = seg[poly], a[poly], length[poly]
        tau = (ap - tl.t0[sp])[:, None] + 0.5 * L[:, None] * (x[None, :] + 1.0)
        th = tl.angle(sp[:, None], tau)
        ic[poly] = 0.5 * L * (np.cos(th) @ w)
        is_[poly] = 0.5 * L * (np.sin(th) @ w)
    # Constant rate: rate * length, as before profiles (bit for bit).
    swept = np.where(tl.polynomial[seg], theta_b - theta_a, tl.rate[seg] * length)
    return swept, ic, is_


def _rotated_integral(
    axis: np.ndarray, ic: np.ndarray, is_: np.ndarray, length: np.ndarray, w: np.ndarray
) -> np.ndarray:
    """``int R_axis(theta(t))^T w dt`` over sub-intervals, from ``int cos theta`` and ``int sin theta``."""
    out = np.empty_like(w)
    for ax in range(3):
        sel = axis == ax
        j, k = (ax + 1) % 3, (ax + 2) % 3
        out[sel, ax] = w[sel, ax] * length[sel]
        # R_axis(theta)^T rotates (w_j, w_k) by -theta.
        out[sel, j] = w[sel, j] * ic[sel] + w[sel, k] * is_[sel]
        out[sel, k] = -w[sel, j] * is_[sel] + w[sel, k] * ic[sel]
    return out


def uniform_times(tl: Timeline, sample_rate_hz: float) -> np.ndarray:
    """Sample end times at a uniform rate over a timeline."""
    return np.arange(1, int(math.floor(tl.duration_s * sample_rate_hz + 1e-9)) + 1) / sample_rate_hz


def body_integrals(tl: Timeline, time_s: np.ndarray):
    """Per sample, the flip angle increment and ``E = int C_nom^T dt`` (nominal attitude).

    The base mounting and the site enter only through constant ENU vectors,
    so for a true attitude ``R_setup C_nom`` any such vector ``u`` integrates
    to ``E (R_setup^T u)``: one pass over the samples serves every mounting.

    Parameters
    ----------
    tl : Timeline
    time_s : ndarray, shape (n,)
        End of each sample; the first starts at 0.

    Returns
    -------
    flip : ndarray, shape (n, 3)
        ``int rate * axis dt`` (body frame).
    E : ndarray, shape (n, 3, 3)
    """
    n = len(time_s)
    # Break points: every sample end and every segment boundary inside the run.
    inner = tl.t1[:-1][tl.t1[:-1] < time_s[-1]]
    cuts = np.union1d(np.concatenate([[0.0], time_s]), inner)
    a, b = cuts[:-1], cuts[1:]
    keep = b - a > 0
    a, b = a[keep], b[keep]
    seg = np.clip(np.searchsorted(tl.t1, 0.5 * (a + b)), 0, len(tl.t0) - 1)
    sample = np.clip(np.searchsorted(time_s, 0.5 * (a + b)), 0, n - 1)
    axis = np.where(tl.axis[seg] < 0, 0, tl.axis[seg])
    swept, ic, is_ = _cos_sin_integrals(tl, seg, a, b)
    length = b - a
    pieces = np.empty((len(a), 3, 3))
    for c in range(3):  # column c of E integrates C^T e_c, i.e. row c of C
        pieces[:, :, c] = _rotated_integral(axis, ic, is_, length, tl.C0[seg][:, c, :])
    flip = np.zeros((len(a), 3))
    flip[np.arange(len(a)), axis] = swept
    E = np.zeros((n, 9))
    out_flip = np.zeros((n, 3))
    for i in range(9):
        E[:, i] = np.bincount(sample, pieces.reshape(-1, 9)[:, i], minlength=n)
    for i in range(3):
        out_flip[:, i] = np.bincount(sample, flip[:, i], minlength=n)
    return out_flip, E.reshape(n, 3, 3)


def true_increments(tl: Timeline, R_setup: np.ndarray, cfg: SimConfig, time_s: np.ndarray | None = None):
    """Exact gyro and accelerometer increments of a timeline.

    Samples are uniform at ``cfg.sample_rate_hz`` unless ``time_s`` (the end
    of every sample, increasing, the first interval starting at 0) is given.

    Returns
    -------
    time_s : ndarray, shape (n,)
        End of each sample interval.
    dtheta, dv : ndarray, shape (n, 3)
        ``int omega_ib_b dt`` and ``int f_b dt`` over each sample.
    """
    if time_s is None:
        time_s = uniform_times(tl, cfg.sample_rate_hz)
    flip, E = body_integrals(tl, time_s)
    w_ie = R_setup.T @ earth.omega_ie_n(cfg.latitude_rad)
    f = R_setup.T @ earth.specific_force_n(cfg.gravity)
    return time_s, flip + E @ w_ie, E @ f
