"""A fixed-width counter or tick stamp that rolls over: read as counting on; a stamp garbled on the way.

Loggers count in registers of fixed width: a 16-bit packet counter (Xsens'
``PacketCounter``) wraps every 65,536 samples, 11 minutes at 100 Hz; a 24-bit sensor
time or a 32-bit microsecond clock (Arduino's ``micros()``, every 71.6 minutes) wraps
too. At the wrap the column steps back by nearly a power of two. A step back is a
rollover when adding that power of two (the smallest above every value the column
holds) gives a forward step no longer than the longest the column takes elsewhere:
the count goes on where it would have (the step after a step back is not counted among the
column's own: a garbled stamp's neighbours step back to the line by as much). Any other step
back (rows out of order, two logs spliced) is left for the reader to refuse.

A serial link that loses a character garbles a stamp (``988842245, 88855245, 988868245``:
a leading digit lost): one stamp out of line with its neighbours, which themselves lie two of
the column's usual steps apart. Named by :func:`mended`, and put midway between its
neighbours when gaps are allowed.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from calib.errors import CalibError

MIN_WIDTH_BITS = 8  # no logger counts in fewer bits
MAX_WIDTH_BITS = 48  # beyond: epoch stamps in ns (61 bits) and the like, which do not roll over


def unwrapped(values: np.ndarray) -> tuple[np.ndarray, int]:
    """The column with its rollovers counted on, and the width in bits it rolls over at.

    Parameters
    ----------
    values : numpy.ndarray
        ``(n,)`` whole numbers (int64, or floats holding them) as the file gives them.

    Returns
    -------
    values : numpy.ndarray
        The same dtype, each rollover's modulus added to every later value; unchanged
        (the same object) when the column does not roll over.
    bits : int
        The counter's width in bits; 0 when it does not roll over.
    """
    if len(values) < 3 or not np.all(np.isfinite(values)):  # the reader refuses what is not finite
        return values, 0
    step = np.diff(values)
    back = step < 0
    if not back.any() or not (step > 0).any() or np.min(values) < 0:
        return values, 0
    bits = max(MIN_WIDTH_BITS, int(np.max(values)).bit_length())
    if bits > MAX_WIDTH_BITS:  # no logger's counter; and 2^bits would overflow int64
        return values, 0
    modulus = 2**bits
    own = ~back & ~np.r_[False, back[:-1]]  # a step back's next step is the garbled stamp's return
    longest = np.max(step[own]) if own.any() else np.max(step[~back])
    on = step[back] + modulus
    if np.any(on <= 0) or np.any(on > longest):
        return values, 0
    carried = np.concatenate([[0], np.cumsum(back)]) * modulus
    return values + carried.astype(values.dtype), bits


def said_rollover(values: np.ndarray, column: str, locate: Callable[[int], str]) -> np.ndarray:
    """:func:`unwrapped`, with a warning naming the column and its first rollover's row (``locate``)."""
    out, bits = unwrapped(values)
    if bits:
        back = np.flatnonzero(np.diff(values) < 0)
        times = f"{len(back)} time{'s' if len(back) > 1 else ''}"
        warnings.warn(
            f"{locate(int(back[0]) + 1)}: the column '{column}' rolls over at 2^{bits} ({times}), "
            f"as a {bits}-bit counter does; read as counting on",
            stacklevel=3,
        )
    return out


GARBLED_SPAN = 3.0  # the neighbours of a garbled stamp lie at most this many usual steps apart


def out_of_line(time: np.ndarray) -> np.ndarray:
    """Rows whose stamp alone is out of line: not between its neighbours, which lie a positive
    span of at most ``GARBLED_SPAN`` median steps apart.
    """
    if len(time) < 3:
        return np.zeros(0, dtype=np.int64)
    usual = float(np.median(np.diff(time)))
    before, here, after = time[:-2], time[1:-1], time[2:]
    span = after - before
    off = ((here < before) | (here > after)) & (span > 0) & (span <= GARBLED_SPAN * usual)
    # Alone: two in a row are rows out of order (a swapped pair), for the reader to refuse.
    alone = off & ~np.r_[False, off[:-1]] & ~np.r_[off[1:], False]
    return np.flatnonzero(alone) + 1 if usual > 0 else np.zeros(0, dtype=np.int64)


def mended(time: np.ndarray, allow_gaps: bool, column: str, locate: Callable[[int], str]) -> np.ndarray:
    """The time column with each garbled stamp (:func:`out_of_line`) put midway between its
    neighbours when ``allow_gaps``, said once; refused naming the first otherwise.
    """
    rows = out_of_line(time)
    if not rows.size:
        return time
    i = int(rows[0])
    seen = f"{time[i]} between {time[i - 1]} and {time[i + 1]}"
    if not allow_gaps:
        raise CalibError(
            f"the stamp {seen} is out of line with its neighbours, which lie "
            f"{(time[i + 1] - time[i - 1]) / float(np.median(np.diff(time))):.2g} usual steps apart: a "
            f"stamp garbled on the way (a serial link's lost character) ({len(rows)} such)",
            locate(i),
            "correct that stamp, or allow_gaps (the CLI's --allow-gaps) puts each such stamp midway "
            "between its neighbours",
        )
    out = time.copy()
    half = (
        (time[rows + 1] - time[rows - 1]) // 2
        if time.dtype.kind == "i"
        else (time[rows + 1] - time[rows - 1]) / 2
    )
    out[rows] = time[rows - 1] + half  # ticks stay whole integers: an epoch's ns are not rounded
    warnings.warn(
        f"{locate(i)}: {len(rows)} stamp(s) of column '{column}' out of line with their neighbours "
        f"(the first {seen}: garbled on the way) put midway between them",
        stacklevel=3,
    )
    return out
