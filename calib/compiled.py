"""The compiled kernels' one convention: how they are compiled and what they are given.

Only sequential recursions are compiled (as pyins compiles its strapdown recursion and
vectorises the rest): a per-interval step of small matrices costs more to call from
numpy than to compute. numba compiles each kernel on its first call (seconds) and keeps
the machine code in its on-disk cache (``__pycache__`` beside the module, or
``NUMBA_CACHE_DIR``), so later processes load it in a fraction of a second.
"""

from __future__ import annotations

import numba
import numpy as np

# cache: compiled once per machine, not per process; nogil: a kernel does not hold the GIL.
kernel = numba.njit(cache=True, nogil=True)


def compiled_arg(a, dtype=float) -> np.ndarray:
    """``a`` as C-ordered, writable, aligned ``dtype``, copied only where it is not so already.

    A kernel is specialised (compiled anew) per layout and read-only flag of its
    arguments: given arrays of one kind, one compiled version serves every caller.
    """
    return np.require(a, dtype, ["C_CONTIGUOUS", "WRITEABLE", "ALIGNED"])
