"""Read a run log in chunks, and calibrate it without ever holding it whole.

:func:`read_chunks` yields ``(time_s, dtheta, dv)`` blocks of an NPZ
(members read as streams: stored or deflated, never loaded whole) or an
``imu-run/1`` CSV (rows parsed a block at a time). :func:`calibrate_file`
runs the estimator on such a source: one reading pass finds where the IMU
turns and checks the samples (a second one judges a noisy or strongly biased
gyro on windowed rates), the first rest is read for the alignment, a MEMS
unit's bias and heading are solved from all rests (two more passes), and
every navigation of :func:`calib.estimator.fit_intervals` reads the file
again. Memory: one chunk, plus one byte per sample for the motion mask.

What the in-memory path (:func:`calib.runlog.read_run` then
:func:`calib.calibration.calibrate_run`) checks that this one checks per
chunk only: a saturated channel (runs of 10 equal extreme samples) across a
chunk end is not seen; the grid's nominal period is the median of the
chunks' median periods. Gaps are refused (no ``--allow-gaps`` here), and
``--sequence`` is not supported: flips are detected from the gyros.
"""

from __future__ import annotations

import math

import numpy as np

from . import params as P
from . import sanity
from .errors import CalibError
from .estimator import (
    MOTION_THRESHOLD,
    _grow,
    check_first_rest,
    coarse_alignment,
    fit_intervals,
    motion_window,
    start_from_rests,
    window_rate,
    windowed_motion,
)
from .extras import NONE as NO_EXTRAS
from .extras import Extras
from .gyrocompass import gyrocompass_rests
from .jacobian import default_grid
from .profiles import NoiseProfile
from .requirements import PAPER, Requirements
from .runlog import READ_ROWS, nominal_period, read_chunks, read_meta
from .strapdown import quat_mult, quat_to_dcm, rotvec_to_quat
from .stream import Chunk, Site, chunk_cuts, quat_scan


def aligned(blocks, cuts: np.ndarray, t_start: float):
    """Re-cut blocks of samples into :class:`calib.stream.Chunk` s that end exactly at ``cuts``."""
    buf, start, k, t_before = [], 0, 1, t_start
    for block in blocks:
        buf.append(block)
        have = sum(len(b[0]) for b in buf)
        while k < len(cuts) and cuts[k] <= start + have:
            t, th, dv = (np.concatenate([b[i] for b in buf]) for i in range(3))
            m = int(cuts[k] - start)
            yield Chunk(start, t[:m], th[:m], dv[:m], t_before)
            t_before, start, k = float(t[m - 1]), int(cuts[k]), k + 1
            buf, have = [(t[m:], th[m:], dv[m:])], have - m


def _blocks_with_dt(path, rows: int, where: str, period: float):
    """Blocks with each sample's interval, refusing time that stalls, runs back or jumps."""
    prev, start = None, 0
    for t, th, dv in read_chunks(path, rows):
        if not len(t):
            continue
        first = prev if prev is not None else (t[0] - (t[1] - t[0]) if len(t) > 1 else t[0] - period)
        dt = np.diff(np.concatenate([[first], t]))
        bad = np.flatnonzero((dt <= 0) | (dt > 2.0 * period) | ~np.isfinite(dt))
        if bad.size:
            k = int(bad[0])
            raise CalibError(
                f"time steps by {dt[k]:.6g} s at sample {start + k} (nominal period {period:.6g} s)",
                where,
                "time must strictly increase without gaps; `seqdesign calibrate "
                "--allow-gaps` reads logs with gaps",
            )
        yield start, t, th, dv, dt
        prev, start = t[-1], start + len(t)


def survey(path, profile: NoiseProfile, rows: int = READ_ROWS, where: str | None = None):
    """The motion mask, the run's start, its period; per-chunk sanity checks.

    Returns ``(moving, t_start, period_s)``; ``moving`` is judged and grown
    as :func:`calib.estimator.detect_motion` judges and grows it. One reading
    pass, and a second one when the gyros must be judged on windowed rates
    (a noisy gyro or a large bias): their steady rate, the per-axis median of
    the whole run there, is here the median of the chunks' medians (the same
    when the run fits in one chunk).
    """
    where = where or str(path)
    nominal = nominal_period(read_meta(path), where)
    masks, medians, steady, t_start = [], [], [], None
    for a, t, th, dv, dt in _blocks_with_dt(path, rows, where, nominal):
        here = f"{where}, samples {a}-{a + len(t) - 1}"
        t_start = t[0] - dt[0] if t_start is None else t_start
        sanity.check_rates(th, dt, here)
        sanity.check_saturation(th, dv, here)
        masks.append(np.sqrt(np.einsum("ni,ni->n", th, th)) / dt > MOTION_THRESHOLD)
        medians.append(float(np.median(dt)))
        steady.append(np.median(th / dt[:, None], axis=0))
    if t_start is None:
        raise CalibError("the log has no samples", where, "give a recorded run")
    period, steady = float(np.median(medians)), np.median(steady, axis=0)
    window = motion_window(profile.arw, period)
    if windowed_motion(window, steady):
        moving = _grow(_windowed_mask(path, rows, where, nominal, window, steady), 2 + window)
    else:
        moving = _grow(np.concatenate(masks))
    if not moving.any():
        raise CalibError(
            "no rotation found in the run (gyro rates never exceed "
            f"{math.degrees(MOTION_THRESHOLD):.2f} deg/s)",
            where,
            "a calibration run must flip the IMU",
        )
    return moving, float(t_start), period


