"""The count rule: rows of a log whose host stamps jitter, counted as samples.

The rows are consecutive samples, each one period after the one before, unless
the stamps say otherwise *and keep saying it*. A lost sample shifts every later
stamp by a period against the count; a host's reception jitter delays a stamp
and the next ones catch up. So a step of 1.5 periods or more is a gap only where
the stamps' median lag against the count over the next stretch exceeds the one
over the stretch before by a whole number of periods; a jittering stamp that the
next ones make good is jitter. :mod:`calib.runlog.clock` applies it where the
stamps jitter beyond a quarter period.
"""

from __future__ import annotations

import numpy as np

from calib.errors import CalibError

# A persistent shift of the stamps against the count this far from a whole number of
# periods is neither lost samples nor jitter: the stamps do not come from one crystal.
MAX_STEP_FRACTION = 0.35
# The stretch each side of a suspected gap whose median lag decides it (s): long against a
# host's reception jitter (a few periods), short against a clock's drift (ppm of it).
LAG_WINDOW_S = 1.0
LAG_WINDOW_MIN = 25  # rows: a median of fewer would follow the jitter
# The last check: a median lag over two seconds that shifts by this much and stays (half a
# period less a margin for the medians' own scatter under a host's jitter of a period or more)
# is no jitter.
PERSISTENT_SHIFT = 0.45
# Gaps in more than this share of the rows (past the first GAPS_COUNTED) are no crystal's samples
# lost here and there (a lossy radio link drops a few per cent): rows interleaved from two sensors
# put one every other row, and counting them all took tens of seconds.
GAP_SHARE = 0.2
GAPS_COUNTED = 1000


