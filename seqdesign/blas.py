"""One BLAS thread for the command line, set before numpy loads (import this module first).

The work here is many small matrix products: OpenBLAS threads cost far more than
they bring (a 90 x 180 @ 180 x 144 product: 0.09 ms on one thread, 15 ms on two on
the 2-core machine). This is the CLI's choice for its own process (and the worker
processes it starts, which inherit the environment); importing the library changes
nothing. A user's own setting wins.
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
