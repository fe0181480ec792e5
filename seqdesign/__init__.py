"""Self-calibration of a three-axis hybrid INS (see README)."""

import os as _os

# The work here is many small matrix products: OpenBLAS threads cost far more
# than they bring (a 90 x 180 @ 180 x 144 product: 0.09 ms on one thread,
# 15 ms on two on the 2-core CI machine). Must be set before numpy loads;
# a user's own setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
