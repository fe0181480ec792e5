"""A run log in a recording: its raw signals, where its gimbal attitudes come from, its notes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from calib.model import params as P
from calib.nav.transform import dcm_to_rotvec
from calib.sequence.definition import nominal_attitude, timeline

from .rrd import Summary, Writer
from .scene import AXIS_COLORS, SCENE_RATE_HZ, SCENE_STEP_DEG, gimbal_from_attitudes

if TYPE_CHECKING:
    from calib.calibration.result import CalibrationResult
    from calib.sequence.definition import Sequence
    from calib.sim.gimbal_run import Truth

SIGNAL_RATE_HZ = 20.0  # raw signals shown as block means at about this rate


@dataclass(frozen=True)
class RunContext:
    """What is known of a run besides its samples (each optional).

    Parameters
    ----------
    sequence : calib.sequence.definition.Sequence, optional
        The sequence the run followed.
    result : calib.calibration.result.CalibrationResult, optional
        Its calibration.
    truth : calib.sim.gimbal_run.Truth, optional
        What a simulated run really contains.
    """

    sequence: Sequence | None = None
    result: CalibrationResult | None = None
    truth: Truth | None = None


def block_means(time_rel: np.ndarray, dt: np.ndarray, x: np.ndarray, block: int):
    """Mean rate ``sum(x) / sum(dt)`` over blocks of ``block`` samples, stamped at the block middle."""
    starts = np.arange(0, len(dt), block)
    sums = np.add.reduceat(x, starts, axis=0)
    durations = np.add.reduceat(dt, starts)
    ends = np.minimum(starts + block, len(dt)) - 1
    t_mid = 0.5 * ((time_rel[starts] - dt[starts]) + time_rel[ends])
    return t_mid, sums / durations[:, None]


def log_signals(w: Writer, run, t_rel: np.ndarray, dt: np.ndarray) -> int:
    """Raw gyro rates and specific force as block means; returns the block length."""
    block = max(1, int(round(run.sample_rate_hz / SIGNAL_RATE_HZ)))
    t_sig, rate = block_means(t_rel, dt, run.dtheta_rad, block)
    _, force = block_means(t_rel, dt, run.dv_mps, block)
    w.series("signals/gyro_dps", t_sig, np.degrees(rate), "xyz", AXIS_COLORS)
    w.series("signals/accel_mps2", t_sig, force, "xyz", AXIS_COLORS)
    return block


def log_attitude_error(w: Writer, t_scene: np.ndarray, C_nav: np.ndarray, C_scene: np.ndarray) -> None:
    """The calibrated navigation's attitude against the scene's (rotation vector, arcsec)."""
    err = dcm_to_rotvec(np.einsum("nij,nkj->nik", C_nav, C_scene))
    w.series("attitude/nav_minus_gimbal_arcsec", t_scene, err / P.ARCSEC, "ENU", AXIS_COLORS)


def scene_frames(run, keep, t_scene, context: RunContext, nav, calibrated, w):
    """Gimbal angles (rad), C_start, R_mount and where they came from, for the run's scene.

    Encoder and sequence angles are relative to the sequence's start attitude,
    placed by the mounting rotation (truth, else estimated from the result's
    initial attitude, else identity). Without a sequence the start attitude is
    the measured one (the navigation's first attitude, mounting included).
    """
    sequence, result, truth = context.sequence, context.result, context.truth
    if run.gimbal_deg is not None:
        angles = np.radians(run.gimbal_deg[keep])
        source = "encoders (the run's outer_deg, middle_deg, inner_deg columns)"
    elif sequence is not None:
        angles = gimbal_from_attitudes(sequence.C_start, nominal_attitude(timeline(sequence), t_scene))
        source = f"sequence {sequence.name!r} (nominal attitude, decomposed and unwrapped)"
    elif nav is not None:
        angles = gimbal_from_attitudes(nav.C_b_n[0], nav.C_b_n[keep + 1])
        source = (
            "navigation attitude after calibration"
            if calibrated
            else "navigation attitude before calibration (coarse alignment)"
        )
    else:
        angles = np.zeros((len(keep), 3))
        source = "none (no encoders, sequence or alignment): the IMU stays at its start"
        w.note("nothing gives the attitude: the IMU is drawn at identity")
    if sequence is not None:
        C_start = sequence.C_start
        if truth is not None:
            return angles, C_start, truth.R_setup, source, "truth file (setup rotation)"
        if result is not None:
            return (
                angles,
                C_start,
                result.C_b_n0 @ C_start.T,
                source,
                "estimated: the result's initial attitude times C_start^T",
            )
        return angles, C_start, np.eye(3), source, "nominal (identity)"
    if nav is not None:
        return (
            angles,
            nav.C_b_n[0],
            np.eye(3),
            source,
            "included in the measured start attitude (no sequence)",
        )
    return angles, np.eye(3), np.eye(3), source, "unknown (identity)"


def _about_envelope(review) -> list[str]:
    if review.noise_sigma_v is None:
        return []
    return [
        "",
        "## Noise envelope",
        "",
        f"- residuals/after/noise_3sigma_mps: ±3σ of the velocity error that the noise of profile "
        f"{review.noise_profile!r} (ARW, VRW, Gauss-Markov drift) builds up at rest, propagated "
        f"with the fit's own error-state model; {len(review.noise_time)} rows (1 s at rest, "
        "0.1 s turning).",
        "- It starts at zero: the navigation starts at zero velocity from the fit's initial "
        "attitude. Left out: the uncertainty of that attitude (a g·phi0·t ramp) and of the 21 "
        "parameters; the fit absorbs part of the noise, so a good run stays well inside.",
    ]


def about_run(run, review, t_rel, block, n_scene, context: RunContext, summary: Summary) -> str:
    """The ``about`` document of a run recording: sources, time line, what is decimated, the scene
    (``context``: the sequence, result and truth given; ``summary``: where the scene came from, and
    the notes).
    """
    sequence, result, truth = context.sequence, context.result, context.truth
    fs, n = run.sample_rate_hz, run.n_samples
    lat_deg, g = review.latitude_deg, review.gravity_mps2
    scene_source, mount_source, notes = summary.scene_source, summary.mount_source, summary.notes
    lines = (
        [
            f"# Run {run.source}",
            "",
            f"- {n} samples at {fs:g} Hz, {t_rel[-1]:.1f} s; latitude {lat_deg:g} deg, gravity {g:.6f} m/s^2",
            f"- sequence: {sequence.name if sequence is not None else 'none (flips found from the gyros)'}",
            f"- result: {'yes, profile ' + result.profile if result is not None else 'none'}; "
            f"truth: {'yes' if truth is not None else 'none'}",
            "",
            "## Time line",
            "",
            f"`time` = seconds since the first sample starts (`time_s - {run.time_s[0] - t_rel[0]:.9g}`).",
            "",
            "## Rates (what is decimated)",
            "",
            f"- residuals/before, residuals/after: FULL rate, one row per sample at its end time "
            f"({n} rows each; the navigation's initial zero at time 0 is not logged).",
            f"- signals/*: DECIMATED for display: means over blocks of {block} samples "
            f"({fs / block:g} Hz), i.e. sum(increments) / sum(dt), stamped at the block middle.",
            f"- world/... transforms, attitude/*, sequence/position: DECIMATED: {n_scene} rows, one per "
            f"1/{SCENE_RATE_HZ:g} s and one per {SCENE_STEP_DEG:g} deg turned (gyros).",
        ]
        + _about_envelope(review)
        + [
            "",
            "## Scene",
            "",
            "- IMU attitude = R_mount C_start R_Z(outer) R_X(middle) R_Y(inner).",
            f"- gimbal angles from: {scene_source}",
            f"- R_mount from: {mount_source}",
            "- rings: outer (orange) about start-Z, middle (grey) about X, inner (blue) about Y;"
            " body axes X red, Y green, Z blue; ENU axes in the corner; the purple arrow is gravity.",
        ]
    )
    if notes:
        lines += ["", "## Notes", ""] + [f"- {x}" for x in notes]
    return "\n".join(lines)
