"""Before a hand fit: is the log what its labels say? Units, axes and rate, checked by physics.

A unit mistake does not stop a least-squares fit: an accelerometer in g read as
m/s^2 comes out as a scale factor of -90 %, a rate 2.4 % off as a gyro scale
factor of 2.4 %. Two facts need no calibration to check them:

* at rest the accelerometers read gravity: ``|f|`` is ``g`` to a few per cent
  whatever the unit's errors (``g`` read as m/s^2 is 1.0; m/s^2 read as g is 96;
  milli-g read as m/s^2 is 1000; near 0 the logger took gravity out; gyro and
  accelerometer columns swapped put ``g`` in the gyro);
* across a move the gyro's turn carries the gravity direction of the rest before
  onto the one of the rest after. Scaled by 57 (deg/s read as rad/s), 1/57 or a
  thousand (milli-degrees per second),
  with two axes swapped or one sign flipped, it does not;
* after the fit, a rate a few per cent off shows as three gyro scale factors
  alike (`rate_mistake`).

The still stretches are found here from the data alone, thresholds relative to the
recording's own quietest windows, so that a gyro 57 times too large does not hide
them. Each check names the likely mistake; `fixed` undoes it when the user says so.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from calib.errors import CalibError
from calib.nav.strapdown import sample_intervals
from calib.sequence.motion import runs_of

from .force_check import force_mistake, zero_mistake
from .mistake import Mistake
from .rests import moving_mean

WINDOW_S = 0.25
QUIET_FACTOR = 4.0  # a window is quiet within this factor of the recording's quietest tenth
MIN_STILL_S = 0.5
MIN_TILT_DEG = 20.0  # moves that tilt gravity less tell little of the gyro's turn
GOOD_DEG = 5.0  # the gyro's carried gravity within this of the next rest's: no mistake to name
RATE_TOLERANCE = 0.02  # three gyro scale factors alike beyond this: a wrong rate (MEMS: < 1 %, unlike)
DEG = math.pi / 180.0
BLOCK = 4  # increments summed before chaining: a diagnosis needs degrees, not arcseconds


def _windows(x: np.ndarray, dt: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's centred window mean and spread (largest axis) of the rates ``x / dt``."""
    r = x / dt[:, None]
    mean = moving_mean(r, window)
    spread = np.sqrt(np.maximum(moving_mean(r**2, window) - mean**2, 0.0)).max(axis=1)
    return mean, spread


