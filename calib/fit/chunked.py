"""Read a run log in chunks, and calibrate it without ever holding it whole.

:func:`read_chunks` yields ``(time_s, dtheta, dv)`` blocks of an NPZ
(members read as streams: stored or deflated, never loaded whole) or an
``imu-run/1`` CSV (rows parsed a block at a time). :func:`fit_file`
runs the estimator on such a source: one reading pass finds where the IMU
turns and checks the samples (a second one judges a noisy or strongly biased
gyro on windowed rates), the first rest is read for the alignment, a MEMS
unit's bias and heading are solved from all rests (two more passes), and
every navigation of :func:`calib.fit.estimator.fit_intervals` reads the file
again. Memory: one chunk, plus one byte per sample for the motion mask (two
with a sequence file, whose flips are checked against the gyros as in memory).
:func:`calib.calibration.entry.calibrate` is the entry that applies the policy.

What the in-memory path (:func:`calib.runlog.read_run` then
:func:`calib.calibration.entry.calibrate`) checks that this one checks per
chunk only: a saturated channel (runs of 10 equal extreme samples) across a
chunk end is not seen; the grid's nominal period is the median of the
chunks' median periods. A sequence file's flips are checked against the
motion judged with the profile's gyro noise (in memory: sample by sample).
"""

from __future__ import annotations

import math

import numpy as np

from calib.errors import CalibError
from calib.nav.chunk_pass import Chunk, Passes, chunk_cuts, quat_scan
from calib.nav.jacobian import default_grid
from calib.nav.site import Site
from calib.nav.transform import quat_mult, quat_to_dcm, rotvec_to_quat
from calib.noise.profiles import NoiseProfile
from calib.runlog import READ_ROWS, Run, nominal_period, read_chunks, read_meta
from calib.sequence.definition import timeline
from calib.sequence.motion import (
    MIN_TURN_DEG,
    MOTION_THRESHOLD,
    carried_cumsum,
    check_sequence_matches,
    grow,
    motion_window,
    row_norm,
    runs_of,
    sample_motion,
    sequence_mask,
    window_rate,
    windowed_motion,
)

from . import sanity
from .estimator import fit_intervals
from .gyrocompass import Rests
from .options import FIT, FitOptions
from .solution import nominal_judge
from .start import check_first_rest, start_attitude


def aligned(blocks, cuts: np.ndarray, t_start: float):
    """Re-cut blocks of samples into :class:`calib.nav.chunk_pass.Chunk` s that end exactly at ``cuts``."""
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
                "--allow-gaps` (allow_gaps=True) reads logs with gaps in memory",
            )
        yield start, t, th, dv, dt
        prev, start = t[-1], start + len(t)


def survey(path, profile: NoiseProfile, rows: int = READ_ROWS, where: str | None = None):
    """The motion mask, the run's start, its period; per-chunk sanity checks.

    Returns ``(moving, t_start, period_s)``; ``moving`` is judged and grown
    as :func:`calib.sequence.motion.detect_motion` judges and grows it. One reading
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
        masks.append(sample_motion(th, dt))
        medians.append(float(np.median(dt)))
        steady.append(np.median(th / dt[:, None], axis=0))
    if t_start is None:
        raise CalibError("the log has no samples", where, "give a recorded run")
    period, steady = float(np.median(medians)), np.median(steady, axis=0)
    window = motion_window(profile.arw, period)
    if windowed_motion(window, steady):
        moving = grow(_windowed_mask(path, rows, where, nominal, window, steady), 2 + window)
    else:
        moving = grow(np.concatenate(masks))
    if not moving.any():
        raise CalibError(
            "no rotation found in the run (gyro rates never exceed "
            f"{math.degrees(MOTION_THRESHOLD):.2f} deg/s)",
            where,
            "a calibration run must flip the IMU",
        )
    return moving, float(t_start), period


def _windowed_mask(path, rows: int, where: str, period: float, window: int, steady: np.ndarray):
    """Windowed rate above the threshold, per sample (:func:`calib.sequence.motion.window_rate`).

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
    starts, _ = runs_of(~moving)
    first, T, turned = ([], [], []), np.zeros(len(starts)), np.zeros((len(starts), 3))
    for a, t, th, dv, dt in _blocks_with_dt(path, rows, where, period):
        still = ~moving[a : a + len(t)]
        sanity.check_rests(dv, dt, ~still, profile.vrw, f"{where}, samples {a}-{a + len(t) - 1}")
        if a < end:
            for part, x in zip(first, (th, dv, dt), strict=True):
                part.append(x[: end - a])
        rest = np.searchsorted(starts, np.flatnonzero(still) + a, side="right") - 1
        T += np.bincount(rest, weights=dt[still], minlength=len(starts))
        for i in range(3):
            turned[:, i] += np.bincount(rest, weights=th[still, i], minlength=len(starts))
    th, dv, dt = (np.concatenate(p) if p else np.zeros((0, 3) if i < 2 else 0) for i, p in enumerate(first))
    return (th, dv, dt), T, turned


def _rest_attitudes(path, rows, where, period, moving, bias):
    """Body attitude at each rest's middle relative to the start, integrated chunk by chunk."""
    starts, ends = runs_of(~moving)
    mids, q_mid, carry = (starts + ends) // 2, np.empty((len(starts), 4)), np.array([1.0, 0, 0, 0])
    for a, t, th, _, dt in _blocks_with_dt(path, rows, where, period):
        q = quat_mult(carry, quat_scan(rotvec_to_quat(th - bias * dt[:, None])))
        here = (mids >= a) & (mids < a + len(t))
        q_mid[here] = q[mids[here] - a]
        carry = q[-1]
    return quat_to_dcm(q_mid)


