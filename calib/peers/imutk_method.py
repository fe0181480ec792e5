"""imu_tk's multi-position method (Tedaldi, Pretto, Menegatti, ICRA 2014), written here from its description.

The method calibrates a unit placed by hand in many static poses, without
equipment, in three steps:

1. **Static intervals.** Over a sliding window (101 samples) the variance of
   each accelerometer axis is taken; a sample is static where the norm of that
   variance vector is below a threshold. The threshold is a multiple ``k`` of
   the same norm over the initial static period ``T_init`` (the unit left still
   before the first move). Intervals of at least ``interval_samples`` samples
   are kept, and at least :data:`MIN_INTERVALS` of them are needed.
2. **Accelerometer** (9 parameters, ``f = T_a K_a (a - b_a)``: ``T_a`` unit
   upper triangular with three misalignments, ``K_a`` three scale factors,
   ``b_a`` three biases): least squares on ``g - |f|`` over the static
   samples (the first ``interval_samples`` of each interval, or each
   interval's mean), for every ``k`` in :data:`MULTIPLIERS`; the ``k`` whose
   fit leaves the least cost wins, with its intervals. (``g - |f|`` and
   ``(g^2 - |f|^2) / 2g`` agree to first order in the residual; imu_tk uses the
   former.)
3. **Gyro** (9 parameters, ``w = T_g K_g (r - b_g)``: ``T_g`` unit diagonal
   with six misalignments, ``K_g`` three scale factors): the bias ``b_g`` is
   the mean rate over ``T_init``; then least squares on the gravity direction
   carried by the calibrated gyro from the end of each static interval to the
   start of the next (the rates integrated as piecewise linear in time
   between the samples' stamps), against the direction measured there (the
   calibrated accelerometer's mean over the interval, normalised).

What the method is not: it has no noise model, no sigmas and no
g-sensitivity; the gyro bias is the one seen in ``T_init`` (at that pose's
specific force). The result is a :class:`calib.calibration.correction.Correction`,
``calibrated = M (raw - b)`` with ``M = T K``, in the units of the arrays given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.calibration.correction import Correction, SensorCorrection
from calib.errors import CalibError
from calib.nav.transform import quat_mult, quat_to_dcm, rotvec_to_quat

WINDOW = 101  # samples: imu_tk's variance window
MULTIPLIERS = tuple(range(2, 11))  # threshold multiples of the variance over T_init
MIN_INTERVALS = 12  # static intervals the accelerometer fit needs
INTERVAL_SAMPLES = 100  # a static interval holds at least this many samples
ACC_UPPER = ((0, 1), (0, 2), (1, 2))  # the accelerometer's free misalignments in T_a
RELATIVE_FLOOR = 1e-6  # of the raw reading: the least noise taken for T_init (no sensor is this quiet)
GYRO_OFF = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))  # the gyro's in T_g


@dataclass(frozen=True)
class ImuTkFit:
    """What the method found.

    Attributes
    ----------
    correction : Correction
        ``calibrated = T K (raw - b)`` per sensor.
    multiplier : int
        The threshold multiple chosen.
    start, end : ndarray of int
        The static intervals used, samples ``[start, end)``.
    accel_cost, gyro_cost : float
        Half the sum of squared residuals at the solution (m^2/s^4; unit vectors squared).
    costs : dict of int to float
        The accelerometer fit's cost for each multiple tried (absent: too few intervals).
    """

    correction: Correction
    multiplier: int
    start: np.ndarray
    end: np.ndarray
    accel_cost: float
    gyro_cost: float
    costs: dict


def window_variance_norm(x: np.ndarray, window: int = WINDOW) -> np.ndarray:
    """Norm of the per-axis sample variance over a centred window, per sample (nan near the ends)."""
    n, h = len(x), window // 2
    out = np.full(n, np.nan)
    if n < window:
        return out
    c = np.cumsum(np.vstack([np.zeros(3), x - x.mean(axis=0)]), axis=0)
    c2 = np.cumsum(np.vstack([np.zeros(3), (x - x.mean(axis=0)) ** 2]), axis=0)
    s, s2 = c[window:] - c[:-window], c2[window:] - c2[:-window]
    var = (s2 - s * s / window) / (window - 1)
    out[h : n - h] = np.linalg.norm(np.maximum(var, 0.0), axis=1)
    return out


def static_intervals(
    accel: np.ndarray, threshold: float, window: int = WINDOW
) -> tuple[np.ndarray, np.ndarray]:
    """Stretches ``[start, end)`` where the windowed variance norm stays below ``threshold``."""
    quiet = window_variance_norm(accel, window) < threshold  # nan compares False
    edges = np.diff(np.concatenate([[0], quiet.astype(np.int8), [0]]))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


def _triad(T: np.ndarray, K: np.ndarray, b: np.ndarray, raw_unit: str) -> SensorCorrection:
    return SensorCorrection(T @ np.diag(K), b, np.full((3, 3), np.nan), np.full(3, np.nan), raw_unit)


def _acc_T(p: np.ndarray) -> np.ndarray:
    T = np.eye(3)
    for (i, j), v in zip(ACC_UPPER, p, strict=True):
        T[i, j] = v
    return T


def _gyro_T(p: np.ndarray) -> np.ndarray:
    T = np.eye(3)
    for (i, j), v in zip(GYRO_OFF, p, strict=True):
        T[i, j] = v
    return T


def ellipsoid_start(means: np.ndarray, gravity: float) -> np.ndarray:
    """A start for the accelerometer fit: the axis-aligned ellipsoid through the static means.

    ``sum_j K_j^2 (a_j - b_j)^2 = g^2`` is linear in ``(K_j^2, -2 K_j^2 b_j, const)``
    up to a common factor (the null vector of the design matrix); ``g`` fixes the
    factor. Returns the 9 parameters (misalignments 0, scales, biases).
    """
    A = np.column_stack([means**2, means, np.ones(len(means))])
    scale = np.abs(A).max(axis=0)
    u = np.linalg.svd(A / scale)[2][-1] / scale
    if u[0] < 0:
        u = -u
    P, Q, R = u[:3], u[3:6], u[6]
    if np.any(P <= 0):
        raise CalibError(
            "the static poses do not span an ellipsoid", "imu_tk's method", "give poses of every face"
        )
    b = -Q / (2.0 * P)
    c = gravity**2 / (P @ b**2 - R)
    if not c > 0:
        raise CalibError("the static poses do not span an ellipsoid", "imu_tk's method", "give more poses")
    return np.concatenate([np.zeros(3), np.sqrt(c * P), b])


def fit_accel(samples: np.ndarray, gravity: float, start: np.ndarray):
    """Least squares of ``g - |T K (a - b)|`` over the static samples; returns (params, cost)."""
    from scipy.optimize import least_squares  # lazy: scipy.optimize is slow to import

    def residual(p):
        f = (samples - p[6:]) @ (_acc_T(p[:3]) @ np.diag(p[3:6])).T
        return gravity - np.linalg.norm(f, axis=1)

    x_scale = np.concatenate([np.full(3, 1e-3), np.abs(start[3:6]), np.full(3, 0.01 * gravity / start[3:6])])
    sol = least_squares(residual, start, x_scale=x_scale, method="lm", xtol=1e-12, ftol=1e-12)
    return sol.x, float(sol.cost)


def carried_rotations(rate: np.ndarray, time_s: np.ndarray, spans: list[tuple[int, int]]) -> np.ndarray:
    """Rotation (body at the span's end to body at its start) of rates linear between samples.

    Each step from sample ``i`` to ``i + 1`` turns by the mean of the two rates
    over ``t[i+1] - t[i]`` (second order, as imu_tk's Runge-Kutta step on the same
    linear rate); steps are chained right to left in the body frame.
    """
    lengths = [max(b - a, 0) for a, b in spans]
    m, longest = len(spans), max(max(lengths), 1)
    q = np.zeros((m, 1 << (longest - 1).bit_length(), 4))
    q[..., 0] = 1.0
    for k, (a, b) in enumerate(spans):
        if b > a:
            phi = 0.5 * (rate[a:b] + rate[a + 1 : b + 1]) * np.diff(time_s[a : b + 1])[:, None]
            q[k, : b - a] = rotvec_to_quat(phi)
    while q.shape[1] > 1:  # pairwise products, order kept: q0 q1 q2 q3 -> (q0 q1)(q2 q3)
        q = quat_mult(q[:, 0::2], q[:, 1::2])
    return quat_to_dcm(q[:, 0])


def fit_gyro(rate: np.ndarray, time_s: np.ndarray, ups: np.ndarray, spans, scale0: np.ndarray):
    """Least squares of ``R^T up_r - up_{r+1}`` over the moves; returns (params, cost)."""
    from scipy.optimize import least_squares  # lazy: scipy.optimize is slow to import

    def residual(p):
        w = rate @ (_gyro_T(p[:6]) @ np.diag(p[6:])).T
        R = carried_rotations(w, time_s, spans)
        return (np.einsum("kji,kj->ki", R, ups[:-1]) - ups[1:]).ravel()

    start = np.concatenate([np.zeros(6), scale0])
    x_scale = np.concatenate([np.full(6, 1e-3), np.abs(scale0) * 1e-2])
    sol = least_squares(residual, start, x_scale=x_scale, method="lm", xtol=1e-12, ftol=1e-12)
    return sol.x, float(sol.cost)


@dataclass(frozen=True)
class ImuTkOptions:
    """How imu_tk's method is run: its start, its static intervals, its residuals.

    Parameters
    ----------
    gyro_scale0 : float or ndarray, shape (3,)
        The gyro's nominal scale, rad/s per raw unit: the fit's start.
    interval_samples : int
        The shortest static interval kept, and the samples of each used as residuals.
    use_means : bool
        One residual per interval (its mean) instead of its first ``interval_samples`` samples.
    min_intervals : int
        The fewest static intervals a threshold must give (imu_tk's: :data:`MIN_INTERVALS`).
    """

    gyro_scale0: np.ndarray | float = 1.0
    interval_samples: int = INTERVAL_SAMPLES
    use_means: bool = False
    min_intervals: int = MIN_INTERVALS


IMUTK = ImuTkOptions()  # imu_tk's own settings


def imutk_calibrate(
    time_s: np.ndarray,
    gyro: np.ndarray,
    accel: np.ndarray,
    gravity: float,
    *,
    init: tuple[int, int],
    options: ImuTkOptions = IMUTK,
    raw_units: tuple[str, str] = ("counts", "counts"),
    source: str = "imu_tk's method",
) -> ImuTkFit:
    """Calibrate by imu_tk's method (module docstring).

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample stamps, s.
    gyro, accel : ndarray, shape (n, 3)
        Raw rates and specific force, in any units (counts, rad/s, m/s^2).
    gravity : float
        Local gravity, m/s^2.
    init : (int, int)
        The initial static period ``T_init``, samples ``[start, end)``.
    options : ImuTkOptions
        The gyro's nominal scale (the fit's start), the static intervals kept and the
        residuals taken of them.
    raw_units : (str, str)
        The gyro's and the accelerometer's raw unit, for the correction.
    source : str

    Returns
    -------
    ImuTkFit

    Raises
    ------
    CalibError
        When no threshold gives ``options.min_intervals`` static intervals (default
        :data:`MIN_INTERVALS`).
    """
    interval_samples, min_intervals = options.interval_samples, options.min_intervals
    time_s, gyro, accel = (np.asarray(a, dtype=float) for a in (time_s, gyro, accel))
    a0, a1 = init
    base = float(np.linalg.norm(accel[a0:a1].var(axis=0, ddof=1)))
    # Noise-free data are still to rounding: a floor far below any sensor's noise keeps k * base > 0.
    base = max(base, (RELATIVE_FLOOR * float(np.abs(accel[a0:a1]).max())) ** 2)
    best, costs = None, {}
    for k in MULTIPLIERS:
        start, end = static_intervals(accel, k * base)
        keep = end - start >= interval_samples
        start, end = start[keep], end[keep]
        if len(start) < min_intervals:
            continue
        means = np.array([accel[a:b].mean(axis=0) for a, b in zip(start, end, strict=True)])
        samples = means if options.use_means else np.vstack([accel[a : a + interval_samples] for a in start])
        p, cost = fit_accel(samples, gravity, ellipsoid_start(means, gravity))
        costs[k] = cost
        if best is None or cost < best[1]:
            best = (p, cost, k, start, end)
    if best is None:
        raise CalibError(
            f"no threshold gives {min_intervals} static intervals of {interval_samples} samples",
            source,
            "give a recording with more static poses, each held longer",
        )
    pa, acost, k, start, end = best
    accel_c = _triad(_acc_T(pa[:3]), pa[3:6], pa[6:], raw_units[1])
    bias = gyro[a0:a1].mean(axis=0)
    f = (accel - accel_c.b) @ accel_c.M.T
    ups = np.array([f[a:b].mean(axis=0) for a, b in zip(start, end, strict=True)])
    ups /= np.linalg.norm(ups, axis=1, keepdims=True)
    spans = [(int(e), int(s) - 1) for e, s in zip(end[:-1], start[1:], strict=True)]  # as imu_tk's
    scale0 = np.broadcast_to(np.asarray(options.gyro_scale0, dtype=float), (3,)).copy()
    pg, gcost = fit_gyro(gyro - bias, time_s, ups, spans, scale0)
    gyro_c = _triad(_gyro_T(pg[:6]), pg[6:], bias, raw_units[0])
    return ImuTkFit(Correction(gyro_c, accel_c, None, None, source), k, start, end, acost, gcost, costs)
