"""Run simulator: exact IMU increments of a sequence on a stationary base.

The body turns at constant rate about one body axis per flip, on a base
mounted with a small rotation ``R_setup`` and fixed to the rotating Earth.
Gyro increments integrate ``C_n_b omega_ie_n + rate * axis`` and velocity
increments integrate ``C_n_b [0, 0, g]`` in closed form over every sample
(splitting samples at segment boundaries), so they are exact to rounding.
The 21 errors and any optional terms (:mod:`calib.model.optional_terms`) are applied to
the increments, then the noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from calib.gimbal.description import DEFAULT_GIMBAL
from calib.gimbal.encoders import encoder_track
from calib.gimbal.rule import plan_sequence
from calib.model import optional_terms as X
from calib.model.error_model import ErrorModel
from calib.model.optional_terms import OptionalTermValues
from calib.nav import earth
from calib.nav.transform import rotvec_to_dcm
from calib.noise.gauss_markov import gauss_markov
from calib.noise.profiles import NoiseProfile
from calib.runlog import Run, make_meta
from calib.sequence.definition import Sequence, timeline
from calib.sequence.kinematics import SimConfig, body_integrals, true_increments

if TYPE_CHECKING:
    from calib.runlog import Run


@dataclass(frozen=True)
class Truth:
    """What a simulated run really contains (the truth file of ``docs/formats.md``)."""

    errors: ErrorModel
    setup_rotvec: np.ndarray  # rad, ENU rotation vector of R_setup
    flip_errors_deg: np.ndarray  # per step
    profile: str
    seed: int | None
    noise: bool
    extra: OptionalTermValues | None = None  # optional terms of calib.model.optional_terms, None when all off

    @property
    def R_setup(self) -> np.ndarray:
        return rotvec_to_dcm(self.setup_rotvec)


@dataclass(frozen=True)
class SimOptions:
    """What a simulated run draws and how its base is mounted (the site and sampling: ``SimConfig``).

    Parameters
    ----------
    setup_rotvec : array_like
        Base mounting rotation vector (E, N, U), rad.
    flip_error_deg : float
        Each flip misses its angle by a uniform random amount within +-this.
    noise : bool
        Add the profile's noise.
    seed : int or None
        Seeds the noise, the flip errors and a drawn mounting.
    random_setup_deg : float or None
        If given, draw each setup component uniformly within +-this (deg), instead of
        ``setup_rotvec``.
    """

    setup_rotvec: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0)
    flip_error_deg: float = 0.0
    noise: bool = True
    seed: int | None = None
    random_setup_deg: float | None = None

    @classmethod
    def drawn(cls, seed: int | None, tolerance_deg: float, flip_error_deg: float) -> SimOptions:
        """A Monte Carlo run's: noise, the mounting drawn within +-``tolerance_deg`` (0: none),
        each flip missing by up to ``flip_error_deg``, all from ``seed``.
        """
        setup = tolerance_deg if tolerance_deg > 0 else None
        return cls(flip_error_deg=flip_error_deg, noise=True, seed=seed, random_setup_deg=setup)


SIM = SimOptions()  # the defaults: no mounting rotation, no flip errors, noise, no seed


def encoder_angles(
    seq: Sequence, time_s: np.ndarray, gimbal=None, played: Sequence | None = None
) -> np.ndarray:
    """Gimbal encoder angles (deg, continuous) at each sample.

    The gimbal sits on the base, so the mounting rotation does not enter.
    ``seq`` (the nominal sequence) decides which gimbal plays each flip and
    any lock counter-rotation (:mod:`calib.gimbal.rule`); ``played`` (default
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
    options: SimOptions = SIM,
    extra: OptionalTermValues | None = None,
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
        ``options.noise`` is False).
    options : SimOptions
        The base mounting, flip errors, noise and seed.
    extra : OptionalTermValues, optional
        The optional terms of :mod:`calib.model.optional_terms` (lever arms, quadratic
        accelerometer terms, gyro-accelerometer time offset).
    gimbal : calib.gimbal.rule.Gimbal, optional
        Plays the encoder channels (lock counter-rotations at its limits);
        default: slip rings, no limits.

    Returns
    -------
    run : Run
    truth : Truth
    """
    seed, noise, flip_error_deg = options.seed, options.noise, options.flip_error_deg
    setup_rotvec = options.setup_rotvec
    rng = np.random.default_rng(seed)
    flip_errors = (
        rng.uniform(-flip_error_deg, flip_error_deg, len(seq.steps))
        if flip_error_deg > 0
        else np.zeros(len(seq.steps))
    )
    if options.random_setup_deg is not None:
        spread = options.random_setup_deg
        setup_rotvec = np.radians(rng.uniform(-spread, spread, 3))
    setup_rotvec = np.asarray(setup_rotvec, dtype=float)
    real = seq.with_flip_errors(flip_errors)
    tl = timeline(real)
    R = rotvec_to_dcm(setup_rotvec)
    time_s, dtheta, dv = true_increments(tl, R, cfg)
    dt = np.diff(np.concatenate([[0.0], time_s]))
    extra = extra if extra is not None else OptionalTermValues()
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
