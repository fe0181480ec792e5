"""The matrix exponential, for the noise model's Van Loan integrals.

Scaling and squaring of the degree-13 Padé approximant (Higham, "The scaling
and squaring method for the matrix exponential revisited", SIAM J. Matrix
Anal. Appl. 26, 2005): the matrix is halved ``s`` times until its 1-norm is
below ``THETA_13``, where the approximant's backward error is below the unit
roundoff, and the result squared ``s`` times. Written here rather than taken
from ``scipy.linalg``, whose import alone costs every command that fits a run
0.15 s of CPU time, more than the fit's whole noise model.
"""

from __future__ import annotations

import math

import numpy as np

# Padé [13/13] coefficients of exp and the largest 1-norm at which its backward error
# stays below 2^-53 (Higham 2005, table 2.3).
PADE_13 = (
    64764752532480000.0,
    32382376266240000.0,
    7771770303897600.0,
    1187353796428800.0,
    129060195264000.0,
    10559470521600.0,
    670442572800.0,
    33522128640.0,
    1323241920.0,
    40840800.0,
    960960.0,
    16380.0,
    182.0,
    1.0,
)
THETA_13 = 5.371920351148152


def expm(M: np.ndarray) -> np.ndarray:
    """``exp(M)`` of a square matrix (relative accuracy near the unit roundoff)."""
    M = np.asarray(M, dtype=float)
    norm = float(np.abs(M).sum(axis=0).max()) if M.size else 0.0
    s = max(0, math.ceil(math.log2(norm / THETA_13))) if norm > THETA_13 else 0
    A = M / 2.0**s
    b, eye = PADE_13, np.eye(len(A))
    A2 = A @ A
    A4 = A2 @ A2
    A6 = A4 @ A2
    U = A @ (A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2) + b[7] * A6 + b[5] * A4 + b[3] * A2 + b[1] * eye)
    V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 + b[0] * eye
    E = np.linalg.solve(V - U, V + U)
    for _ in range(s):
        E = E @ E
    return E
