"""A fixed-width counter or tick stamp that rolls over: read as counting on.

Loggers count in registers of fixed width: a 16-bit packet counter (Xsens'
``PacketCounter``) wraps every 65,536 samples, 11 minutes at 100 Hz; a 24-bit sensor
time or a 32-bit microsecond clock (Arduino's ``micros()``, every 71.6 minutes) wraps
too. At the wrap the column steps back by nearly a power of two. A step back is a
rollover when adding that power of two (the smallest above every value the column
holds) gives a forward step no longer than the longest the column takes elsewhere:
the count goes on where it would have. Any other step back (rows out of order, two
logs spliced) is left for the reader to refuse.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

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
    longest = np.max(step[~back])
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