def counted_steps(
    time_s: np.ndarray, periods: np.ndarray, counted: np.ndarray, period: float, resolution: float = 1.0
) -> np.ndarray:
    """The count rule: one sample per row, plus the gaps the stamps' lag keeps.

    Stamps written coarser than the period (``resolution`` periods apart, a 200 Hz IMU
    stamped to 10 ms: 2) place each sample only to that resolution: a step is a gap only
    beyond it, and the lag's medians, which step with the rounding as its phase drifts,
    may move by as much before a shift counts. A lost sample the rounding hides is not
    seen; a longer hole is.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        The stamps, s.
    periods : ndarray, shape (n - 1,)
        Their steps in nominal periods.
    counted : ndarray of bool, shape (n - 1,)
        False for a row that repeats the one before (a duplicate: no sample).
    period : float
        The nominal period, s.

    Returns
    -------
    ndarray of int, shape (n - 1,)
        Samples per step.

    Raises
    ------
    CalibError
        Where the lag shifts and stays by no whole number of periods (``where`` the row).
    """
    steps = counted.astype(np.int64)
    index = np.zeros(len(time_s))
    np.cumsum(steps, out=index[1:])
    lag = (time_s - time_s[0]) / period - index  # in periods; exact: t - t0 at epoch magnitude
    width = max(LAG_WINDOW_MIN, int(round(LAG_WINDOW_S / period)))
    extra = max(resolution, 1.0) - 1.0  # periods the stamps' rounding adds to a step and to the lag
    long_steps = np.flatnonzero((periods >= 1.5 + extra) & counted)
    # A logger clock off the nominal rate is a trend in the lag, not lost samples: the lag's
    # median over the first and the last stretch (jitter aside; printed stamps rounded to ms
    # make the median step no measure of a rate a few ppm off), less the jumps of its holes:
    # a hole of 140 samples in a 600 s log is no clock 2,200 ppm slow.
    if index[-1] > 0:
        ends = min(width, len(lag))
        head, tail = float(np.median(lag[:ends])), float(np.median(lag[-ends:]))
        lag -= (
            (index - index[ends // 2])
            * (tail - head - _jumps(lag, long_steps, width))
            / max(index[-1] - ends + 1, 1.0)
        )
    rows = long_steps + 1  # the first row after each long step
    shifts = _shifts(lag, rows, width)
    moved = -width  # the last row from which the lag was moved: windows near it are taken again
    gaps = 0
    for i, first in enumerate(rows):
        shift = shifts[i]
        if first < moved + width or _tied(shift, (0.5, MAX_STEP_FRACTION)):
            shift = _shift(lag, int(first), width)
        lost = int(np.rint(shift))
        if abs(shift - lost) > MAX_STEP_FRACTION:
            continue  # no whole number of samples: jitter here, or refused by the check below
        if lost > 0:
            moved = _gap_row(lag, periods, int(first), width, lost, 1.5 + extra)
            steps[moved - 1] += lost
            lag[moved:] -= lost
            gaps += 1
            _check_gap_share(gaps, int(first))
    _check_lag_kept(lag, 2 * width, PERSISTENT_SHIFT + extra, periods)
    return steps


def _check_gap_share(gaps: int, row: int) -> None:
    """Refuse stamps that leave a gap in more than GAP_SHARE of their rows up to ``row``."""
    if gaps > max(GAPS_COUNTED, GAP_SHARE * row):
        raise CalibError(
            f"the stamps leave a gap in {gaps} of their first {row} rows: no sample clock with "
            "samples lost here and there counts them",
            str(row),
            "the time column must locate samples taken at sample_rate_hz; check whether the log "
            "mixes sensors or clocks",
        )


def _jumps(lag: np.ndarray, long_steps: np.ndarray, width: int) -> float:
    """The lag's jumps at the long steps, summed (periods): each taken once, then levelled."""
    level = lag.copy()
    total = 0.0
    rows = long_steps + 1
    jumps = _shifts(level, rows, width)
    moved, levelled = -width, 0
    for i, row in enumerate(rows):
        jump = float(jumps[i])
        if row < moved + width or abs(jump) > 0.5 - TIE:
            jump = _shift(level, int(row), width)  # a jump levelled is the one taken alone, to the bit
        if abs(jump) > 0.5:  # a neighbour's window saw it first: levelled there, none here
            level[int(row) :] -= jump
            total += jump
            moved = int(row)
            levelled += 1
            _check_gap_share(levelled, int(row))
    return total


def _shift(lag: np.ndarray, row: int, width: int) -> float:
    """The lag's median over the stretch from ``row`` less that over the stretch before it."""
    return float(np.median(lag[row : row + width]) - np.median(lag[max(0, row - width) : row]))


# A shift taken with the others lies within float rounding (1e-14) of the one taken alone on the
# moved lag; at a decision's edge (stamps rounded to ms put medians on exact halves) it is taken
# alone, so that the count is the one-at-a-time rule's to the last row.
TIE = 1e-9


def _tied(shift: float, edges: tuple[float, ...]) -> bool:
    """Whether a shift's distance from its nearest whole number lies within TIE of an edge."""
    off = abs(shift - round(shift))
    return any(abs(off - edge) < TIE for edge in edges)


SHIFT_BATCH = 4_000_000  # values gathered at once for the medians of many windows (32 MB)


def _shifts(lag: np.ndarray, rows: np.ndarray, width: int) -> np.ndarray:
    """:func:`_shift` at each of ``rows``, the whole windows' medians taken together.

    A host that stamps two samples at a time has a long step every other row: one median
    at a time, a 10-minute log took tens of seconds. A lag moved from a row on keeps the
    shift of a row whose windows both lie on one side: only those within a window of a
    move are taken again, one at a time, by the callers.
    """
    out = np.empty(len(rows))
    whole = (rows >= width) & (rows + width <= len(lag))
    for i in np.flatnonzero(~whole):
        out[i] = _shift(lag, int(rows[i]), width)
    inner = np.flatnonzero(whole)
    offsets = np.arange(width)
    batch = max(1, SHIFT_BATCH // width)
    for k in range(0, len(inner), batch):
        at = rows[inner[k : k + batch]]
        after = np.median(lag[at[:, None] + offsets], axis=1)
        before = np.median(lag[at[:, None] - width + offsets], axis=1)
        out[inner[k : k + batch]] = after - before
    return out


def _gap_row(lag: np.ndarray, periods: np.ndarray, row: int, width: int, lost: int, long: float) -> int:
    """Where, near ``row``, ``lost`` samples went: the long step that splits the lag best.

    The medians find that the lag shifts but not to the row (they are flat over
    half a window); the split of least absolute misfit (a level ``b`` before,
    ``b + lost`` after) among the steps of 1.5 periods or more does.
    """
    lo, hi = max(0, row - width), min(len(lag), row + width)
    base = float(np.median(lag[lo:row]))
    before = np.concatenate([[0.0], np.cumsum(np.abs(lag[lo:hi] - base))])
    after = np.concatenate([[0.0], np.cumsum(np.abs(lag[lo:hi] - base - lost))])
    rows = lo + 1 + np.flatnonzero(periods[lo : hi - 1] >= long)
    rows = rows[rows >= row]  # the candidates before `row` were judged already
    if rows.size == 0:
        return row
    cost = before[rows - lo] + after[-1] - after[rows - lo]
    return int(rows[np.argmin(cost)])


def _check_lag_kept(lag: np.ndarray, width: int, threshold: float, periods: np.ndarray) -> None:
    """Refuse stamps whose median lag against the count shifts and stays (in periods, detrended).

    Left after the gaps were counted, such a shift is a sample the stamps have no
    room for (a repeated time with other data) or a lost one the jitter hid.
    """
    n = len(lag)
    m = min(width, n // 2)
    if m < 2:
        return
    stride = max(1, m // 4)  # medians on a grid: a shift lasts a window, a quarter of one finds it
    m -= m % stride
    starts = np.arange(0, n - m + 1, stride)
    medians = np.array([np.median(lag[j : j + m]) for j in starts]) if len(starts) < 64 else None
    if medians is None:
        view = np.lib.stride_tricks.sliding_window_view(lag, m)[::stride]
        medians = np.median(view, axis=1)
    shift = medians[m // stride :] - medians[: -(m // stride)]
    bad = np.flatnonzero(np.abs(shift) > threshold)
    if bad.size:
        k = int(bad[np.argmax(np.abs(shift[bad]))])
        row = int(starts[k + m // stride])
        size = float(shift[k])
        whole = abs(size - round(size)) <= MAX_STEP_FRACTION
        why = (
            "not a whole number of samples: the stamps do not come from one sample clock"
            if not whole
            else "samples are lost where no step shows it"
            if size > 0
            else "more rows than the stamps have room for (a repeated time with other data, or a "
            "logger whose rate changed)"
        )
        # The shift's own step, where one stands out near it: a logger that paused and took up
        # its samples on another phase is said at its hole, not where the medians first feel it.
        near = slice(max(0, row - m), min(len(periods), row + m))
        step = near.start + int(np.argmax(periods[near])) if periods[near].size else row - 1
        if not whole and periods[step] >= max(1.5, abs(size)):
            raise CalibError(
                f"the time steps by {periods[step]:.2f} periods before row {step + 1}, and the later "
                f"stamps stay {abs(size):.2f} periods {'behind' if size > 0 else 'ahead of'} the count: "
                "not a whole number of samples (a logger that paused and took up its samples on "
                "another phase of its clock)",
                str(step + 1),
                "split the log at that row and calibrate the parts (or cut the part after it)",
            )
        raise CalibError(
            f"from row {row} the time stamps fall {'behind' if size > 0 else 'ahead of'} the sample "
            f"count by {abs(size):.2f} periods and stay there: {why}",
            str(row),
            "check the rate, or whether the log mixes clocks or repeats rows; rows a loop polled "
            "when it came round: at_stamps (the CLI's --at-stamps) reads each at its stamp",
        )
