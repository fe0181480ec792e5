"""Run simulator: exact IMU increments of a sequence on a stationary base.

The body turns at constant rate about one body axis per flip, on a base
mounted with a small rotation ``R_setup`` and fixed to the rotating Earth.
Gyro increments integrate ``C_n_b omega_ie_n + rate * axis`` and velocity
increments integrate ``C_n_b [0, 0, g]`` in closed form over every sample
(splitting samples at segment boundaries), so they are exact to rounding.
The 21 errors and any optional terms (:mod:`calib.extras`) are applied to
the increments, then the noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from . import earth
from . import extras as X
from .encoders import encoder_track
from .errormodel import ErrorModel
from .extras import ExtraValues
from .gaussmarkov import gauss_markov
from .gimbal import plan_sequence
from .gimbalfile import DEFAULT_GIMBAL
from .profiles import NoiseProfile
from .runlog import Run, make_meta
from .sequence import Sequence, Timeline, timeline
from .transform import rotvec_to_dcm

if TYPE_CHECKING:
    from .runlog import Run


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


@dataclass(frozen=True)
class Truth:
    """What a simulated run really contains (the truth file of ``docs/formats.md``)."""

    errors: ErrorModel
    setup_rotvec: np.ndarray  # rad, ENU rotation vector of R_setup
    flip_errors_deg: np.ndarray  # per step
    profile: str
    seed: int | None
    noise: bool
    extra: ExtraValues | None = None  # optional terms of calib.extras, None when all off

    @property
    def R_setup(self) -> np.ndarray:
        return rotvec_to_dcm(self.setup_rotvec)


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


def encoder_angles(
    seq: Sequence, time_s: np.ndarray, gimbal=None, played: Sequence | None = None
) -> np.ndarray:
    """Gimbal encoder angles (deg, continuous) at each sample.

    The gimbal sits on the base, so the mounting rotation does not enter.
    ``seq`` (the nominal sequence) decides which gimbal plays each flip and
    any lock counter-rotation (:mod:`calib.gimbal`); ``played`` (default
    ``seq``) is what was really played, e.g. with flip errors.
    """
    plan = plan_sequence(seq, gimbal or DEFAULT_GIMBAL)
    angles, _ = encoder_track(plan, played if played is not None else seq, time_s)
    return np.degrees(angles) + 0.0  # no negative zeros


def add_noise(
    dtheta: np.ndarray, dv: np.ndarray, dt: np.ndarray, profile: NoiseProfile, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The profile's white noise and any Gauss-Markov bias instability, added to increments."""
    if profile.has_gauss_markov:
        # Bias instability: a stationary first-order Gauss-Markov bias, constant over a sample.
        dtheta = (
            dtheta
            + gauss_markov(len(dt), dt, profile.gyro_gm_sigma, profile.gyro_bias_correlation_s, rng)
            * dt[:, None]
        )
        dv = (
            dv
            + gauss_markov(len(dt), dt, profile.accel_gm_sigma, profile.accel_bias_correlation_s, rng)
            * dt[:, None]
        )
    sq = np.sqrt(dt)[:, None]
    dtheta = dtheta + profile.arw * sq * rng.standard_normal(dtheta.shape)
    dv = dv + profile.vrw * sq * rng.standard_normal(dv.shape)
    return dtheta, dv


def run_meta(cfg: SimConfig, sequence_name: str | None, **extra: str) -> dict[str, str]:
    """The run log's metadata for a simulated site (:func:`calib.runlog.make_meta`): the sequence it
    played (None for a run placed by hand) and any ``extra`` keys.
    """
    return make_meta(
        math.degrees(cfg.latitude_rad),
        cfg.height_m,
        cfg.sample_rate_hz,
        gravity_mps2=cfg.gravity_mps2,
        sequence=sequence_name,
        **extra,
    )


def simulate(
    seq: Sequence,
    cfg: SimConfig,
    errors: ErrorModel,
    profile: NoiseProfile,
    setup_rotvec=(0.0, 0.0, 0.0),
    flip_error_deg: float = 0.0,
    noise: bool = True,
    seed: int | None = None,
    random_setup_deg: float | None = None,
    extra: ExtraValues | None = None,
    gimbal=None,
) -> tuple[Run, Truth]:
    """Simulate a calibration run.

    Parameters
    ----------
    seq : Sequence
    cfg : SimConfig
    errors : ErrorModel
        Injected deterministic errors.
    profile : NoiseProfile
        White noise and any Gauss-Markov bias instability (ignored when
        ``noise`` is False).
    setup_rotvec : array_like
        Base mounting rotation vector (E, N, U), rad.
    flip_error_deg : float
        Each flip misses its angle by a uniform random amount within +-this.
    noise : bool
    seed : int or None
    random_setup_deg : float or None
        If given, draw each setup component uniformly within +-this (deg).
    extra : ExtraValues, optional
        The optional terms of :mod:`calib.extras` (lever arms, quadratic
        accelerometer terms, gyro-accelerometer time offset).
    gimbal : calib.gimbal.Gimbal, optional
        Plays the encoder channels (lock counter-rotations at its limits);
        default: slip rings, no limits.

    Returns
    -------
    run : Run
    truth : Truth
    """
    rng = np.random.default_rng(seed)
    flip_errors = (
        rng.uniform(-flip_error_deg, flip_error_deg, len(seq.steps))
        if flip_error_deg > 0
        else np.zeros(len(seq.steps))
    )
    if random_setup_deg is not None:
        setup_rotvec = np.radians(rng.uniform(-random_setup_deg, random_setup_deg, 3))
    setup_rotvec = np.asarray(setup_rotvec, dtype=float)
    real = seq.with_flip_errors(flip_errors)
    tl = timeline(real)
    R = rotvec_to_dcm(setup_rotvec)
    time_s, dtheta, dv = true_increments(tl, R, cfg)
    dt = np.diff(np.concatenate([[0.0], time_s]))
    extra = extra if extra is not None else ExtraValues()
    if extra.time_offset_s != 0.0:
        # The accelerometers integrate over windows shifted by the offset: exact, as above.
        _, E = body_integrals(tl, time_s - extra.time_offset_s)
        # body_integrals starts the first window at 0; the IMU rested there before the run.
        E[0] += extra.time_offset_s * tl.C0[0].T
        dv = E @ (R.T @ earth.specific_force_n(cfg.gravity))
    dtheta_m, _ = errors.apply(dtheta, dv, dt)
    dv = X.apply(extra, dtheta, dv, dt, lambda x: errors.apply(dtheta, x, dt)[1])
    dtheta = dtheta_m
    if noise:
        dtheta, dv = add_noise(dtheta, dv, dt, profile, rng)

    run = Run(
        time_s=time_s,
        dtheta_rad=dtheta,
        dv_mps=dv,
        meta=run_meta(cfg, seq.name),
        gimbal_deg=encoder_angles(seq, time_s, gimbal, played=real),
    )
    truth = Truth(
        errors=errors,
        setup_rotvec=setup_rotvec,
        flip_errors_deg=flip_errors,
        profile=profile.name,
        seed=seed,
        noise=noise,
        extra=extra if extra.active else None,
    )
    return run, truth
