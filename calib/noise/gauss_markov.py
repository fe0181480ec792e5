"""First-order Gauss-Markov (GM) bias instability: exact sampled simulation.

A GM bias obeys ``b' = -b / tau + w`` with white ``w`` of PSD ``2 sigma^2 / tau``;
stationary, it has variance ``sigma^2`` and autocorrelation
``sigma^2 exp(-|lag| / tau)``. Sampled, it is exactly the AR(1) recursion::

    b_k = a_k b_{k-1} + sigma sqrt(1 - a_k^2) w_k,   a_k = exp(-dt_k / tau),

with ``w_k ~ N(0, 1)``, started from the stationary ``b_0 ~ N(0, sigma^2)``.
"""

from __future__ import annotations

import numpy as np

# Per block of the non-uniform recursion, the decay exp(-t / tau) spans at most
# exp(-_BLOCK_DECAY): the rescaled sum then stays far from overflow and loses
# nothing to rounding (relative error ~ 1e-16 of the current value).
_BLOCK_DECAY = 30.0


def gauss_markov(n: int, dt: np.ndarray, sigma: float, tau: float, rng: np.random.Generator) -> np.ndarray:
    """Per-sample values of three independent stationary GM processes.

    Parameters
    ----------
    n : int
        Number of samples.
    dt : ndarray, shape (n,)
        Sample lengths, s (> 0). ``dt[k]`` decorrelates sample ``k`` from
        sample ``k - 1``; ``dt[0]`` is not used (``b_0`` is stationary).
    sigma : float
        Steady-state 1-sigma, SI (rad/s or m/s^2). 0 gives zeros and draws
        nothing from ``rng`` (GM off leaves the caller's random stream as is).
    tau : float
        Correlation time, s (> 0 when ``sigma > 0``).
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (n, 3)
        The bias of each sample (held constant over the sample: the caller
        adds ``b * dt`` to the increments).
    """
    dt = np.asarray(dt, dtype=float)
    if dt.shape != (n,):
        raise ValueError(f"dt must have shape ({n},), got {dt.shape}")
    if not (np.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"sigma must be finite and >= 0, got {sigma!r}")
    if sigma == 0 or n == 0:
        return np.zeros((n, 3))
    if not (np.isfinite(tau) and tau > 0):
        raise ValueError(f"tau must be finite and > 0, got {tau!r}")
    if not np.all(dt[1:] > 0):
        raise ValueError("dt must be > 0")
    w = rng.standard_normal((n, 3))
    a = np.exp(-dt[1:] / tau)
    u = sigma * np.sqrt(-np.expm1(-2.0 * dt[1:] / tau))[:, None] * w[1:]  # 1 - a^2 without cancellation
    b0 = sigma * w[0]
    out = np.empty((n, 3))
    out[0] = b0
    if n == 1:
        return out
    if np.all(a == a[0]):  # uniform sampling: a linear filter with constant coefficient
        from scipy.signal import lfilter  # lazy: importing scipy.signal costs 0.5 s per CLI start

        out[1:] = lfilter([1.0], [1.0, -a[0]], u, axis=0, zi=(a[0] * b0)[None, :])[0]
    else:
        out[1:] = _varying_ar1(a, u, b0)
    return out


def _varying_ar1(a: np.ndarray, u: np.ndarray, b0: np.ndarray) -> np.ndarray:
    """``b_k = a_k b_{k-1} + u_k`` (k = 1..m) in closed form, block by block.

    Within a block, with ``P_k = a_1 ... a_k``: ``b_k = P_k (b_0 + sum_j u_j / P_j)``.
    Blocks keep ``P`` above ``exp(-_BLOCK_DECAY)`` so ``1 / P`` cannot overflow.
    """
    log_a = np.log(a)
    cum = np.cumsum(log_a)
    out = np.empty_like(u)
    start, carry = 0, b0
    while start < len(a):
        base = cum[start - 1] if start else 0.0
        stop = start + max(1, int(np.searchsorted(-(cum[start:] - base), _BLOCK_DECAY, side="right")))
        P = np.exp(cum[start:stop] - base)[:, None]
        out[start:stop] = P * (carry + np.cumsum(u[start:stop] / P, axis=0))
        start, carry = stop, out[stop - 1]
    return out