def _windowed_mask(path, rows: int, where: str, period: float, window: int, steady: np.ndarray):
    """Windowed rate above the threshold, per sample (:func:`calib.estimator.window_rate`).

    The running sums carry across chunks exactly as the whole run's do; only
    the samples whose windows are still needed are kept.
    """
    half = window // 2
    angle, clock, base, done, total, masks = np.zeros((1, 3)), np.zeros(1), 0, 0, 0, []
    for a, t, th, _, dt in _blocks_with_dt(path, rows, where, period):
        inc = (th / dt[:, None] - steady) * dt[:, None]
        angle = np.concatenate([angle, np.cumsum(np.vstack([angle[-1:], inc]), axis=0)[1:]])
        clock = np.concatenate([clock, np.cumsum(np.concatenate([clock[-1:], dt]))[1:]])
        total = a + len(t)
        upto = total - (window - half)  # the samples whose windows end within what was read
        if upto > done:
            masks.append(
                window_rate(angle, clock, np.arange(done, upto), total, window, base) > MOTION_THRESHOLD
            )
            done = upto
            keep = max(0, done - half - base)
            angle, clock, base = angle[keep:], clock[keep:], base + keep
    masks.append(window_rate(angle, clock, np.arange(done, total), total, window, base) > MOTION_THRESHOLD)
    return np.concatenate(masks)


def _read_rests(path, moving, rows, where, period, profile):
    """Check the rests chunk by chunk; the first rest's samples, each rest's length and mean rate."""
    end = int(np.argmax(moving))
    starts, _ = sanity.runs_of(~moving)
    first, T, turned = ([], [], []), np.zeros(len(starts)), np.zeros((len(starts), 3))
    for a, t, th, dv, dt in _blocks_with_dt(path, rows, where, period):
        still = ~moving[a : a + len(t)]
        sanity.check_rests(dv, dt, ~still, profile.vrw, f"{where}, samples {a}-{a + len(t) - 1}")
        if a < end:
            for part, x in zip(first, (th, dv, dt)):
                part.append(x[: end - a])
        rest = np.searchsorted(starts, np.flatnonzero(still) + a, side="right") - 1
        T += np.bincount(rest, weights=dt[still], minlength=len(starts))
        for i in range(3):
            turned[:, i] += np.bincount(rest, weights=th[still, i], minlength=len(starts))
    th, dv, dt = (np.concatenate(p) if p else np.zeros((0, 3) if i < 2 else 0) for i, p in enumerate(first))
    return (th, dv, dt), T, turned


def _rest_attitudes(path, rows, where, period, moving, bias):
    """Body attitude at each rest's middle relative to the start, integrated chunk by chunk."""
    starts, ends = sanity.runs_of(~moving)
    mids, q_mid, carry = (starts + ends) // 2, np.empty((len(starts), 4)), np.array([1.0, 0, 0, 0])
    for a, t, th, _, dt in _blocks_with_dt(path, rows, where, period):
        q = quat_mult(carry, quat_scan(rotvec_to_quat(th - bias * dt[:, None])))
        here = (mids >= a) & (mids < a + len(t))
        q_mid[here] = q[mids[here] - a]
        carry = q[-1]
    return quat_to_dcm(q_mid)


def start_attitude(path, moving, rows, where, period, latitude_rad, gravity_mps2, profile, requirements):
    """Checked rests, the start values and ``C_b_n`` at the start, as the in-memory path has them.

    Levelling and gyrocompassing on the first rest; a gyro bias beyond the
    Earth rate (a MEMS unit) is taken out first and then solved with the
    heading from all rests (:func:`calib.gyrocompass.gyrocompass_rests`),
    each of its two passes one more reading of the file.
    """
    (th, dv, dt), T, turned = _read_rests(path, moving, rows, where, period, profile)
    sanity.check_latitude(latitude_rad, where)
    check_first_rest(th, dv, dt, slice(None), gravity_mps2, where, requirements)
    start = start_from_rests(turned.sum(axis=0) / T.sum())
    C0 = coarse_alignment(th - start[P.GYRO_BIAS] * dt[:, None], dv, dt)
    if np.any(start[P.GYRO_BIAS]):
        start[P.GYRO_BIAS], C0 = gyrocompass_rests(
            lambda bias: _rest_attitudes(path, rows, where, period, moving, bias),
            T,
            turned / T[:, None],
            C0,
            latitude_rad,
            start[P.GYRO_BIAS],
        )
    return start, C0


def calibrate_file(
    path,
    latitude_rad: float,
    gravity_mps2: float,
    profile: NoiseProfile,
    extras: Extras = NO_EXTRAS,
    partial: bool = False,
    requirements: Requirements = PAPER,
    rows: int = READ_ROWS,
    max_iterations: int | None = None,
    tol_sigma: float = 1e-3,
):
    """:func:`calib.estimator.calibrate` of a run log read from disk chunk by chunk.

    Returns the same :class:`calib.estimator.Fit`; the estimates equal those
    of the in-memory path to rounding (the same passes over the same samples).
    """
    where = str(path)
    moving, t_start, period = survey(path, profile, rows, where)
    start, C0 = start_attitude(
        path,
        moving,
        rows,
        where,
        nominal_period(read_meta(path), where),
        latitude_rad,
        gravity_mps2,
        profile,
        requirements,
    )
    grid = default_grid(moving, 1.0 / period)
    del moving
    site, cuts = Site(latitude_rad, gravity_mps2, t_start), chunk_cuts(grid)
    return fit_intervals(
        lambda: aligned(read_chunks(path, rows), cuts, t_start),
        grid,
        site,
        C0,
        profile,
        extras=extras,
        partial=partial,
        requirements=requirements,
        max_iterations=max_iterations,
        tol_sigma=tol_sigma,
        where=where,
        start=start,
    )
