"""The compiled recursions: what runs interval by interval over small matrices.

Only the sequential recursions are compiled (as pyins compiles its strapdown
recursion and vectorises the rest): one step of 12 x 9 matrices costs more to call
from numpy than to compute. numba compiles each kernel on its first call (seconds)
and keeps the machine code in its on-disk cache (``__pycache__`` beside this module,
or ``NUMBA_CACHE_DIR``); a later process loads it in about half a second, numba's
own start-up included (a second on a loaded machine). That is why this module is
imported only by the paths that need it (the Gauss-Markov noise filter), never by the
white-noise ones.
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


# over 8 parameters: a numba kernel, which takes plain arrays (no objects) to compile once per layout
@kernel
def filter_columns(F, Q, index, turns, turning, X, P, state, E, U):  # pragma: no cover - compiled
    """The recursion of :func:`calib.noise.gm_filter.gram_pass`, mounting by mounting, interval by interval.

    Updates ``P`` (M, s, s) and ``state`` (M, s, c) in place; writes the innovations
    ``E`` and ``S^-1 E`` into ``U`` (both (M, k, 3, c), ``X`` being (k, M, 3, c)). Compiled because each
    interval is a dozen products of 12 x 9 matrices: in numpy their per-call cost, not
    the arithmetic, set the time (one mounting's 30-min run: 0.35 s -> 0.05 s).
    """
    K, M, _, c = X.shape
    s = F.shape[2]
    Fk = np.empty((s + 3, s))
    FP = np.empty((s + 3, s))
    J = np.empty((s + 3, s + 3))
    S_inv = np.empty((3, 3))
    gain = np.empty((s, 3))
    pred = np.empty((s + 3, c))
    for m in range(M):
        for k in range(K):
            u = index[k]
            if turning[k]:
                _turn_biases(F[u], turns[k, m], Fk)
            else:
                Fk[:, :] = F[u]
            _predicted_covariance(Fk, P[m], Q[u], FP, J)
            _inverse_3(J[s:, s:], S_inv)
            _filtered_covariance(J, S_inv, gain, P[m])
            _filter_step(Fk, state[m], X[k, m], S_inv, gain, pred, E[m, k], U[m, k])


# over 8 parameters: a numba kernel, which takes plain arrays (no objects) to compile once per layout
@kernel
def filter_mountings(F, Q, index, turns, turning, X, P, state, E, U):  # pragma: no cover - compiled
    """:func:`filter_columns` with the covariance recursion of all mountings at once.

    The same arithmetic in the same order, to the last bit. ``turns`` (k, 3, 3, M) and
    ``P`` (s, s, M) carry the mountings on their last axis, so that each step of the
    covariance recursion (the one part that does not depend on the columns, about two
    thirds of the filter's time) is one loop over the mountings, which the compiler runs
    several at a time (SIMD): 28 mountings of a 30-min run 1.06 -> 0.50 s. The columns
    then go mounting by mounting (:func:`_filter_step`). With a few mountings the
    short loops cost more than they save: :func:`calib.noise.gm_filter.gram_pass` chooses.
    """
    K, M, _, c = X.shape
    n, s = F.shape[1], F.shape[2]
    Fk = np.empty((n, s, M))
    nonzero = np.empty((n, s), dtype=np.bool_)
    FP = np.empty((n, s, M))
    J = np.empty((n, n, M))
    S_inv = np.empty((3, 3, M))
    gain = np.empty((s, 3, M))
    pred = np.empty((n, c))
    for k in range(K):
        u = index[k]
        _turned_models(F[u], turns[k], turning[k], Fk, nonzero)
        _predicted_covariances(Fk, nonzero, P, Q[u], FP, J)
        for m in range(M):
            _inverse_3(J[s:, s:, m], S_inv[:, :, m])
        _filtered_covariances(J, S_inv, gain, P)
        for m in range(M):
            _filter_step(
                Fk[:, :, m], state[m], X[k, m], S_inv[:, :, m], gain[:, :, m], pred, E[m, k], U[m, k]
            )


@kernel
def _turned_models(Fu, D, turning, Fk, nonzero):  # pragma: no cover - compiled
    """:func:`_turn_biases` for every mounting (``D`` (3, 3, M)), and the entries zero in all of them.

    An entry of a turned bias block is zero for every turn only where its row of the
    block is zero: what :func:`_predicted_covariances` and :func:`_filter_step` skip.
    """
    n, s, M = Fk.shape
    for i in range(n):
        for j in range(s):
            if turning and j >= 3:  # a bias column (phi's come first), turned
                j0 = j - j % 3
                nonzero[i, j] = Fu[i, j0] != 0.0 or Fu[i, j0 + 1] != 0.0 or Fu[i, j0 + 2] != 0.0
                for m in range(M):
                    Fk[i, j, m] = (
                        Fu[i, j0] * D[0, j - j0, m]
                        + Fu[i, j0 + 1] * D[1, j - j0, m]
                        + Fu[i, j0 + 2] * D[2, j - j0, m]
                    )
            else:
                nonzero[i, j] = Fu[i, j] != 0.0
                for m in range(M):
                    Fk[i, j, m] = Fu[i, j]


@kernel
def _predicted_covariances(Fk, nonzero, P, Q, FP, J):  # pragma: no cover - compiled
    """:func:`_predicted_covariance` of every mounting (last axis)."""
    n, s, M = Fk.shape
    for i in range(n):
        for j in range(s):
            for m in range(M):
                FP[i, j, m] = 0.0
        for r in range(s):
            if nonzero[i, r]:
                for j in range(s):
                    for m in range(M):
                        FP[i, j, m] += Fk[i, r, m] * P[r, j, m]
    for i in range(n):
        for j in range(i, n):
            for m in range(M):
                J[i, j, m] = Q[i, j]
            for r in range(s):
                if nonzero[j, r]:
                    for m in range(M):
                        J[i, j, m] += FP[i, r, m] * Fk[j, r, m]
            for m in range(M):
                J[j, i, m] = J[i, j, m]


@kernel
def _filtered_covariances(J, S_inv, gain, P):  # pragma: no cover - compiled
    """:func:`_filtered_covariance` of every mounting (last axis)."""
    s, _, M = P.shape
    for i in range(s):
        for j in range(3):
            for m in range(M):
                gain[i, j, m] = (
                    J[i, s, m] * S_inv[0, j, m]
                    + J[i, s + 1, m] * S_inv[1, j, m]
                    + J[i, s + 2, m] * S_inv[2, j, m]
                )
    for i in range(s):
        for j in range(i, s):
            for m in range(M):
                p_ij = J[i, j, m] - (
                    gain[i, 0, m] * J[j, s, m]
                    + gain[i, 1, m] * J[j, s + 1, m]
                    + gain[i, 2, m] * J[j, s + 2, m]
                )
                p_ji = J[j, i, m] - (
                    gain[j, 0, m] * J[i, s, m]
                    + gain[j, 1, m] * J[i, s + 1, m]
                    + gain[j, 2, m] * J[i, s + 2, m]
                )
                P[i, j, m] = 0.5 * (p_ij + p_ji)
                P[j, i, m] = P[i, j, m]


# The compiled helpers below loop explicitly: in compiled code a matrix product or an
# arithmetic on slices allocates its result each time, which costs more than 3 x 3 arithmetic.


@kernel
def _product_skipping_zeros(A, B, out):  # pragma: no cover - compiled
    """``out = A B``, the exact zeros of ``A`` skipped (the transitions are about half zeros)."""
    for i in range(A.shape[0]):
        for q in range(B.shape[1]):
            out[i, q] = 0.0
        for r in range(A.shape[1]):
            f = A[i, r]
            if f != 0.0:
                for q in range(B.shape[1]):
                    out[i, q] += f * B[r, q]


@kernel
def _turn_biases(Fu, D, Fk):  # pragma: no cover - compiled
    """``Fk`` = the model ``Fu``, its bias coordinates turned by ``D`` first (each 3-vector after phi)."""
    for i in range(Fu.shape[0]):
        for j in range(3):
            Fk[i, j] = Fu[i, j]
        for j0 in range(3, Fu.shape[1], 3):
            for j in range(3):
                Fk[i, j0 + j] = Fu[i, j0] * D[0, j] + Fu[i, j0 + 1] * D[1, j] + Fu[i, j0 + 2] * D[2, j]


@kernel
def _predicted_covariance(Fk, P, Q, FP, J):  # pragma: no cover - compiled
    """``J = Fk P Fk' + Q``, the predicted [state; velocity] covariance; Fk's exact zeros skipped.

    The GM biases' rows of the transition are diagonal blocks: about half its entries are zero.
    """
    n, s = Fk.shape
    _product_skipping_zeros(Fk, P, FP)
    for i in range(n):
        for j in range(i, n):
            acc = Q[i, j]
            for r in range(s):
                f = Fk[j, r]
                if f != 0.0:
                    acc += FP[i, r] * f
            J[i, j] = acc
            J[j, i] = acc


@kernel
def _inverse_3(S, S_inv):  # pragma: no cover - compiled
    """``S_inv`` = the inverse of the symmetric 3 x 3 ``S`` (the innovation covariance), by cofactors."""
    a, b, c = S[0, 0], S[0, 1], S[0, 2]
    d, e, f = S[1, 1], S[1, 2], S[2, 2]
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A + b * B + c * C
    if not det > 0.0:
        raise np.linalg.LinAlgError("innovation covariance is not positive definite")
    S_inv[0, 0], S_inv[0, 1], S_inv[0, 2] = A / det, B / det, C / det
    S_inv[1, 1], S_inv[1, 2] = (a * f - c * c) / det, (b * c - a * e) / det
    S_inv[2, 2] = (a * d - b * b) / det
    S_inv[1, 0], S_inv[2, 0], S_inv[2, 1] = S_inv[0, 1], S_inv[0, 2], S_inv[1, 2]


@kernel
def _filtered_covariance(J, S_inv, gain, P):  # pragma: no cover - compiled
    """The gain ``J_sv S^-1`` and the filtered ``P = J_ss - gain J_sv'``, kept symmetric."""
    s = P.shape[0]
    for i in range(s):
        for j in range(3):
            gain[i, j] = J[i, s] * S_inv[0, j] + J[i, s + 1] * S_inv[1, j] + J[i, s + 2] * S_inv[2, j]
    for i in range(s):
        for j in range(i, s):
            p_ij = J[i, j] - (gain[i, 0] * J[j, s] + gain[i, 1] * J[j, s + 1] + gain[i, 2] * J[j, s + 2])
            p_ji = J[j, i] - (gain[j, 0] * J[i, s] + gain[j, 1] * J[i, s + 1] + gain[j, 2] * J[i, s + 2])
            P[i, j] = 0.5 * (p_ij + p_ji)
            P[j, i] = P[i, j]


@kernel
def _filter_step(Fk, state, x, S_inv, gain, pred, e, w):  # pragma: no cover - compiled
    """The columns' step: predicted, innovation ``e``, whitened ``w = S^-1 e``, filtered state."""
    s = Fk.shape[1]
    c = state.shape[1]
    _product_skipping_zeros(Fk, state, pred)
    for i in range(3):
        for q in range(c):
            e[i, q] = x[i, q] - pred[s + i, q]
    for i in range(3):
        for q in range(c):
            w[i, q] = S_inv[i, 0] * e[0, q] + S_inv[i, 1] * e[1, q] + S_inv[i, 2] * e[2, q]
    for i in range(s):
        for q in range(c):
            state[i, q] = pred[i, q] + gain[i, 0] * e[0, q] + gain[i, 1] * e[1, q] + gain[i, 2] * e[2, q]


@kernel
def propagate_columns(Phis, index, inputs, S, out):  # pragma: no cover - compiled
    """:func:`calib.nav.jacobian.propagate`'s recursion ``S_k = Phi_k S_{k-1} + inputs_k``.

    Updates ``S`` (6, c) in place; fills ``out`` (K + 1, 3, c) with its velocity rows.
    """
    c = S.shape[1]
    nxt = np.empty((6, c))
    for q in range(c):
        for i in range(3):
            out[0, i, q] = S[3 + i, q]
    for k in range(len(index)):
        _product_skipping_zeros(Phis[index[k]], S, nxt)
        for i in range(6):
            for q in range(c):
                S[i, q] = nxt[i, q] + inputs[k, i, q]
        for i in range(3):
            for q in range(c):
                out[k + 1, i, q] = S[3 + i, q]
