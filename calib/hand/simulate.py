"""Simulator of calibration runs placed by hand: exact IMU increments of a :class:`HandPlan`.

Each sample is the increment over its interval ``(t_{k-1}, t_k]`` (what a
rate-integrating gyro or a logger's averaging filter outputs):
``dtheta_k = int omega_ib_b dt`` and ``dv_k = int f_b dt`` of the closed-form
trajectory of :mod:`calib.hand.trajectory`. The integrals are taken over a grid
``oversample`` times finer than the samples, cut as well at every instant where
the motion is not infinitely smooth (the ends of rests and turns); on each
piece the integrand is constant (a rest: one node is exact) or analytic (a
move: :data:`GAUSS_NODES`-point Gauss-Legendre, error of order ``h^8``
relative to the turn's time scale, i.e. at rounding for the grids used). Then
the 21 errors (:meth:`calib.model.error_model.ErrorModel.apply`) and the profile's
noise (:func:`calib.sim.gimbal_run.add_noise`). ``docs/by-hand-sim.md`` gives the physics.

The troubles of real hand recordings (:mod:`calib.hand.troubles`: tremor, gyro
g-sensitivity, a sample-clock rate error, host time stamps) are off by default;
a run without them is the same to the last bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.io.files import atomic_write_text
from calib.model.error_model import ErrorModel
from calib.nav.site import Site
from calib.noise.profiles import NoiseProfile
from calib.runlog import Run, write_run, write_windows
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import Truth, add_noise, run_meta
from calib.sim.truth import truth_path_for, truth_to_dict

from .host_clock import epoch_ms, epoch_seconds, host_stamps, write_epoch_ms_csv
from .plan import HandPlan
from .trajectory import hand_state, segment_of, sensed
from .tremor import Tremor, held_at
from .troubles import HandTroubles, apply_g_sensitivity, troubles_to_table

GAUSS_NODES = 4  # per piece of a move
CHUNK_NODES = 200_000  # nodes evaluated at once (bounds the memory of the attitude arrays)
MOTION = "by-hand"


def sample_times(plan: HandPlan, sample_rate_hz: float) -> np.ndarray:
    """Sample end times at a uniform rate over the plan (the first interval starts at 0)."""
    n = int(math.floor(plan.duration_s * sample_rate_hz + 1e-9))
    return np.arange(1, n + 1) / sample_rate_hz


def quadrature(
    plan: HandPlan, time_s: np.ndarray, oversample: int, tremor: Tremor | None = None
) -> tuple[np.ndarray, ...]:
    """Nodes, weights and sample index of the rule integrating over each sample interval.

    Parameters
    ----------
    plan : HandPlan
    time_s : ndarray, shape (n,)
        End of each sample; the first interval starts at 0.
    oversample : int
        Equal pieces per sample interval (before the cuts at the plan's breakpoints).
    tremor : Tremor, optional
        Held rests: integrated as moves are (Gauss-Legendre), cut at the ends of their tapers.

    Returns
    -------
    t, w : ndarray
        Nodes (s) and weights (s).
    sample : ndarray of int
        The sample each node belongs to.
    """
    if oversample < 1:
        raise ValueError("oversample must be at least 1")
    starts = np.concatenate([[0.0], time_s[:-1]])
    frac = np.arange(oversample) / oversample
    fine = (starts[:, None] + (time_s - starts)[:, None] * frac[None, :]).ravel()
    breaks = plan.breakpoints_s
    if tremor is not None:
        breaks = np.concatenate([breaks, tremor.breakpoints_s])
    inside = breaks[(breaks > 0.0) & (breaks < time_s[-1])]
    cuts = np.unique(np.concatenate([fine, time_s, inside]))
    a, b = cuts[:-1], cuts[1:]
    mid = 0.5 * (a + b)
    sample = np.searchsorted(time_s, mid)
    _, moving = segment_of(plan, mid)
    if tremor is not None:
        moving = moving | (held_at(tremor, mid) >= 0)
    # A rest piece: the integrand is constant, its midpoint is exact.
    t_rest, w_rest, s_rest = mid[~moving], (b - a)[~moving], sample[~moving]
    x, gw = np.polynomial.legendre.leggauss(GAUSS_NODES)
    half = 0.5 * (b - a)[moving]
    t_move = (mid[moving][:, None] + half[:, None] * x[None, :]).ravel()
    w_move = (half[:, None] * gw[None, :]).ravel()
    s_move = np.repeat(sample[moving], GAUSS_NODES)
    return (
        np.concatenate([t_rest, t_move]),
        np.concatenate([w_rest, w_move]),
        np.concatenate([s_rest, s_move]),
    )


def true_increments(
    plan: HandPlan,
    site: Site,
    sample_rate_hz: float,
    oversample: int = 10,
    time_s: np.ndarray | None = None,
    tremor: Tremor | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact gyro and accelerometer increments of a hand-placed run.

    Parameters
    ----------
    plan : HandPlan
    site : Site
        Where the plan is played (its Earth rate and gravity).
    sample_rate_hz : float
    oversample : int
        Pieces per sample interval of the quadrature grid (default 10).
    time_s : ndarray, optional
        Sample end times (increasing, the first interval from 0); default uniform.
    tremor : Tremor, optional
        The held rests' tremor (:mod:`calib.hand.tremor`); None: every rest on the table.

    Returns
    -------
    time_s : ndarray, shape (n,)
    dtheta, dv : ndarray, shape (n, 3)
        ``int omega_ib_b dt`` (rad) and ``int f_b dt`` (m/s) over each sample.
    """
    if time_s is None:
        time_s = sample_times(plan, sample_rate_hz)
    n = len(time_s)
    t, w, sample = quadrature(plan, time_s, oversample, tremor)
    dtheta, dv = np.zeros((n, 3)), np.zeros((n, 3))
    for lo in range(0, len(t), CHUNK_NODES):
        sl = slice(lo, lo + CHUNK_NODES)
        omega, f = sensed(hand_state(plan, t[sl], tremor), site)
        for i in range(3):
            dtheta[:, i] += np.bincount(sample[sl], w[sl] * omega[:, i], minlength=n)
            dv[:, i] += np.bincount(sample[sl], w[sl] * f[:, i], minlength=n)
    return time_s, dtheta, dv


def draw_errors(half_range_units: np.ndarray, rng: np.random.Generator) -> ErrorModel:
    """21 errors drawn uniformly within ``+-half_range_units`` (spec units, e.g. a MEMS unit's sizes)."""
    half = np.asarray(half_range_units, dtype=float)
    return ErrorModel.from_units(rng.uniform(-half, half))


@dataclass(frozen=True)
class HandTruth:
    """What a simulated run placed by hand really contains.

    Attributes
    ----------
    errors : ErrorModel
        The injected 21 errors (SI).
    plan : HandPlan
        The trajectory: rest attitudes, rest and move times, turns, translations, wobbles.
    profile : str
        The noise profile's name ("" when none was given).
    seed : int or None
    noise : bool
        Whether noise was added.
    oversample : int
        The quadrature grid of the increments.
    troubles : HandTroubles
        Tremor, g-sensitivity, rate error and stamps (:mod:`calib.hand.troubles`); none by default.
    """

    errors: ErrorModel
    plan: HandPlan
    profile: str
    seed: int | None
    noise: bool
    oversample: int = 10
    troubles: HandTroubles = HandTroubles()

    @property
    def rest_start_s(self) -> np.ndarray:
        return self.plan.rest_start_s

    @property
    def rest_end_s(self) -> np.ndarray:
        return self.plan.rest_end_s

    def as_truth(self) -> Truth:
        """The :class:`calib.sim.gimbal_run.Truth` a truth reader sees: the errors, no mounting, no flips."""
        return Truth(
            errors=self.errors,
            setup_rotvec=np.zeros(3),
            flip_errors_deg=np.zeros(0),
            profile=self.profile,
            seed=self.seed,
            noise=self.noise,
        )


def hand_meta(cfg: SimConfig, plan: HandPlan) -> dict[str, str]:
    """The run log's metadata: the site (:func:`~calib.sim.gimbal_run.run_meta`), ``motion: by-hand``."""
    return run_meta(cfg, None, motion=MOTION, poses=str(plan.n_poses))


@dataclass(frozen=True)
class HandStreams:
    """The random generators of a simulated run placed by hand, when not drawn from its seed.

    Parameters
    ----------
    noise : numpy.random.Generator, optional
        The noise's generator; default ``default_rng(seed)``.
    stamps : numpy.random.Generator, optional
        The host delays' generator (jittering stamps only); default: a stream spawned from ``seed``.
    """

    noise: np.random.Generator | None = None
    stamps: np.random.Generator | None = None


FROM_SEED = HandStreams()  # every draw from the seed


def simulate_by_hand(
    plan: HandPlan,
    cfg: SimConfig,
    errors: ErrorModel | None = None,
    profile: NoiseProfile | None = None,
    seed: int | None = None,
    oversample: int = 10,
    troubles: HandTroubles | None = None,
    streams: HandStreams = FROM_SEED,
) -> tuple[Run, HandTruth]:
    """Simulate a run placed by hand.

    Parameters
    ----------
    plan : HandPlan
    cfg : SimConfig
        Site, sample rate (the IMU's nominal one) and (optionally) measured gravity.
    errors : ErrorModel, optional
        The injected 21 errors; None: none.
    profile : NoiseProfile, optional
        White noise and any Gauss-Markov bias instability; None: a noise-free run.
    seed : int, optional
        Seed of the noise (recorded in the truth).
    oversample : int
        Pieces per sample interval of the quadrature (default 10).
    troubles : HandTroubles, optional
        Tremor, gyro g-sensitivity, a sample-clock rate error, host stamps
        (:mod:`calib.hand.troubles`); None: none, the run is the same to the last bit.
    streams : HandStreams
        The noise's and the host delays' generators instead of the seed's.

    Returns
    -------
    run : Run
        ``time_s`` the written stamps: the nominal sample times, the host's reception
        times, or epoch seconds in whole ms (``troubles.stamps``).
    truth : HandTruth
    """
    errors = errors if errors is not None else ErrorModel.zero()
    trouble = troubles if troubles is not None else HandTroubles()
    rate_hz = cfg.sample_rate_hz * (1.0 + trouble.rate_error)  # the IMU's true rate
    time_s, dtheta, dv = true_increments(
        plan, cfg.site, rate_hz, oversample=oversample, tremor=trouble.tremor
    )
    dt = np.diff(np.concatenate([[0.0], time_s]))
    dv_true = dv
    dtheta, dv = errors.apply(dtheta, dv, dt)
    dtheta = apply_g_sensitivity(dtheta, dv_true, trouble.g_sensitivity)
    if profile is not None:
        noise_rng = streams.noise if streams.noise is not None else np.random.default_rng(seed)
        dtheta, dv = add_noise(dtheta, dv, dt, profile, noise_rng)
    if trouble.any:
        time_s, dtheta, dv = _as_logged(time_s, dtheta, dv, cfg.sample_rate_hz, trouble, seed, streams.stamps)
    run = Run(time_s=time_s, dtheta_rad=dtheta, dv_mps=dv, meta=hand_meta(cfg, plan))
    truth = HandTruth(
        errors=errors,
        plan=plan,
        profile=profile.name if profile is not None else "",
        seed=seed,
        noise=profile is not None,
        oversample=oversample,
        troubles=trouble,
    )
    return run, truth


def _as_logged(time_s, dtheta, dv, nominal_hz, trouble: HandTroubles, seed, stamp_rng):
    """The IMU's samples as the log holds them: increments over the nominal period, the stamps written."""
    if trouble.rate_error != 0.0:
        # Mean rate and specific force over the true sample, times the nominal period.
        scale = 1.0 + trouble.rate_error
        dtheta, dv = dtheta * scale, dv * scale
    stamps = np.arange(1, len(time_s) + 1) / nominal_hz
    if trouble.stamp_jitter_s > 0.0:
        if stamp_rng is None:
            stamp_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
        stamps = host_stamps(time_s, trouble.stamp_jitter_s, stamp_rng)
    if trouble.stamps == "epoch-ms":
        stamps = epoch_seconds(epoch_ms(stamps, trouble.epoch_ms))
    return stamps, dtheta, dv


def plan_to_table(plan: HandPlan) -> dict:
    """The ``[hand]`` table of a truth file: the plan, exactly (floats written as reprs)."""

    def rows(a: np.ndarray) -> list:
        return np.asarray(a, dtype=float).tolist()

    return {
        "motion": MOTION,
        "rest_start_s": rows(plan.rest_start_s),
        "rest_end_s": rows(plan.rest_end_s),
        "rest_s": rows(plan.rest_s),
        "C_b_n": rows(plan.C_b_n),
        "move_s": rows(plan.move_s),
        "turn_s": rows(plan.turn_s),
        "translation_m": rows(plan.translation_m),
        "wobble_deg": rows(np.degrees(plan.wobble_rad)),
        "wobble_axis": rows(plan.wobble_axis),
    }


def plan_from_table(table: dict) -> HandPlan:
    """The plan of a ``[hand]`` table written by :func:`plan_to_table`."""
    if "rest_s" in table:
        rest = np.asarray(table["rest_s"], dtype=float)
    else:  # the rests from their ends (to rounding)
        rest = np.asarray(table["rest_end_s"], dtype=float) - np.asarray(table["rest_start_s"], dtype=float)
    return HandPlan(
        C_b_n=np.asarray(table["C_b_n"], dtype=float),
        rest_s=rest,
        move_s=np.asarray(table["move_s"], dtype=float),
        turn_s=np.asarray(table["turn_s"], dtype=float),
        translation_m=np.asarray(table["translation_m"], dtype=float).reshape(-1, 3),
        wobble_rad=np.radians(np.asarray(table["wobble_deg"], dtype=float)),
        wobble_axis=np.asarray(table["wobble_axis"], dtype=float).reshape(-1, 3),
    )


def hand_truth_to_dict(truth: HandTruth) -> dict:
    """The truth TOML document: the common tables (:func:`calib.sim.truth.truth_to_dict`) and ``[hand]``."""
    doc = truth_to_dict(truth.as_truth())
    doc["meta"]["oversample"] = int(truth.oversample)
    doc["hand"] = plan_to_table(truth.plan) | troubles_to_table(truth.troubles)
    return doc


def write_hand_truth(path: str | Path, truth: HandTruth, provenance: dict | None = None) -> None:
    """Write the truth file of a hand-placed run atomically (read by :func:`calib.sim.truth.read_truth`)."""
    import tomli_w

    doc = hand_truth_to_dict(truth)
    if provenance:
        doc["provenance"] = provenance
    atomic_write_text(path, tomli_w.dumps(doc))


def write_hand_run(output: str | Path, run: Run, truth: HandTruth, provenance: dict | None = None) -> Path:
    """Write the run log (``.csv`` or ``.npz``) and its truth file beside it; return the truth's path.

    Epoch-ms stamps (``truth.troubles.stamps``) are written as a ``time_ms`` column of
    integers, in a ``.csv`` only. A host's stamps are written as they are, unchecked (a
    reader judges them; :func:`calib.runlog.write_run` would refuse stamps that repeat or
    step by a fraction of a period).
    """
    if truth.troubles.stamps == "epoch-ms":
        if Path(output).suffix.lower() != ".csv":
            raise ValueError("epoch-ms stamps are written in a .csv run log (an .npz holds float seconds)")
        write_epoch_ms_csv(run, output)
    elif truth.troubles.stamp_jitter_s > 0.0:
        write_windows(output, run.meta, [(run.time_s, run.dtheta_rad, run.dv_mps)])
    else:
        write_run(run, output)
    truth_path = truth_path_for(output)
    write_hand_truth(truth_path, truth, provenance)
    return truth_path
