"""Samples taken at their stamps: a logger that polls the sensor when its loop comes round.

Most logs hold an IMU's samples on its own crystal: the stamps only locate them, and
their deviation from a uniform clock is jitter, bounded (a host's reception delays) or
nil (the IMU's own stamps). A logger that reads the sensor whenever its loop comes
round (an Arduino's ``loop()`` with ``micros()``) takes each sample at its stamp: the
intervals vary from row to row, independently, and the time drifts from any uniform
clock as a random walk. Counting such rows on a uniform clock puts each interval's
error into the increments (a 4-6 ms loop at 200 deg/s: 0.2 deg a sample, about
0.3 deg over a one-second turn).

The two are told apart by how the deviation from the straight line in sample count
grows: over ``m`` rows a random walk's spread grows as ``sqrt(m)``, bounded jitter's
not at all. ``walk_ratio`` is ``Var(e[k+m] - e[k]) / (m Var(e[k+1] - e[k]))``: 1 for a
walk, ``1/m`` for bounded jitter.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import numpy as np

from calib.nav.strapdown import sample_intervals
from calib.runlog.countrule import MAX_STEP_FRACTION

# The reader told that the rows were sampled at their stamps (the CLI's --at-stamps): a loop whose
# stamps no rule here tells from a crystal's under a host's jitter (an RTOS task's steps of 4 and 6
# ms about 5 ms, its stalls in bursts). Set for one reading by `told_at_stamps`; every time column
# read inside it takes the stamps rule, and its clock says it was told.
_TOLD: ContextVar[bool] = ContextVar("at_stamps", default=False)


@contextmanager
def told_at_stamps(told: bool) -> Iterator[None]:
    """Read every time column inside the block at its stamps when ``told`` (:data:`_TOLD`)."""
    token = _TOLD.set(told)
    try:
        yield
    finally:
        _TOLD.reset(token)


def told() -> bool:
    """Whether the reading in progress was told that the rows were sampled at their stamps."""
    return _TOLD.get()


WALK_ROWS = 100  # m: 1/m = 0.01 for jitter, 1 for a walk
WALK_RATIO = 0.25  # above: the stamps walk, the samples were taken at them
# Steps whose spread is below this fraction of the period are a clock's own or a host's that
# follows it (the Xsens recording's steps spread by 0.29 % and walk, yet its moves fit worse
# integrated over them: move noise x1.11 against x1.06 over the nominal period); a polling
# loop's vary by tens of per cent.
MIN_STEP_SPREAD = 0.02
# Steps beyond 4 robust sigmas in at most this share of the rows are rare events (a host's stall
# and the burst that drains it, 1 % of the rows in the test that holds it); in more, they are the
# loop's own second cadence (a phone's sensor hub stamping 20 ms and 21-22 ms steps, 21 % of them)
# and are kept.
RARE_STEPS = 0.05


def walk_ratio(deviation: np.ndarray, period: float, min_spread: float = MIN_STEP_SPREAD) -> float:
    """How the deviation of the stamps from a uniform clock grows with the rows, ``(n,)`` s.

    Returns 0 when the log is too short to tell (fewer than ``3 * WALK_ROWS`` rows) or its
    steps vary by less than ``min_spread`` periods.
    """
    e = np.asarray(deviation, dtype=float)
    m = WALK_ROWS
    if len(e) < 3 * m:
        return 0.0
    one = np.diff(e)
    # Robust to a host's rare stalls and the bursts that drain them (heavy tails in bounded
    # jitter): steps beyond 4 robust sigmas, when rare, are left out before the spreads are compared.
    middle = float(np.median(one))
    sigma = 1.4826 * float(np.median(np.abs(one - middle)))
    if not sigma > min_spread * period:
        return 0.0
    usual = np.abs(one - middle) <= 4.0 * sigma
    if np.mean(~usual) <= RARE_STEPS:
        one = one[usual]
    if len(one) < 3 * m:
        return 0.0
    walk = np.concatenate([[0.0], np.cumsum(one)])
    far = walk[m:] - walk[:-m]
    return float(np.var(far) / (m * np.var(one)))


# Steps spread by less than this (a tenth of a per cent of the period) say nothing of a walk: most
# of them equal (stamps printed coarser than their jitter), the robust spread is not the steps'.
WANDER_MIN_SPREAD = 1e-3


def wanders(deviation: np.ndarray, period: float) -> bool:
    """Whether stamps too even for ``MIN_STEP_SPREAD`` are still a loop's, each row at its stamp.

    A loop whose period drifts (its work slowly changing: a real 154 Hz logger's
    6.42-6.51 ms over four minutes, each step within 24 us of its neighbours) runs periods
    away from any uniform count, which no crystal does under a host's bounded delays: its
    deviation ``(n,)`` s from the row count's straight line exceeds a period RMS and grows
    as a walk does. (The Xsens recording's host stamps walk too, by 0.26 ms RMS.)
    """
    e = np.asarray(deviation, dtype=float)
    if not float(np.sqrt(np.mean(np.square(e)))) > period:
        return False
    return walk_ratio(e, period, min_spread=WANDER_MIN_SPREAD) > WALK_RATIO


def loop_wanders(time_s: np.ndarray, period: float, duplicate: np.ndarray) -> bool:
    """:func:`wanders`, of stamps no sample clock could count (each row taken as the next sample)."""
    t = time_s[~duplicate]
    if len(t) < 3 * WALK_ROWS:
        return False
    count = np.arange(len(t), dtype=np.float64)
    slope, offset = np.polyfit(count, t - t[0], 1)
    return wanders(t - t[0] - (offset + slope * count), period)


# A loop delayed now and then (a slow read every few seconds) and never making the delay up: each
# long step shifts every later stamp by its excess over the loop's cadence, for good. A crystal's
# stamps shift by whole periods (samples lost) or not at all (a host's delay, caught up).
DELAY_STEP = (1.3, 3.0)  # periods: a long step, short of a stall
DELAY_ROWS = 50  # rows each side that tell the cadence before and the shift after
DELAY_MATCH = 0.2  # periods: the shift kept is the step's excess to this
DELAYS_KEPT = 3  # such delays, and most of the long steps, before the rows are taken at their stamps


def _delays(time_s: np.ndarray, duplicate: np.ndarray) -> tuple[int, int]:
    """``(kept, long)``: the long steps that shift the later stamps for good by no whole number of
    periods, and all the long steps (:func:`delays_kept`).
    """
    t = time_s[~duplicate]
    step = np.diff(t)
    w = DELAY_ROWS
    if len(step) < 2 * w + 1:
        return 0, 0
    usual = float(np.median(step))
    if not usual > 0.0:
        return 0, 0
    low, high = DELAY_STEP
    long = np.flatnonzero(step > low * usual)
    kept = 0
    for i in long:
        if i < w or i + w >= len(t) or np.count_nonzero(step[i - w : i + w] > low * usual) > 1:
            continue  # near an end, or among other long steps: no cadence to judge it by
        cadence = (t[i] - t[i - w]) / w
        size = step[i] / cadence
        if size >= high:
            continue
        shift = (t[i + w] - t[i] - w * cadence) / cadence
        if abs(shift - (size - 1.0)) <= DELAY_MATCH and abs(shift - round(shift)) > MAX_STEP_FRACTION:
            kept += 1
    return kept, len(long)


def delays_kept(time_s: np.ndarray, period: float, duplicate: np.ndarray) -> bool:
    """Whether a loop's long steps shift the later stamps for good, by no whole number of periods.

    Each long step (:data:`DELAY_STEP`) with no other within :data:`DELAY_ROWS` rows: the
    cadence ``c`` of the rows before it, and the shift of the stamp ``DELAY_ROWS`` rows after
    it against that cadence, ``(t[i + W] - t[i] - W c) / c``. A host's delay the next rows
    make good shifts nothing, a lost sample a whole period; a polling loop's delay shifts by
    the step's excess over ``c``, which stamps printed to 1 ms at 88 Hz, steps of 11 and 12 ms
    with delays of 18 ms, hide from the spread of the steps that :func:`walk_ratio` judges.
    """
    kept, long = _delays(time_s, duplicate)
    return kept >= DELAYS_KEPT and 2 * kept >= long


# Steps whose robust spread is below this fraction of the period locate each sample to a small
# part of it: a phone's gyro stamped to 0.1 ms at 94 Hz, steps of 10.5 and 10.6 ms (0.5 %).
PRECISE_SPREAD = 0.01


def rephased(time_s: np.ndarray, duplicate: np.ndarray) -> bool:
    """Whether precise stamps shift for good, by no whole number of periods, at every long step.

    A sensor whose sampling took up another phase (a phone's gyro: one step of 1.49 periods
    among steps within 1 % of the period, and every later stamp 0.49 periods on) has samples
    no count of one clock places, and that neither a host's delay (made good) nor a lost
    sample (a whole period) explains. Its stamps, precise, place each at its time: read there,
    the one longer interval is the sample's own.
    """
    kept, long = _delays(time_s, duplicate)
    if not kept or kept != long:
        return False
    step = np.diff(time_s[~duplicate])
    usual = float(np.median(step))
    steady = step[step <= DELAY_STEP[0] * usual]
    spread = 1.4826 * float(np.median(np.abs(steady - np.median(steady))))
    return spread <= PRECISE_SPREAD * usual


STALL_STEPS = 3.0  # a step this many times the median one: the loop stalled (a hole in the record)


def stalls(time_s: np.ndarray, duplicate: np.ndarray, origin: float) -> list:
    """Where a polling loop stalled: (time of the stall's start, rows its interval stands for less one).

    A row after a stall holds one reading over the whole hole; at rest that is the hole's
    increment to its noise, while turning it is not known (:func:`calib.runlog.clock.settle`).
    """
    step = np.diff(time_s)
    usual = float(np.median(step[~duplicate[1:]]))
    long = np.flatnonzero((step > STALL_STEPS * usual) & ~duplicate[1:])
    return [(float(time_s[i] - origin + usual), int(round(step[i] / usual)) - 1) for i in long]


def loop_counts(step: np.ndarray) -> np.ndarray:
    """Samples each step of a loop's stamps stands for: one, and a stall's hole as :func:`stalls`
    counts it, so that a rate from the stamps is the loop's own, not lowered by its stalls.
    """
    moving = step[step > 0]
    if not moving.size:
        return np.zeros(len(step))
    stall = STALL_STEPS * float(np.median(moving))
    holes = step > stall
    usual = float(np.mean(moving[moving <= stall]))  # the loop's mean step
    return np.where(holes, np.rint(step / usual), (step > 0).astype(float))


def summary(step_stats: tuple, deviation_rms: float, was_told: bool = False) -> str:
    """The clock line of a log sampled at its stamps; ``step_stats`` (min, max, mean, RMS), s."""
    low, high, mean, rms = step_stats
    why = (
        "as the reading was told (the CLI's --at-stamps)"
        if was_told
        else "its delays never made up: a polling logger, or a sensor that took up another phase"
    )
    return (
        f"clock: samples taken at their stamps (steps {1e3 * low:.3g}-{1e3 * high:.3g} ms, "
        f"{1e3 * rms:.3g} ms RMS about {1e3 * mean:.4g} ms, the time wandering from a "
        f"uniform clock by {1e3 * deviation_rms:.3g} ms RMS, {why}); "
        "each sample covers its own stamp interval"
    )


def own_intervals(time_s: np.ndarray) -> np.ndarray:
    """``(n, 1)`` each row's own interval, s; a row at its predecessor's time repeats its interval.

    A repeated row then repeats its increment too, and is taken as the repeat it is.
    """
    dt = sample_intervals(time_s)
    repeat = np.flatnonzero(dt == 0)
    if repeat.size:
        held = np.maximum.accumulate(np.where(dt > 0, np.arange(len(dt)), 0))
        dt = dt[held]
    return dt[:, None]


# Rows of several IMUs in one log, one after the other (a flight controller's IMU instances):
# every m-th stamp keeps the sensors' period to this fraction...
INTERLEAVE_REGULAR = 0.05
# ...while the single steps spread beyond this fraction of their median (the sensors' phases)...
INTERLEAVE_IRREGULAR = 0.3
# ...and the specific force's direction differs from a row to the next steadily, by this many
# times more than from a row to the m-th: neighbours are other units (their biases and mounting
# differ by tenths of a degree, which stay; noise and motion average out).
INTERLEAVE_ALTERNATION = 2.0
INTERLEAVE_SMOOTH = 50  # row pairs averaged: a MEMS sample's direction noise falls seven-fold


def interleaved(time_s: np.ndarray, dv: np.ndarray) -> tuple[int, float] | None:
    """``(m, period)`` when the rows look like ``m`` sensors' samples interleaved, else None.

    A host that reads two samples at once stamps them alike too (steps of 0 and two periods,
    every second stamp regular); its rows are one sensor's, whose specific force changes from
    a row to the next no more than over two rows: told apart by the force's direction.
    """
    step = np.diff(time_s)
    if len(step) < 100 or not np.median(step) > 0.0:
        return None
    if np.std(step) < INTERLEAVE_IRREGULAR * np.median(step):
        return None
    norm = np.linalg.norm(dv, axis=1, keepdims=True)
    up = dv / np.where(norm > 0.0, norm, 1.0)
    for m in (2, 3, 4):
        lag = time_s[m:] - time_s[:-m]
        period = float(np.median(lag))
        if not period > 0.0 or np.std(lag) > INTERLEAVE_REGULAR * period:
            continue
        first, second = up[0::m], up[1::m]
        n = min(len(first), len(second)) // 2 * 2
        if n < 2 * INTERLEAVE_SMOOTH:
            continue
        # Another unit's offset stays from row pair to row pair; noise and motion average out.
        # The first unit against itself a period on, in disjoint pairs (a running mean of
        # consecutive differences would telescope to nothing).
        own = first[1:n:2] - first[0:n:2]
        if _steady(second[:n] - first[:n]) > INTERLEAVE_ALTERNATION * _steady(own):
            return m, period
    return None


def _steady(d: np.ndarray) -> float:
    """The median size of ``d``'s running mean over `INTERLEAVE_SMOOTH` rows: what stays."""
    run = np.cumsum(np.vstack([np.zeros((1, d.shape[1])), d]), axis=0)
    mean = (run[INTERLEAVE_SMOOTH:] - run[:-INTERLEAVE_SMOOTH]) / INTERLEAVE_SMOOTH
    return float(np.median(np.linalg.norm(mean, axis=1)))
