"""The sample clock of a run log: which IMU sample each row is, and what the time column adds.

An IMU samples on its own crystal: every increment covers one nominal period ``1 / sample_rate_hz``.
The time column is written by whatever logged the samples (often a host clock) and only locates
them; it can jitter, and a logger can drop or repeat samples. Here the time column is turned into a
sample count, the jitter is measured against that count, and lost and repeated samples are named.
Pure functions over arrays; :mod:`calib.runlog` applies them when it reads a run. Stamps that
jitter beyond a quarter period (a host's reception times) are counted by the count rule of
:mod:`calib.runlog.countrule`; a polling loop's rows are read at their stamps (:mod:`.polled`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError
from calib.sequence.motion import runs_of

from . import coarse, polled
from .countrule import counted_steps
from .fill import check_stalls_at_rest, fill_dropped

# Steps all within this of whole periods (and none zero) come from the IMU's own clock and are
# counted step by step; a host's reception jitter goes beyond it.
STEP_RULE_FRACTION = 0.25
# A step beyond this many periods (58 days at 200 Hz) is a clock jump, not lost samples.
MAX_STEP_PERIODS = 1e9
# Below this (relative to the period) the time column is uniform up to float rounding
# and is kept exactly as written.
ROUNDING_JITTER = 1e-9
# A time column whose first stamp is beyond this (s; 28 hours) counts from an epoch (UNIX or ROS
# time, 1.7e9 s): there a float64 resolves 2.4e-7 s, 24 ppm of a 100 Hz period, so the run's time
# base is re-based to its first stamp. A log that counts from its start (up to a day) keeps its times.
EPOCH_S = 1e5
# Steps shorter than half the median one in more than this share of the rows: the host receives
# the samples in bursts (a Bluetooth link: eight steps of 11.2 ms, then one of 0.4 ms, every 10 ms
# sample there), not a rare catch-up after a stall; the median step is then no period.
BURST_SHARE = 0.05


@dataclass(frozen=True)
class SampleClock:
    """What the time column says about the samples.

    Attributes
    ----------
    index : numpy.ndarray
        ``(n,)`` int64 sample count of each row from the first (0); a
        duplicated row has the index of the row it repeats.
    period_s : float
        Nominal sample period, s.
    offset_s : float
        Time of sample index 0 on the uniform time base, s (from ``origin_s``).
    rate_error_ppm : float
        How much longer the time column's period is than the nominal one
        (a logger clock running fast or slow against the IMU's), ppm.
    jitter_rms_s, jitter_max_s : float
        RMS and largest absolute deviation of the time column from the
        straight line through it in sample count (offset and rate fitted), s.
    dropped : list of (float, int)
        Each place where samples are missing: the time of the first missing
        sample (one period after the row before the hole) and how many are missing.
    duplicates : list of (float, int)
        Each repeated sample: its time and how many extra copies follow it.
    rule : str
        ``"step"``: every step rounded to whole periods (the IMU's own clock); ``"count"``: the
        rows counted, a gap only where the stamps' lag stays (a host's jittering stamps);
        ``"stamps"``: each row sampled at its stamp (a polling logger, :mod:`calib.runlog.polled`).
    origin_s : float
        The time column's first stamp when it counts from an epoch
        (``|t0| > EPOCH_S``), else 0: every time here (offset, dropped,
        duplicates, the run's time base) counts from it, so per-sample
        intervals stay exact.
    """

    index: np.ndarray
    period_s: float
    offset_s: float
    rate_error_ppm: float
    jitter_rms_s: float
    jitter_max_s: float
    dropped: list
    duplicates: list
    origin_s: float = 0.0
    rule: str = "step"  # how the rows were counted: "step", "count" or "stamps"
    step_stats: tuple = ()  # rule "stamps": the steps' min, max, mean and RMS spread, s
    resolution_s: float = 0.0  # stamps coarser than the period (:mod:`calib.runlog.coarse`): theirs, s
    told: bool = False  # rule "stamps" because the reading was told so (:func:`polled.told_at_stamps`)

    @property
    def uniform(self) -> bool:
        """True when the time column is uniform at the nominal period up to float rounding."""
        drift = abs(self.rate_error_ppm) * 1e-6 * self.period_s * float(self.index[-1])
        return self.rule != "stamps" and self.jitter_max_s + drift <= ROUNDING_JITTER * self.period_s

    def summary(self) -> str:
        """One line for the user: jitter in ms, lost and repeated samples."""
        text = (
            f"clock: time column jitters by {1e3 * self.jitter_rms_s:.3g} ms RMS, "
            f"{1e3 * self.jitter_max_s:.3g} ms max, against the nominal "
            f"{1e3 * self.period_s:.6g} ms period"
        )
        if abs(self.rate_error_ppm) >= 1.0:
            text += f"; its period is {self.rate_error_ppm:+.3g} ppm off the nominal"
        if self.rule == "count" and self.resolution_s:
            text += (
                f"; stamps written to {1e3 * self.resolution_s:.3g} ms, coarser than the period: rows "
                "counted as samples, a gap only where the stamps' lag stays beyond that"
            )
        elif self.rule == "count":
            text += "; rows counted as samples (host stamps), a gap only where the stamps' lag stays"
        if self.uniform:
            text = "clock: time column uniform at the nominal period"
        if self.rule == "stamps":
            text = polled.summary(self.step_stats, self.jitter_rms_s, self.told)
        if self.dropped:
            text += f"; {sum(c for _, c in self.dropped)} dropped sample(s): " + describe(self.dropped)
        if self.duplicates:
            text += f"; {sum(c for _, c in self.duplicates)} duplicated sample(s): " + describe(
                self.duplicates
            )
        if self.origin_s:
            text += (
                "; stamps counting from an epoch or a long-running clock re-based: t = 0 at the first "
                f"stamp, {self.origin_s:.6f} s"
            )
        return text

    def as_dict(self) -> dict:
        """JSON-ready figures (SI)."""
        figures = {
            "period_s": self.period_s,
            "rate_error_ppm": self.rate_error_ppm,
            "jitter_rms_s": self.jitter_rms_s,
            "jitter_max_s": self.jitter_max_s,
            "dropped": [{"time_s": t, "count": c} for t, c in self.dropped],
            "duplicates": [{"time_s": t, "count": c} for t, c in self.duplicates],
            "rule": self.rule,
        }
        # Only where they apply: epoch stamps (the times above count from it), coarse stamps, told.
        figures |= {"origin_s": self.origin_s} if self.origin_s else {}
        figures |= {"resolution_s": self.resolution_s} if self.resolution_s else {}
        figures |= {"told_at_stamps": True} if self.told else {}
        return figures


def describe(events: list, first: int = 3) -> str:
    """``'1 at t = 250.005 s, 2 at t = 750 s'`` for a list of (time, count).

    Past ``first`` events only the first few are named, after their number (a
    100 Hz log read at 200 Hz loses every other sample: tens of thousands of places).
    """
    named = ", ".join(f"{c} at t = {t:.6g} s" for t, c in events[:first])
    if len(events) <= first:
        return named
    return f"in {len(events)} places, the first {first}: {named}, ..."


def sample_clock(
    time_s: np.ndarray, sample_rate_hz: float, duplicate: np.ndarray | None = None
) -> SampleClock:
    """Sample count, jitter, dropped and duplicated samples from a time column.

    Each step between rows that are not duplicates is rounded to whole
    nominal periods: 1 is the next sample, k > 1 means k - 1 samples are
    missing. Rounding step by step (not the absolute time) follows a clock
    that drifts slowly against the IMU's.

    Parameters
    ----------
    time_s : numpy.ndarray
        ``(n,)`` time column, s, increasing (duplicates aside).
    sample_rate_hz : float
        Nominal IMU output rate.
    duplicate : numpy.ndarray of bool, optional
        Rows that repeat the previous one (:func:`calib.runlog.coarse.duplicate_rows`).

    Returns
    -------
    SampleClock

    Raises
    ------
    CalibError
        When a step is not close to a whole number of periods and the rows are no polling
        loop's (``where`` is the row index, to be located by the caller).
    """
    period = 1.0 / sample_rate_hz
    dup = np.zeros(len(time_s), dtype=bool) if duplicate is None else duplicate
    try:
        steps = _whole_steps(time_s, period, dup)  # None: told the rows were sampled at their stamps
    except CalibError:
        if not (
            polled.loop_wanders(time_s, period, dup)
            or polled.delays_kept(time_s, period, dup)
            or polled.rephased(time_s, dup)
        ):
            raise
        steps = None
    loop = steps is None
    if steps is None:
        steps = (~dup[1:]).astype(np.int64)  # each row the next sample
    counted = steps[~dup[1:]]
    with np.errstate(over="ignore", invalid="ignore"):
        off = np.abs(np.diff(time_s)[~dup[1:]] / period - np.rint(np.diff(time_s)[~dup[1:]] / period))
    rule = "count" if counted.size and bool((off > STEP_RULE_FRACTION).any()) else "step"
    resolution = coarse.stamp_resolution(np.diff(time_s)[~dup[1:]] / period)
    if resolution > 1.0:
        rule = "count"  # stamps coarser than the period: the rows are counted at their resolution
    origin = epoch_origin(time_s)
    dropped = [(float(time_s[i] - origin + period), int(steps[i] - 1)) for i in np.flatnonzero(steps > 1)]
    index = np.zeros(len(time_s), dtype=np.int64)
    np.cumsum(steps, out=index[1:])
    del steps
    offset, slope, jitter = _deviation(time_s, index, period, origin)
    if loop or polled.walk_ratio(jitter, period) > polled.WALK_RATIO or polled.wanders(jitter, period):
        rule = "stamps"  # no clock to count by: each row is the next sample
        np.cumsum(~dup[1:], out=index[1:])
        dropped = polled.stalls(time_s, dup, origin)  # a loop that stalled: a hole, as a lost sample is
        offset, slope, jitter = _deviation(time_s, index, period, origin)
    jitter_max = float(np.maximum(jitter.max(), -jitter.min()))
    step_stats: tuple = ()
    if rule == "stamps":
        between = np.diff(time_s)[~dup[1:]]
        step_stats = (float(between.min()), float(between.max()), float(between.mean()), float(between.std()))
    return SampleClock(
        index=index,
        period_s=period,
        offset_s=offset,
        rate_error_ppm=1e6 * slope / period,
        jitter_rms_s=float(np.sqrt(np.mean(np.square(jitter, out=jitter)))),
        jitter_max_s=jitter_max,
        dropped=dropped,
        duplicates=[(float(time_s[a - 1] - origin), int(b - a)) for a, b in zip(*runs_of(dup), strict=True)],
        origin_s=origin,
        rule=rule,
        step_stats=step_stats,
        resolution_s=resolution * period if resolution > 1.0 else 0.0,
        told=polled.told(),
    )


def _deviation(time_s: np.ndarray, index: np.ndarray, period: float, origin: float):
    """Offset, rate trend and each row's deviation from ``offset + index * period`` (s).

    In place: the same arithmetic with three whole-run arrays alive instead of seven.
    """
    residual = index * period
    if origin:  # t - t0 is exact at epoch magnitude, where t - k T would be rounded to 2.4e-7 s
        residual -= time_s - origin
        np.negative(residual, out=residual)
    else:
        np.subtract(time_s, residual, out=residual)
    offset = float(np.mean(residual))
    # A logger clock running at another rate than the IMU's is a trend, not jitter.
    centred = index - index.mean()
    slope = float(centred @ residual / (centred @ centred)) if index[-1] > 0 else 0.0
    residual -= offset
    centred *= slope
    residual -= centred
    return offset, slope, residual


def sampled_at_stamps(time_s: np.ndarray, sample_rate_hz: float) -> bool:
    """Whether a time column's rows were sampled at their stamps (:mod:`calib.runlog.polled`).

    Rows at one time are taken as repeats, as the reader's checks take them. False where the
    column cannot be counted at all: the reader's checks refuse it.
    """
    try:
        repeat = np.concatenate([[False], np.diff(time_s) == 0])
        return sample_clock(time_s, sample_rate_hz, repeat).rule == "stamps"
    except CalibError:
        return False


def epoch_origin(time_s: np.ndarray) -> float:
    """The first stamp of a time column that counts from an epoch (``|t0| > EPOCH_S``), else 0."""
    first = float(time_s[0]) if len(time_s) else 0.0
    return first if abs(first) > EPOCH_S else 0.0


def stamps_rate(time_s: np.ndarray) -> float:
    """The sample rate of a time column: the least-squares slope of the stamps in sample count.

    A first guess of the period (the median step) counts each step in whole
    periods (a dropped sample is a step of 2); the period is then the slope
    of ``t - t[0]`` against that count, fitted over the whole run, so neither
    the rounding of printed stamps nor that of a float64 at epoch magnitude
    (2.4e-7 s at 1.7e9 s) moves it: both average out over the run. Where the
    median step is no period, the span over the rows is the guess: stamps
    coarser than the samples (:func:`calib.runlog.coarse.coarse_stamps`) and
    samples a host receives in bursts (`BURST_SHARE`).

    Parameters
    ----------
    time_s : numpy.ndarray
        ``(n,)`` time column, s, n >= 2.

    Returns
    -------
    float
        Samples per second; NaN when the median step is not positive.
    """
    rel = time_s - time_s[0]  # exact: the stamps are within a factor 2 of each other or small
    step = np.diff(rel)
    first = float(np.median(step))
    if coarse.coarse_stamps(step) or np.mean((step > 0.0) & (step < 0.5 * first)) > BURST_SHARE:
        first = float(rel[-1]) / (len(rel) - 1)  # the rows are the samples: span over rows
    if not first > 0:
        return math.nan
    try:  # the counts of `sample_clock` (the count rule for jittering stamps; told: each row one)
        whole = _whole_steps(rel, first, np.zeros(len(rel), dtype=bool))
        counts = polled.loop_counts(step) if whole is None else whole.astype(float)
    except CalibError:
        counts = np.rint(np.maximum(step, 0.0) / first)
    index = np.zeros(len(rel))
    np.cumsum(counts, out=index[1:])
    if index[-1] == 0:
        return 1.0 / first
    index -= index.mean()
    rel -= rel.mean()
    return float((index @ index) / (index @ rel))


def _periods(time_s: np.ndarray, period: float) -> np.ndarray:
    """Each time step in nominal periods; a clock jump (beyond ``MAX_STEP_PERIODS``) refused."""
    periods = np.diff(time_s)
    with np.errstate(over="ignore"):  # a step of 1e308 s overflows to inf: refused as a jump below
        periods /= period
    huge = np.flatnonzero(periods > MAX_STEP_PERIODS)
    if huge.size:
        i = int(huge[0]) + 1
        raise CalibError(
            f"the time jumps by {time_s[i] - time_s[i - 1]:.6g} s before row {i}, "
            f"{periods[i - 1]:.3g} nominal periods",
            str(i),
            "the time column must locate samples taken at sample_rate_hz; split the log where its "
            "clock jumps",
        )
    return periods


def _whole_steps(time_s: np.ndarray, period: float, dup: np.ndarray) -> np.ndarray | None:
    """Each time step in samples (0 for a duplicate); refuse jumps and shifts that are not whole.
    None when the reading was told the rows were sampled at their stamps (no count is tried).

    Stamps from the IMU's own clock (every step within a quarter period of a
    whole number of periods, none zero) are counted step by step: the step
    rule, exact for a lost sample and for a logger clock that drifts slowly.
    Otherwise the stamps jitter (a host's reception times) and the count rule
    of the module's docstring applies.
    """
    periods = _periods(time_s, period)
    if polled.told():
        return None
    counted = ~dup[1:]
    steps = np.rint(periods).astype(np.int64)
    steps[~counted] = 0
    off = np.abs(periods - steps)
    off[~counted] = 0.0
    if not (off > STEP_RULE_FRACTION).any():
        zero = np.flatnonzero((steps == 0) & counted)
        if zero.size and (periods[zero] > 0.0).any():
            return counted_steps(time_s, periods, counted, period)  # a host's burst: jitter
        if zero.size:  # a clean clock does not stamp two samples alike; stamps coarser than it do
            resolution = coarse.stamp_resolution(periods)
            if resolution > 1.0:
                try:
                    return counted_steps(time_s, periods, counted, period, resolution)
                except CalibError:
                    pass  # the stamps never make room for the extra row: said as a repeat
            i = int(zero[0]) + 1
            raise CalibError(
                f"time_s = {float(time_s[i])!r} follows {float(time_s[i - 1])!r}: two samples at one "
                "time in a time column that otherwise keeps the sample period",
                str(i),
                "samples must be in time order without repeats; sort the log or remove duplicates",
            )
        return steps
    return counted_steps(time_s, periods, counted, period)


def uniform_time(clock: SampleClock, time_s: np.ndarray) -> np.ndarray:
    """The time base of the IMU: ``offset + index * period``; the column itself if already uniform.

    Epoch stamps (``clock.origin_s`` set) are always rebuilt, from their first
    stamp: at 1.7e9 s a float64 rounds each time to 2.4e-7 s, which would put
    24 ppm of noise in every 100 Hz interval.
    """
    if clock.rule == "stamps":  # the samples' own times
        return time_s - clock.origin_s if clock.origin_s else time_s
    if clock.uniform and not clock.dropped and not clock.duplicates and not clock.origin_s:
        return time_s
    return clock.offset_s + clock.index * clock.period_s


def settle(run, allow_gaps: bool, guess_turns: bool = False):
    """The run on the IMU's own time base, with its clock report attached.

    Jitter only: the time column is replaced by ``offset + index / rate``
    (from the first stamp when the column counts from an epoch, `uniform_time`).
    Duplicates and lost samples are refused unless ``allow_gaps``; then the
    extra copies are removed and the lost samples filled (`fill_dropped`).

    Parameters
    ----------
    run : calib.runlog.Run
        A run that passed the reader's checks; its ``clock``, when set, is the
        one they found in its time column (not searched again).
    allow_gaps : bool
    guess_turns : bool
        With ``allow_gaps``: a sample lost amid a turn is put in as a guess and
        marked in ``guessed`` (a hand fit leaves its move out), not refused.

    Returns
    -------
    calib.runlog.Run
        A new run (``clock`` set); the input is not modified.
    """
    period = run.dt_nominal
    clock = run.clock  # found by the reader's checks on this time column, else found here
    if clock is None:
        try:
            repeats = coarse.duplicate_rows(run.time_s, run.dtheta_rad, run.dv_mps, period)
            clock = sample_clock(run.time_s, run.sample_rate_hz, repeats)
        except CalibError as exc:
            raise CalibError(exc.what, f"{run.source}, sample {exc.where}", exc.fix) from None
    if clock.dropped or clock.duplicates:
        if not allow_gaps:
            raise refusal(clock, run.source)
        keep = ~coarse.duplicate_rows(run.time_s, run.dtheta_rad, run.dv_mps, period)
        present = clock.index[keep]
        gimbal = None if run.gimbal_deg is None else run.gimbal_deg[keep]
        dtheta, dv, index = run.dtheta_rad[keep], run.dv_mps[keep], present
        guessed = None
        try:
            if clock.rule == "stamps":  # repeats dropped; a stall's one row kept if at rest, not filled
                time = uniform_time(clock, run.time_s)[keep]
                guessed = check_stalls_at_rest(dtheta, time, [t for t, _ in clock.dropped], guess_turns)
            else:
                dtheta, dv, gimbal, index, guessed = fill_dropped(
                    present, (clock.offset_s, period), dtheta, dv, gimbal, guess_turns
                )
                time = clock.offset_s + index * period
        except CalibError as exc:
            raise CalibError(exc.what, f"{run.source}, {exc.where}", exc.fix) from None
        clipped = run.clipped  # the mask follows its samples; a filled sample is not clipped
        if clipped is not None:
            clipped = np.zeros((len(index), clipped.shape[1]), dtype=bool)
            clipped[present - present[0]] = run.clipped[keep]
        samples = dict(time_s=time, dtheta_rad=dtheta, dv_mps=dv, gimbal_deg=gimbal, clipped=clipped)
        return dataclasses.replace(run, clock=clock, guessed=guessed, **samples)
    return dataclasses.replace(run, time_s=uniform_time(clock, run.time_s), clock=clock)


def refusal(clock: SampleClock, source: str, at_rest: list[str] | None = None) -> CalibError:
    """The error naming every dropped and duplicated sample.

    ``at_rest``, per hole in order: ``"still"``, ``"turning"`` or ``"long"`` (`fill.holes_at_rest`),
    said so that the user knows whether ``allow_gaps`` will do.
    """
    parts, still = [], ""
    if clock.dropped:
        if at_rest is not None and len(at_rest) == len(clock.dropped):
            turning = [t for (t, _), state in zip(clock.dropped, at_rest, strict=True) if state == "turning"]
            long = [t for (t, _), state in zip(clock.dropped, at_rest, strict=True) if state == "long"]
            if not turning and not long:
                still = "; every one where the IMU is still"
            if turning:
                still += (
                    f"; {len(turning)} of them while the IMU turns (first at t = {turning[0]:.6g} s), "
                    "which nothing fills (a hand fit leaves its move out: guess_turns, "
                    "the CLI's --allow-gaps by hand)"
                )
            if long:
                first = f"first at t = {long[0]:.6g} s"
                still += f"; {len(long)} hole(s) too long to fill ({first}): split the log there"
        parts.append(
            f"{sum(c for _, c in clock.dropped)} sample(s) dropped: " + describe(clock.dropped) + still
        )
    if clock.duplicates:
        parts.append(
            f"{sum(c for _, c in clock.duplicates)} sample(s) duplicated: " + describe(clock.duplicates)
        )
    why = (
        ""
        if still.startswith("; every")
        else " (a lost or repeated increment is a step the fit would read as IMU error)"
    )
    return CalibError(
        "; ".join(parts) + why,
        source,
        "read it with allow_gaps (the CLI's --allow-gaps) to fill samples lost at rest and drop exact "
        "duplicates, or repair the log",
    )
