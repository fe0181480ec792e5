"""A sample counter in place of a time column: time from the count and a stated rate.

Some loggers write no time, only the sample's number (imucal's ``n_samples``).
With the IMU's stated rate (``sample_rate_hz``) the counter is the time base:
the sample counted ``c`` ends its interval at ``(c - c[0] + 1) / rate``. A
counter must be whole numbers and increase (a fixed-width counter's rollover is
counted on, :mod:`calib.runlog.rollover`); a jump (samples the logger
dropped) is refused, or, when gaps are allowed, left in the time base for
:mod:`calib.runlog.clock` to fill as it fills dropped samples.

The converse mistake is caught too: a time column whose steps are all exactly
1 where the rate is not 1 Hz is a counter read as seconds.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from calib.errors import CalibError

from .columns import COUNTER, IMU_LIKE_COUNT
from .rollover import said_rollover

RATE_FIX = (
    "give the IMU's sample rate: sample_rate_hz (the CLI's --sample-rate-hz HZ) or a line "
    "'# sample_rate_hz: 102.4' above the header"
)


def counter_time(
    counter: np.ndarray,
    sample_rate_hz: float | None,
    allow_gaps: bool,
    locate: Callable[[int], str],
    column: str = COUNTER,
) -> np.ndarray:
    """The time (end of each sample's interval, s) of a sample counter at a stated rate.

    Parameters
    ----------
    counter : numpy.ndarray
        ``(n,)`` the counter column as read (floats holding whole numbers).
    sample_rate_hz : float or None
        The stated rate; None is refused.
    allow_gaps : bool
        Keep jumps of the counter (dropped samples) for the clock to fill; else refuse them.
    locate : callable
        Row index (0-based) to the place to name (file, line, column).
    column : str
        The file's name of the counter column, for messages.

    Returns
    -------
    numpy.ndarray
        ``(counter - counter[0] + 1) / sample_rate_hz``.

    Raises
    ------
    CalibError
        Without a rate, or on a counter that is not whole, does not increase or
        (unless ``allow_gaps``) jumps; the message names the row.
    """
    if sample_rate_hz is None:
        raise CalibError(
            f"the column '{column}' is a sample counter, and a counter says no time without the rate",
            locate(0),
            RATE_FIX,
        )
    whole = np.rint(counter)
    bad = np.flatnonzero(whole != counter)
    if bad.size:
        i = int(bad[0])
        raise CalibError(
            f"the sample counter reads {counter[i]!r}, not a whole number",
            locate(i),
            "a counter counts samples in whole numbers; map a time column as time_s, time_ms, ...",
        )
    whole = said_rollover(whole, column, locate)
    step = np.diff(whole)
    back = np.flatnonzero(step <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise CalibError(
            f"the sample counter does not increase: {whole[i]:.0f} follows {whole[i - 1]:.0f}",
            locate(i),
            "samples must be in order without repeats; sort the log or remove the repeated rows",
        )
    jumps = np.flatnonzero(step > 1)
    if jumps.size and not allow_gaps:
        i = int(jumps[0]) + 1
        lost = int(np.sum(step[jumps] - 1))
        raise CalibError(
            f"the sample counter jumps from {whole[i - 1]:.0f} to {whole[i]:.0f}: "
            f"{lost} sample(s) dropped in {jumps.size} place(s)",
            locate(i),
            "repair the log, or read it with allow_gaps (the CLI's --allow-gaps) to fill samples "
            "lost at rest",
        )
    return (whole - whole[0] + 1.0) / float(sample_rate_hz)


def counter_suspect(time_s: np.ndarray, sample_rate_hz: float | None, column: str) -> CalibError | None:
    """The refusal of a time column in seconds that is a sample counter, or None.

    Its steps are all exactly 1 "second" and its stamps whole numbers, while the
    stated rate is not 1 Hz or, without one, the log is long enough
    (``IMU_LIKE_COUNT`` samples) that 1 Hz is no IMU's rate.

    Parameters
    ----------
    time_s : numpy.ndarray
        ``(n,)`` the time column read as seconds.
    sample_rate_hz : float or None
        The stated rate.
    column : str
        The file's name of the column.
    """
    n = len(time_s)
    if n < 2 or time_s[0] != np.rint(time_s[0]) or not np.all(np.diff(time_s) == 1.0):
        return None
    if sample_rate_hz is not None and sample_rate_hz == 1.0:
        return None
    if sample_rate_hz is None and n < IMU_LIKE_COUNT:
        return None
    said = f"at a stated {sample_rate_hz:g} Hz" if sample_rate_hz is not None else f"over {n} samples (1 Hz)"
    return CalibError(
        f"the time column '{column}' steps by exactly 1 s {said}: it looks like a sample counter",
        None,
        f"name it counter (under a column map: {column}=counter) and give the rate "
        "(the CLI's --sample-rate-hz HZ)",
    )