def still_stretches(dtheta: np.ndarray, dv: np.ndarray, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stretches where both triads are within `QUIET_FACTOR` of their quietest tenth, unit-free."""
    period = float(np.median(dt))
    window = max(3, int(round(WINDOW_S / period)))
    _, a_spread = _windows(dv, dt, window)
    g_mean, g_spread = _windows(dtheta, dt, window)
    g_level = np.linalg.norm(g_mean - np.median(g_mean, axis=0), axis=1) + g_spread
    quiet = (a_spread <= QUIET_FACTOR * np.percentile(a_spread, 10) + 1e-12) & (
        g_level <= QUIET_FACTOR * np.percentile(g_level, 10) + 1e-12
    )
    start, end = runs_of(quiet)
    keep = (end - start) * period >= MIN_STILL_S
    return start[keep], end[keep]


def _moves(dtheta, dv, start, end):
    """Gravity directions before and after each move, and the move's increments."""
    u = [dv[a:b].mean(axis=0) for a, b in zip(start, end, strict=True)]
    u = [x / np.linalg.norm(x) for x in u]
    out = []
    for k in range(len(start) - 1):
        tilt = math.degrees(math.acos(np.clip(u[k] @ u[k + 1], -1.0, 1.0)))
        if tilt >= MIN_TILT_DEG:
            out.append((u[k], u[k + 1], dtheta[end[k] : start[k + 1]]))
    return out


def _rodrigues(phi: np.ndarray) -> np.ndarray:
    """Rotation matrices of ``(C, 3)`` rotation vectors."""
    angle = np.linalg.norm(phi, axis=1)
    safe = np.where(angle > 1e-12, angle, 1.0)
    k = phi / safe[:, None]
    K = np.zeros((len(phi), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K = K - K.transpose(0, 2, 1)
    s, c = np.sin(angle)[:, None, None], (1.0 - np.cos(angle))[:, None, None]
    return np.eye(3) + s * K + c * (K @ K)


def carried_misfit(moves, gyros: np.ndarray, bias: np.ndarray, period: float) -> np.ndarray:
    """Per candidate gyro map ``(C, 3, 3)``: the median angle (deg) between each next rest's
    gravity and the one the mapped gyro carries there (increments summed by `BLOCK`).
    """
    errors = []
    for u0, u1, inc in moves:
        inc = inc - bias * period
        n = len(inc) // BLOCK * BLOCK
        blocks = inc[:n].reshape(-1, BLOCK, 3).sum(axis=1)
        if n < len(inc):
            blocks = np.vstack([blocks, inc[n:].sum(axis=0)])
        R = np.broadcast_to(np.eye(3), (len(gyros), 3, 3)).copy()
        for d in blocks:
            R = R @ _rodrigues(gyros @ d)
        pred = np.einsum("cji,j->ci", R, u0)
        errors.append(np.degrees(np.arccos(np.clip(pred @ u1, -1.0, 1.0))))
    return np.median(np.array(errors), axis=0) if errors else np.zeros(len(gyros))


def _signed_permutations():
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            M = np.zeros((3, 3))
            M[np.arange(3), perm] = signs
            yield M


def _describe_axes(M: np.ndarray) -> str:
    """'gyro x and y swapped', 'gyro z sign flipped' for a signed permutation."""
    names = "xyz"
    parts = []
    src = np.argmax(np.abs(M), axis=1)
    swapped = [(i, int(src[i])) for i in range(3) if src[i] != i and i < src[i]]
    for i, j in swapped:
        parts.append(f"{names[i]} and {names[j]} swapped")
    for i in range(3):
        if M[i, src[i]] < 0:
            parts.append(f"{names[i]} sign flipped")
    return ", ".join(parts)


# The factors that put a gyro's unit mistake right, and what each says (the plain reading first).
_GYRO_SCALES = {
    1.0: "",
    DEG: "the gyro is in deg/s and read as rad/s (name its columns gyro_<axis>_dps)",
    1.0 / DEG: "the gyro is in rad/s and read as deg/s (name its columns gyro_<axis>_radps)",
    DEG / 1000.0: "the gyro is in mdeg/s (milli-degrees per second) and read as rad/s (name its "
    "columns gyro_<axis>_mdps)",
    1.0 / 1000.0: "the gyro is in mdeg/s and read as deg/s (name its columns gyro_<axis>_mdps)",
}


def diagnose(run, gravity_mps2: float) -> list[Mistake]:
    """The likely setup mistakes of a hand run, none when its labels hold.

    Parameters
    ----------
    run : calib.runlog.Run
    gravity_mps2 : float
        The site's gravity.

    Returns
    -------
    list of Mistake
    """
    dt = sample_intervals(run.time_s)
    dtheta, dv = run.dtheta_rad, run.dv_mps
    start, end = still_stretches(dtheta, dv, dt)
    if len(start) < 2:
        return []  # the fit's rest finder says what is missing
    rests_f = np.array([dv[a:b].mean(0) / dt[a:b].mean() for a, b in zip(start, end, strict=True)])
    f = float(np.median(np.linalg.norm(rests_f, axis=1)))
    w = np.median(
        [np.linalg.norm(dtheta[a:b].mean(0) / dt[a:b].mean()) for a, b in zip(start, end, strict=True)]
    )
    eye = np.eye(3)
    if abs(w / gravity_mps2 - 1.0) < 0.15 and f < 0.2 * gravity_mps2:
        return [
            Mistake(
                f"the gyro columns read {w:.3g} at rest and the accelerometer's {f:.3g}: "
                "the gyro and accelerometer columns are swapped",
                eye,
                eye,
                swap=True,
            )
        ]
    ratio = f / gravity_mps2
    offset = None
    if abs(ratio - 1.0) <= 0.15:
        offset = zero_mistake(rests_f, gravity_mps2, run.conversion, ZERO_BEYOND_BIAS)
    if offset is not None:  # |f| spread over the poses, about g in the median: a zero offset
        return [offset]
    if abs(ratio - 1.0) > 0.15:
        return [zero_mistake(rests_f, gravity_mps2, run.conversion) or force_mistake(f, gravity_mps2)]
    moves = _moves(dtheta, dv, start, end)
    if len(moves) < 3:
        return []
    period = float(np.median(dt))
    bias = np.median([dtheta[a:b].sum(0) / dt[a:b].sum() for a, b in zip(start, end, strict=True)], axis=0)
    candidates = [(scale, M) for scale in _GYRO_SCALES for M in _signed_permutations()]
    misfits = carried_misfit(moves, np.array([scale * M for scale, M in candidates]), bias, period)
    plain = float(misfits[0])  # scale 1, the identity: the first of each list
    k = int(np.argmin(misfits))
    misfit, (scale, M) = float(misfits[k]), candidates[k]
    if plain > GOOD_DEG and misfit >= 0.5 * plain:
        spliced = _spliced(moves, bias, period)
        if spliced is not None:
            return [spliced]
        # Stamps that jitter are a clock's readings: they cannot be off by a factor. A time
        # uniform to rounding may be a stated rate's (a counter, evenly spaced rows), which can.
        stated = run.clock is None or run.clock.uniform
        off = _time_base(moves, bias, period, plain, stated)
        if off is not None:
            return [off]
        coarse = _coarsely_sampled(moves, bias, period, plain)
        if coarse is not None:
            return [coarse]
    if plain > GOOD_DEG and misfit < 0.5 * plain:
        what = []
        if scale != 1.0:
            what.append(_GYRO_SCALES[scale])
        if not np.array_equal(M, eye):
            what.append(f"the gyro's axes do not match the accelerometer's: {_describe_axes(M)}")
        return [
            Mistake(
                f"the gyro's turn across the moves misses the accelerometer's change of gravity by "
                f"{plain:.3g} deg (median); " + "; ".join(what) + f" would leave {misfit:.2g} deg",
                scale * M,
                eye,
            )
        ]
    return []


# The fit's integration rule is checked to 10 deg a sample (1000 deg/s at 100 Hz) on increments, a
# rate's mean over its interval; a logger printing the rate at that instant, as most do, strays far
# sooner. Turns this coarsely sampled that miss the gravity's change are put down to the sampling.
COARSE_TURN_DEG = 10.0


def _coarsely_sampled(moves, bias: np.ndarray, period: float, plain: float) -> Mistake | None:
    """The turns the log samples too seldom to integrate, when that is what their misfit shows."""
    step = max(float(np.linalg.norm(inc - bias * period, axis=1).max()) for _, _, inc in moves)
    if math.degrees(step) < COARSE_TURN_DEG:
        return None
    eye = np.eye(3)
    return Mistake(
        f"the gyro's turn across the moves misses the accelerometer's change of gravity by {plain:.3g} "
        f"deg (median over {len(moves)} moves), and no unit or axis mistake explains it: at "
        f"{1.0 / period:.3g} Hz the unit turns up to {math.degrees(step):.3g} deg between samples, too "
        "far apart for its rates to be integrated into the turn",
        eye,
        eye,
        cannot_fix="log the gyro at a higher rate (100 Hz or more for a hand's turns), or turn the unit "
        "more slowly",
    )


# A common factor on every turn beyond what a gyro's scale factors (a few per cent at worst)
# or the named unit mistakes explain: the time base (a column's unit, the rate) or a gyro unit off.
TIME_BASE_FACTORS = np.geomspace(0.02, 50.0, 81)
TIME_BASE_SLACK = 1.25


# With |f| about g in the median, an offset this large (in g) or more is a zero left in (a flight
# computer's 0.48 g); below it, a cheap part's own bias (datasheets' zero-g offsets: 50-150 mg),
# which the fit estimates.
ZERO_BEYOND_BIAS = 0.25
RANGE_SLACK = 1.06  # a factor this close to 2, 4, 1/2...: a full-scale range, beyond a gyro's own scale


def _times(factor: float) -> str:
    """``'2 times'``, ``'half'``, ``'a quarter of'``... for a power of two."""
    if factor >= 1.0:
        return f"{factor:g} times"
    return {0.5: "half", 0.25: "a quarter of"}.get(factor, f"1/{1.0 / factor:g} of")


def _time_base(moves, bias: np.ndarray, period: float, plain: float, stated: bool = True) -> Mistake | None:
    """The gyro's turns a common factor ``k`` off the accelerometer's change of gravity, or None.

    ``stated``: the time may come from a stated rate (uniform to rounding), so a power of two
    may be the rate's (InvenSense parts run at 1 or 8 kHz over a divider, Bosch at 25 * 2^n Hz)
    as well as the gyro's full-scale range: both are named and neither is put right.
    """
    factors = TIME_BASE_FACTORS[np.abs(np.log(TIME_BASE_FACTORS)) > math.log(TIME_BASE_SLACK)]
    misfits = carried_misfit(moves, factors[:, None, None] * np.eye(3), bias, period)
    k = int(np.argmin(misfits))
    if misfits[k] >= 0.5 * plain:
        return None
    # The grid's step is 10 %: the factor told to a per cent around its best point.
    finer = factors[k] * np.geomspace(0.9, 1.1, 21)
    fine = carried_misfit(moves, finer[:, None, None] * np.eye(3), bias, period)
    factor, best = float(finer[int(np.argmin(fine))]), float(fine.min())
    rate_hz = 1.0 / period  # as the time column reads
    octave = round(math.log2(factor))
    # Twice or half: a MEMS gyro's full-scale range set to another step than its conversion's
    # (its sensitivity halves as the range doubles).
    ranged = bool(octave) and abs(math.log2(factor) - octave) < math.log2(RANGE_SLACK)
    if ranged and not stated:
        return Mistake(
            f"the gyro's turns across the moves come out {1.0 / factor:.2g} times the change of gravity the "
            f"accelerometer sees (the median miss of {plain:.3g} deg falls to {best:.2g} deg at {factor:.2g} "
            f"times the turns): the gyro's full-scale range is likely {_times(2.0**octave)} the one its "
            "readings were converted at",
            2.0**octave * np.eye(3),
            np.eye(3),
        )
    off = f"{1.0 / factor:.2g} times too long" if factor < 1.0 else f"{factor:.2g} times too short"
    return Mistake(
        f"the gyro's turns across the moves come out {1.0 / factor:.2g} times the change of gravity "
        f"the accelerometer sees (median miss {plain:.3g} deg; {best:.2g} deg at {factor:.2g} times the "
        f"turns): the time base is {off} ({rate_hz:.5g} Hz as read; likely {rate_hz / factor:.3g} Hz), "
        + (
            "or the gyro's unit or full-scale range is off by as much"
            if ranged
            else "or the gyro's unit is off by as much"
        ),
        np.eye(3),
        np.eye(3),
        cannot_fix="check the time column's unit and the sample rate, or the gyro's unit and range",
    )


UNRECORDED_TURN = 0.1  # a move whose gyro turns less than this fraction of its gravity's tilt


def _spliced(moves, bias: np.ndarray, period: float) -> Mistake | None:
    """The log's rests joined without the turns between them, when most moves say so.

    A move that tilts gravity by tens of degrees while the gyro turns by a tenth of that
    or less was not recorded: static sections cut out and joined (a six-position log, a
    pre-cut session). No relabelling of the gyro helps, and the rests cannot be chained.
    """
    tilt = np.array([math.degrees(math.acos(np.clip(u0 @ u1, -1.0, 1.0))) for u0, u1, _ in moves])
    turn = np.array(
        [math.degrees(np.linalg.norm(inc.sum(axis=0) - bias * period * len(inc))) for *_, inc in moves]
    )
    unrecorded = turn < UNRECORDED_TURN * tilt
    if 2 * unrecorded.sum() <= len(moves):
        return None
    tilted, turned = np.median(tilt[unrecorded]), np.median(turn[unrecorded])
    return Mistake(
        f"across {unrecorded.sum()} of {len(moves)} moves gravity turns by {tilted:.0f} deg (median) while "
        f"the gyro turns by {turned:.2g} deg: the log does not hold "
        "the turns between its rests (static sections cut out and joined, or a gyro that reads nothing?)",
        np.eye(3),
        np.eye(3),
        cannot_fix="a calibration by hand chains the rests through the turns the gyro records: log the "
        "poses and the turns between them in one continuous recording (docs/by-hand.md)",
    )


def rate_mistake(
    gyro_scale: np.ndarray, sigma: np.ndarray, period: float, at_stamps: bool = False, counts: bool = False
) -> Mistake | None:
    """A wrong sample rate or gyro conversion, told by a fit's three gyro scale factors being alike.

    The gyro's increments are its rates times the period: a rate given 2.4 % low turns
    every axis 2.4 % too far, which the fit reads as three equal scale factors. A MEMS
    gyro's own scale errors are below a per cent and differ axis to axis. A gyro in raw
    counts converted at the wrong sensitivity (another part's, another full-scale range's)
    does the same; where each sample is timed by its own stamp (``at_stamps``: a polling
    logger's) no rate was given, and that is the likely cause.
    """
    common = float(np.mean(gyro_scale))
    alike = np.ptp(gyro_scale) < 0.5 * abs(common) and np.all(np.abs(gyro_scale) > 3.0 * sigma)
    if abs(common) <= RATE_TOLERANCE or not alike:
        return None
    rate = 1.0 / period
    factor = 1.0 / (1.0 + common)
    shown = ", ".join(f"{100 * s:+.2f} %" for s in gyro_scale)
    conversion = (
        f"the gyro's counts per unit are {factor:.4g} times what they should be (another part's or "
        "full-scale range's sensitivity?)"
        if counts
        else f"the gyro's unit is off by {factor:.4g}"
    )
    if at_stamps:
        return Mistake(
            f"the three gyro scale factors are alike ({shown}) in a log timed by its stamps: " + conversion,
            factor * np.eye(3),
            np.eye(3),
        )
    return Mistake(
        f"the three gyro scale factors are alike ({shown}): the sample rate is likely "
        f"{rate / factor:.5g} Hz, not the {rate:.5g} Hz given, or " + conversion,
        factor * np.eye(3),
        factor * np.eye(3),
        rate_factor=1.0 / factor,
    )


def fixed(run, mistakes: list[Mistake]):
    """The run with each mistake undone (``--fix-units``)."""
    for m in mistakes:
        dtheta, dv = (run.dv_mps, run.dtheta_rad) if m.swap else (run.dtheta_rad, run.dv_mps)
        time_s = run.time_s
        if m.rate_factor != 1.0:
            time_s = run.time_s[0] + (run.time_s - run.time_s[0]) / m.rate_factor
        run = dataclasses.replace(
            run, dtheta_rad=dtheta @ m.gyro.T, dv_mps=dv @ m.accel.T, time_s=time_s, clock=None
        )
    return run


STATIC_TILT_DEG = 5.0  # gravity never leaving its first direction by more: a static log


def static_refusal(run) -> CalibError | None:
    """The refusal of a log whose gravity direction never moves (the gimbal path says the same)."""
    dt = sample_intervals(run.time_s)
    per = max(1, int(round(1.0 / float(np.median(dt)))))  # one-second means
    n = len(dt) // per * per
    if n == 0:
        return None
    f = (run.dv_mps[:n] / dt[:n, None]).reshape(-1, per, 3).mean(axis=1)
    u = f / np.maximum(np.linalg.norm(f, axis=1), 1e-12)[:, None]
    tilt = float(np.degrees(np.arccos(np.clip(u @ u[0], -1.0, 1.0))).max())
    if tilt >= STATIC_TILT_DEG:
        return None
    return CalibError(
        f"the log never turns (gravity within {tilt:.2g} deg of its first direction): it is a static "
        "log; use it with `seqdesign profile fit` for a noise profile",
        run.source,
        "calibrating by hand takes poses with different faces up (docs/by-hand.md)",
    )


def check_setup(run, gravity_mps2: float, fix: bool):
    """Refuse a run whose labels the data contradict, or put it right when ``fix``; the lines said."""
    static = static_refusal(run)
    if static is not None:
        raise static
    mistakes = diagnose(run, gravity_mps2)
    if not mistakes:
        return run, []
    stuck = next((m for m in mistakes if m.cannot_fix), None)
    if stuck is not None:
        raise CalibError(stuck.what, run.source, stuck.cannot_fix)
    if not fix:
        raise CalibError(
            mistakes[0].what,
            run.source,
            "correct the log's labels (or the reading options), or give --fix-units to calibrate it "
            "as the data say",
        )
    return fixed(run, mistakes), [f"fixed: {m.what}" for m in mistakes]


# A hand carries the unit: while it turns the unit fast, the specific force leaves g by metres
# per second squared. A gimbal turns the IMU about its own centre: a lever arm of a decimetre at
# 1 rad/s and 2 rad/s^2 leaves g by 0.2 m/s^2.
CARRIED_MPS2 = 0.5
FAST_TURN = 0.2  # rad/s: the samples judged (a hand's turns pass it; this tool's gimbal flips do not)
# A gimbal flips about one axis at a time: the rate keeps its direction in the body through a flip
# (to the noise's scatter, a degree at this rate for a MEMS gyro). A hand's wrist wobbles the axis.
WOBBLE_DEG = 5.0


def carried_by_hand(run) -> str | None:
    """Why a run looks turned by hand, or None.

    Either its fast turns carry the unit (the 90th percentile of ``| |f| - g |`` over the
    samples turning faster than `FAST_TURN`, against `CARRIED_MPS2`), or their axis wobbles
    (the median over the moves of each move's median angle between the rate and its mean
    direction, against `WOBBLE_DEG`); with at least four still stretches.
    """
    if len(run.time_s) < 3:
        return None
    dt = sample_intervals(run.time_s)
    start, end = still_stretches(run.dtheta_rad, run.dv_mps, dt)
    if len(start) < 4:
        return None
    still = np.zeros(len(dt), dtype=bool)
    for a, b in zip(start, end, strict=True):
        still[a:b] = True
    rate = run.dtheta_rad / dt[:, None]
    fast = np.linalg.norm(rate, axis=1) > FAST_TURN
    if fast.sum() < 50:
        return None
    f = np.linalg.norm(run.dv_mps / dt[:, None], axis=1)
    lurch = float(np.percentile(np.abs(f[fast] - np.median(f[still])), 90))
    wobble = []
    for k in range(len(start) - 1):
        w = rate[end[k] : start[k + 1]][fast[end[k] : start[k + 1]]]
        if len(w) >= 10:
            u = w / np.linalg.norm(w, axis=1)[:, None]
            mean = u.mean(axis=0) / max(float(np.linalg.norm(u.mean(axis=0))), 1e-12)
            wobble.append(math.degrees(float(np.median(np.arccos(np.clip(u @ mean, -1.0, 1.0))))))
    axis = float(np.median(wobble)) if wobble else 0.0
    if lurch < CARRIED_MPS2 and axis < WOBBLE_DEG:
        return None
    return (
        f"between {len(start)} still stretches its fast turns wobble about their axis by {axis:.2g} deg "
        f"(median) and leave g by {lurch:.2g} m/s^2 (90th percentile): the unit was turned by hand, "
        "not flipped about one gimbal axis at a time"
    )