def run_header(path):
    """The log's metadata as a :class:`calib.runlog.Run` without samples (its site, its rate)."""
    return Run(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), read_meta(path), source=str(path))


def file_start(path, moving, rows, where, period, site: Site, profile, requirements):
    """Check the rests and the first rest; the start values and ``C_b_n`` at the start.

    :func:`calib.fit.start.start_attitude` on what the rests read chunk by chunk
    give; a MEMS unit's bias and heading from all rests cost two more readings.
    """
    (th, dv, dt), T, turned = _read_rests(path, moving, rows, where, period, profile)
    sanity.check_latitude(site.latitude_rad, where)
    check_first_rest(th, dv, dt, slice(None), site.gravity_mps2, where, requirements)
    return start_attitude(
        (th, dv, dt),
        turned.sum(axis=0) / T.sum(),
        lambda: Rests(
            T, turned / T[:, None], lambda bias: _rest_attitudes(path, rows, where, period, moving, bias)
        ),
        site,
    )


def sequence_motion_file(path, rows, where, period, sequence, detected, t_start):
    """Where a sequence says the run turns, read chunk by chunk, refused unless the gyros turn there.

    As :func:`calib.sequence.motion.sequence_motion` and
    :func:`calib.sequence.motion.check_sequence_matches` in memory.
    """
    tl = timeline(sequence)
    masks = [
        sequence_mask(tl, t, dt, t_start) for _, t, _, _, dt in _blocks_with_dt(path, rows, where, period)
    ]
    moving = grow(np.concatenate(masks))
    turns = detected.copy()  # as calib.sequence.motion.log_turns: noise bursts within a rest do not count
    angles = _turn_angles(path, rows, where, period, detected, _steady_rate(path, rows, where, period))
    for a, b, angle in zip(*runs_of(detected), angles, strict=True):
        if angle < math.radians(MIN_TURN_DEG):
            turns[a:b] = False
    check_sequence_matches(
        sequence, turns, moving, None, where, lambda i: _elapsed(path, rows, where, period, i)
    )
    return moving


def _steady_rate(path, rows, where, period) -> np.ndarray:
    """Per axis, the median of the chunks' median rates (rad/s): the run's rate at rest, as
    :func:`survey` takes it (:func:`calib.sequence.motion.steady_rate` in memory).
    """
    medians = [
        np.median(th / dt[:, None], axis=0) for _, _, th, _, dt in _blocks_with_dt(path, rows, where, period)
    ]
    return np.median(medians, axis=0)


def _turn_angles(path, rows, where, period, moving: np.ndarray, steady: np.ndarray) -> np.ndarray:
    """:func:`calib.sequence.motion.turn_angles` of the whole run, integrated chunk by chunk."""
    starts, _ = runs_of(moving)
    largest, carry = np.zeros(len(starts)), np.zeros((len(starts), 3))
    for a, _, th, _, dt in _blocks_with_dt(path, rows, where, period):
        here = np.flatnonzero(moving[a : a + len(dt)])
        which = np.searchsorted(starts, here + a, side="right") - 1
        for k in np.unique(which):
            rows_k = here[which == k]
            angle = carry[k] + np.cumsum(th[rows_k] - steady * dt[rows_k, None], axis=0)
            largest[k] = max(largest[k], float(np.max(row_norm(angle))))
            carry[k] = angle[-1]
    return largest


def _elapsed(path, rows, where, period, idx: np.ndarray) -> np.ndarray:
    """``np.cumsum(dt)[idx]`` of the whole run, summed chunk by chunk in the same order."""
    out, carry = np.empty(len(idx)), 0.0
    for a, t, _, _, dt in _blocks_with_dt(path, rows, where, period):
        clock = carried_cumsum(dt, carry)
        here = (idx >= a) & (idx < a + len(t))
        out[here] = clock[idx[here] - a]
        carry = float(clock[-1])
    return out


def fit_file(
    path,
    site: Site,
    profile: NoiseProfile,
    sequence=None,
    rows: int = READ_ROWS,
    options: FitOptions = FIT,
):
    """:func:`calib.fit.estimator.fit_run` of a run log read from disk chunk by chunk.

    Returns the same :class:`calib.fit.solution.Fit`; the estimates equal those
    of the in-memory path to rounding (the same passes over the same samples).
    A ``sequence`` marks where the run turns and decides, on a run that
    leaves directions unobserved, what is estimable (none given: nothing
    decides, as a navigation of the whole run would be needed to infer it).

    Parameters
    ----------
    path : str or PathLike
        The log (``.npz`` or ``imu-run/1`` CSV).
    site : Site
    profile : NoiseProfile
    sequence : Sequence, optional
    rows : int
        Samples read at a time.
    options : FitOptions
        What is fitted and how; the streamed loop is the only one here and the
        rate check is not made (``renavigate`` and ``max_rate_rad_s`` are not used).
    """
    where = str(path)
    moving, t_start, period = survey(path, profile, rows, where)
    nominal = nominal_period(read_meta(path), where)
    if sequence is not None:
        moving = sequence_motion_file(path, rows, where, nominal, sequence, moving, t_start)
    start = file_start(path, moving, rows, where, nominal, site, profile, options.requirements)
    grid = default_grid(moving, 1.0 / period)
    del moving
    cuts = chunk_cuts(grid)
    judge = (
        None
        if sequence is None
        else nominal_judge(lambda: sequence, site, profile, options.extras, options.requirements)
    )
    passes = Passes(lambda: aligned(read_chunks(path, rows), cuts, t_start), grid, t_start)
    return fit_intervals(passes, site, profile, start, options, where=where, judge=judge)
