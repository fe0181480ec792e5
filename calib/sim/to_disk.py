"""Simulate a long run straight to disk, a time window at a time.

:func:`calib.sim.gimbal_run.simulate` holds the whole run in memory: a 2-hour run at
2 kHz (14.4 M samples) would need several GB before it is written.
:func:`simulate_to_file` calls the same exact per-sample kernel
(:func:`calib.sequence.kinematics.true_increments` on the sample ends of one window) window
by window, applies the 21 errors and the white noise, and appends the
samples to an NPZ (uncompressed, members written as they come) or a CSV
(``imu-run/1``) file; the memory it needs is one window's.

Without noise the samples are those of :func:`calib.sim.gimbal_run.simulate` to the
last bit of the kinematics (the same closed-form integrals; the windows
only change where a sample's integral starts, not its value). With noise
the draws come window by window, so a seed gives a different (equally
distributed) noise sequence than :func:`calib.sim.gimbal_run.simulate`. Not streamed
(refused with a clear message): Gauss-Markov bias instability, the optional
terms of :mod:`calib.model.optional_terms`, flip errors and the gimbal encoder columns.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.model.error_model import ErrorModel
from calib.nav.transform import rotvec_to_dcm
from calib.noise.profiles import NoiseProfile
from calib.runlog import write_windows
from calib.sequence.definition import Sequence, timeline
from calib.sequence.kinematics import SimConfig, true_increments

from .gimbal_run import SIM, SimOptions, Truth, run_meta

WINDOW_SAMPLES = 1 << 18  # 2 MB per column: I/O in large blocks, memory still small


def sample_windows(
    seq: Sequence,
    cfg: SimConfig,
    errors: ErrorModel,
    profile: NoiseProfile,
    options: SimOptions = SIM,
    window: int = WINDOW_SAMPLES,
):
    """Yield ``(time_s, dtheta_m, dv_m)`` of consecutive windows of the run (IMU output).

    ``options`` gives the base mounting, noise and seed; flip errors and a drawn
    mounting are not streamed.
    """
    noise = options.noise
    if options.flip_error_deg > 0 or options.random_setup_deg is not None:
        raise CalibError(
            "flip errors and a drawn mounting are not written a window at a time",
            "simulate_to_file",
            "give the mounting as setup_rotvec, or simulate in memory (calib.sim.gimbal_run.simulate)",
        )
    if profile.has_gauss_markov and noise:
        raise CalibError(
            f"profile {profile.name!r} has Gauss-Markov bias instability, which the "
            "streamed simulator does not draw",
            "profile",
            "use a white-noise profile, or `seqdesign simulate` for this run",
        )
    rng = np.random.default_rng(options.seed)
    tl = timeline(seq)
    R = rotvec_to_dcm(np.asarray(options.setup_rotvec, dtype=float))
    rate = cfg.sample_rate_hz
    n = int(math.floor(tl.duration_s * rate + 1e-9))  # as calib.sequence.kinematics.uniform_times
    for a in range(0, n, window):
        b = min(n, a + window)
        # The window's sample ends, and the end before it (0: the run's start) where its
        # first integral starts; the kernel integrates from 0 to ends[0] first: dropped.
        ends = np.arange(a, b + 1) / rate
        time_s, dtheta, dv = true_increments(tl, R, cfg, time_s=ends if a else ends[1:])
        if a:
            time_s, dtheta, dv = time_s[1:], dtheta[1:], dv[1:]
        dt = np.diff(ends)
        dtheta_m, dv_m = errors.apply(dtheta, dv, dt)
        if noise:
            sq = np.sqrt(dt)[:, None]
            dtheta_m = dtheta_m + profile.arw * sq * rng.standard_normal(dtheta_m.shape)
            dv_m = dv_m + profile.vrw * sq * rng.standard_normal(dv_m.shape)
        yield time_s, dtheta_m, dv_m


def simulate_to_file(
    path,
    seq: Sequence,
    cfg: SimConfig,
    errors: ErrorModel,
    profile: NoiseProfile,
    options: SimOptions = SIM,
    meta_extra: dict | None = None,
    window: int = WINDOW_SAMPLES,
) -> tuple[int, Truth]:
    """Simulate a run window by window into ``path`` (.npz or .csv); nothing is left half-written.

    ``options`` gives the base mounting, noise and seed (:func:`sample_windows`);
    ``meta_extra`` keys join the run log's metadata.

    Returns
    -------
    n_samples : int
    truth : Truth
        For :func:`calib.sim.truth.write_truth` (no flip errors, no optional terms).
    """
    target = Path(path)
    kind = target.suffix.lower()
    if kind not in (".npz", ".csv"):
        raise CalibError(f"unknown run format {target.suffix!r}", str(path), "name the file .csv or .npz")
    meta = run_meta(cfg, seq.name) | (meta_extra or {})
    windows = sample_windows(seq, cfg, errors, profile, options, window)
    n = write_windows(target, meta, windows)
    truth = Truth(
        errors=errors,
        setup_rotvec=np.asarray(options.setup_rotvec, dtype=float),
        flip_errors_deg=np.zeros(len(seq.steps)),
        profile=profile.name,
        seed=options.seed,
        noise=options.noise,
    )
    return n, truth
