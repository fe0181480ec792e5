"""One navigation pass over a run, chunk by chunk, reduced at once to per-interval quantities.

The estimator's Gauss-Newton iterations need, of the whole run, only what
each observation interval contributes: the navigation velocity at the
interval ends (the observations), the kinematic moments of the compensated
increments (the Jacobian, :func:`calib.nav.jacobian.trajectory_moments`), the
attitude at each interval's middle sample boundary (the Gauss-Markov noise
weights) and, with optional terms, their moments. :func:`navigate_pass`
computes these with the navigation of :mod:`calib.nav.strapdown` written as a
recursion carried across chunks (attitude quaternion, Coriolis-free
velocity, the previous sample for the coning and lever-arm terms), so the
memory it needs is one chunk's, whatever the length of the run, and the
time it takes is linear in the samples.

Chunks are cut at interval ends, so every interval is reduced inside one
chunk. Nothing here is compiled: every per-sample step is a handful of
numpy array operations over a chunk (the quaternion product is a blocked
scan, two full passes instead of ``log2 n``), which keeps the tool
installable from the package registries with no compiler. Its kernels
(:func:`quat_scan`, :func:`earth_fixed_dcm`) are written out for speed but
keep :mod:`calib.nav.transform`'s convention (Hamilton, scalar first) and its
products and sums in the same order (bit-identical).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from calib.model import optional_terms as X
from calib.model.error_model import ErrorModel
from calib.model.optional_terms import OptionalTerms

from .jacobian import N_MOMENTS, ObservationGrid, step_model
from .site import Site
from .strapdown import cross3, sculling_dv
from .transform import dcm_to_rotvec, prefix_product, rotvec_to_quat

CHUNK_SAMPLES = 1 << 14  # measured: 2.5x faster per sample than 1 << 16 (a chunk's temporaries stay in cache)
SCAN_BLOCK = 16  # quaternion scan: sequential inside blocks of 16, then one pass to join them


@dataclass(frozen=True)
class Chunk:
    """Raw samples ``[start, start + n)`` of a run, and the end time of the sample before."""

    start: int
    time_s: np.ndarray  # (n,)
    dtheta_m: np.ndarray  # (n, 3)
    dv_m: np.ndarray  # (n, 3)
    t_before: float  # end of sample start - 1 (for the first chunk: when the run began)


@dataclass(frozen=True)
class Passes:
    """A run read again at every pass, chunk by chunk.

    Parameters
    ----------
    chunks : callable
        ``chunks()`` gives the run again, in order, as :class:`Chunk` values cut at
        interval ends (:func:`chunk_cuts`).
    grid : ObservationGrid
        The observation intervals the pass reduces the run to.
    t0 : float
        When the first sample began (the navigation's time origin).
    """

    chunks: Callable[[], Iterable[Chunk]]
    grid: ObservationGrid
    t0: float


@dataclass(frozen=True)
class Estimate:
    """What a pass compensates the raw increments with, and the attitude it starts from.

    Parameters
    ----------
    values : ndarray, shape (21,)
        The current estimate of the 21 (SI).
    C_b_n0 : ndarray, shape (3, 3)
        Attitude when the run began.
    extras : OptionalTerms
        The optional terms switched on.
    extra_values : ndarray, shape (extras.n,)
        Their current estimate.
    turn : ndarray, shape (n, 3) or None
        The Earth's turn in the body per sample for the time-offset term
        (from the previous pass); None: as seen at ``C_b_n0``. Used only with optional terms.
    gyro_correction : ndarray, shape (K, 3), optional
        A body rate (rad/s) per interval added to the compensated gyro increments:
        the estimator's attitude feedback (:func:`calib.fit.feedback.attitude_feedback`).
    """

    values: np.ndarray
    C_b_n0: np.ndarray
    extras: OptionalTerms = X.NONE
    extra_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    turn: np.ndarray | None = None
    gyro_correction: np.ndarray | None = None


@dataclass(frozen=True)
class PassResult:
    """What one navigation pass leaves per observation interval (SI).

    ``y`` is the navigation velocity at the K + 1 interval ends (index 0 = start),
    ``moments`` (K, N_MOMENTS) those of :func:`calib.nav.jacobian.trajectory_moments`,
    ``C_mid`` (K, 3, 3) the attitude at each interval's middle boundary,
    ``extra`` (K, 6, e) the optional terms' inputs (:func:`calib.nav.jacobian.extra_inputs`)
    and ``turn`` (n, 3) the Earth's turn in the body per sample (only with optional terms).
    """

    y: np.ndarray
    t_bounds: np.ndarray  # (K + 1,) time of each interval end
    moments: np.ndarray | None
    C_mid: np.ndarray
    extra: np.ndarray
    turn: np.ndarray | None


def _quat_mult_soa(p: np.ndarray, q: np.ndarray, out: np.ndarray) -> np.ndarray:
    """:func:`~calib.nav.transform.quat_mult` of quaternions stored component first, ``(4, ...)``, in ``out``.

    The same products and sums in the same order (bit-identical), on contiguous
    component arrays instead of strided columns; ``out`` must not share memory with p, q.
    """
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    np.multiply(pw, qw, out=out[0])
    out[0] -= px * qx
    out[0] -= py * qy
    out[0] -= pz * qz
    np.multiply(pw, qx, out=out[1])
    out[1] += px * qw
    out[1] += py * qz
    out[1] -= pz * qy
    np.multiply(pw, qy, out=out[2])
    out[2] -= px * qz
    out[2] += py * qw
    out[2] += pz * qx
    np.multiply(pw, qz, out=out[3])
    out[3] += px * qy
    out[3] -= py * qx
    out[3] += pz * qw
    return out


def quat_scan(q: np.ndarray) -> np.ndarray:
    """Inclusive prefix products ``q[0] q[1] ... q[k]`` of ``(n, 4)`` quaternions.

    Sequential inside blocks of :data:`SCAN_BLOCK` (vectorised across blocks),
    the block totals by doubling, then each block is multiplied by the product
    of all before it: about two passes over the data, against ``log2 n`` for a
    doubling scan of the whole array. The blocks are held component first,
    ``(4, SCAN_BLOCK, blocks)``, so that every step works on contiguous rows.
    """
    n = len(q)
    if n <= 4 * SCAN_BLOCK:
        return prefix_product(q)
    nb = -(-n // SCAN_BLOCK)
    padded = np.zeros((nb * SCAN_BLOCK, 4))
    padded[:, 0] = 1.0  # identity padding
    padded[:n] = q
    blocks = np.ascontiguousarray(padded.reshape(nb, SCAN_BLOCK, 4).transpose(2, 1, 0))
    step = np.empty((4, nb))
    for k in range(1, SCAN_BLOCK):
        blocks[:, k] = _quat_mult_soa(blocks[:, k - 1], blocks[:, k], step)
    before = prefix_product(np.ascontiguousarray(blocks[:, -1].T))  # product of blocks 0..b
    tail = np.empty((4, SCAN_BLOCK, nb - 1))
    _quat_mult_soa(before[:-1].T[:, None, :], blocks[:, :, 1:], tail)
    blocks[:, :, 1:] = tail
    return blocks.transpose(2, 1, 0).reshape(-1, 4)[:n]


def _cross_axis(axis: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``axis x v`` for a fixed ``axis`` and rows ``v`` (cheaper than np.cross)."""
    out = np.empty_like(v)
    out[:, 0] = axis[1] * v[:, 2] - axis[2] * v[:, 1]
    out[:, 1] = axis[2] * v[:, 0] - axis[0] * v[:, 2]
    out[:, 2] = axis[0] * v[:, 1] - axis[1] * v[:, 0]
    return out


def rotate_about(axis: np.ndarray, angle: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R(angle * axis) v`` for a fixed unit ``axis`` and per-row angles (Rodrigues)."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    v = np.ascontiguousarray(np.broadcast_to(v, (len(angle), 3)))
    return v * c + _cross_axis(axis, v) * s + ((1.0 - c) * (v @ axis)[:, None]) * axis


def earth_fixed_dcm(q_i: np.ndarray, axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Direction cosines of ``q(angle * axis) q_i`` for every row: the ENU attitude from the inertial one.

    The product with the rotation about the fixed ``axis`` and the conversion
    to a matrix (normalised first, as :func:`calib.nav.transform.quat_to_dcm`) in
    one pass over contiguous component arrays, with no ``(n, 4)`` temporaries:
    these matrices are most of a navigation pass's arithmetic.
    """
    c, s = np.cos(0.5 * angle), np.sin(0.5 * angle)
    qw, qx, qy, qz = np.ascontiguousarray(q_i.T)
    rx, ry, rz = s * axis[0], s * axis[1], s * axis[2]
    w = c * qw - rx * qx - ry * qy - rz * qz
    x = c * qx + rx * qw + ry * qz - rz * qy
    y = c * qy - rx * qz + ry * qw + rz * qx
    z = c * qz + rx * qy - ry * qx + rz * qw
    k = 2.0 / (w * w + x * x + y * y + z * z)
    xs, ys, zs = x * k, y * k, z * k
    wx, wy, wz, xx, xy, xz = w * xs, w * ys, w * zs, x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    out = np.empty((len(w), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = 1.0 - (yy + zz), xy - wz, xz + wy
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = xy + wz, 1.0 - (xx + zz), yz - wx
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = xz - wy, yz + wx, 1.0 - (xx + yy)
    return out


def array_chunks(time_s, dtheta_m, dv_m, t_start: float, cuts: np.ndarray):
    """Chunks of in-memory arrays between consecutive sample indices ``cuts`` (views, no copies)."""
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        yield Chunk(
            int(a), time_s[a:b], dtheta_m[a:b], dv_m[a:b], float(t_start if a == 0 else time_s[a - 1])
        )


def chunk_cuts(grid: ObservationGrid, size: int = CHUNK_SAMPLES) -> np.ndarray:
    """Interval ends that split the run into chunks of about ``size`` samples."""
    b = grid.bounds
    keep = np.unique(np.searchsorted(b, np.arange(0, b[-1], size)))
    return np.unique(np.concatenate([b[keep], [b[-1]]]))


class _Carry:
    """The navigation recursion's state between chunks."""

    def __init__(self, C_b_n0: np.ndarray, omega_ie_n: np.ndarray):
        self.C_b_n0, self.omega_ie_n = C_b_n0, omega_ie_n
        self.q = rotvec_to_quat(dcm_to_rotvec(C_b_n0))
        self.w = np.zeros(3)  # Coriolis-free velocity, R(2 W t) v
        self.dtheta: np.ndarray | None = None  # compensated increment of the previous sample (coning)
        self.raw: tuple | None = (
            None  # (dtheta_m, dv_m, dt, turn) of the previous sample (extras' rate steps)
        )
        self._inverses: tuple[np.ndarray, np.ndarray] | None = None

    def inverses(self, model: ErrorModel):
        if self._inverses is None:
            self._inverses = (np.linalg.inv(model.gyro_matrix), np.linalg.inv(model.accel_matrix))
        return self._inverses


def _compensate(ch: Chunk, dt, model: ErrorModel, extras: OptionalTerms, extra_values, turn, carry):
    """Compensated increments of a chunk; with optional terms, the sample before is context."""
    if not extras.n:  # the inverse error matrices once per pass, not a solve per chunk
        Eg_inv, Ea_inv = carry.inverses(model)
        return (
            (ch.dtheta_m - model.gyro_bias * dt[:, None]) @ Eg_inv.T,
            (ch.dv_m - model.accel_bias * dt[:, None]) @ Ea_inv.T,
        )
    if turn is None:  # before the first navigation: the Earth's turn seen at the start attitude
        turn = np.outer(dt, carry.C_b_n0.T @ carry.omega_ie_n)
    ctx = carry.raw is not None
    th_m, dv_m, h, tn = (
        (
            np.vstack([carry.raw[0], ch.dtheta_m]),
            np.vstack([carry.raw[1], ch.dv_m]),
            np.concatenate([[carry.raw[2]], dt]),
            np.vstack([carry.raw[3], turn]),
        )
        if ctx
        else (ch.dtheta_m, ch.dv_m, dt, turn)
    )
    dth = model.compensate(th_m, dv_m, h)[0]
    dvv = X.compensate(
        extras.unpack(extra_values), dth, dv_m, h, lambda x: model.compensate(th_m, x, h)[1], tn
    )
    carry.raw = (ch.dtheta_m[-1], ch.dv_m[-1], dt[-1], turn[-1])
    return (dth[1:], dvv[1:]) if ctx else (dth, dvv)


def _navigate_chunk(dth, dvv, t, lb, site: Site, carry: _Carry):
    """Inertial attitude quaternions at every boundary and velocity at the interval ends of a chunk.

    Only the interval-end sums of the Coriolis-free velocity increments are kept:
    ``w_k = sum_j [R(W t_j) C_b_i,j dv_j + R(2 W t_j) g_n h_j]`` (mid-sample times);
    the gravity part needs per sample only ``cos`` and ``sin`` of ``2 W t_j``.
    """
    w_ie = site.omega_ie_n
    rate, axis = float(np.linalg.norm(w_ie)), w_ie / np.linalg.norm(w_ie)
    prev = np.vstack([dth[:1] if carry.dtheta is None else carry.dtheta[None], dth[:-1]])
    rv = dth + cross3(prev, dth) / 12.0  # coning, as calib.nav.strapdown.coning_rotvec
    q = quat_scan(np.vstack([carry.q[None], rotvec_to_quat(rv)]))
    carry.q, carry.dtheta = q[-1], dth[-1]
    t_mid, dt = 0.5 * (t[1:] + t[:-1]), np.diff(t)
    # R(W t_mid) C_b_i at each sample start, as one quaternion product.
    C_a = earth_fixed_dcm(q[:-1], axis, rate * t_mid)
    dw = np.einsum("nij,nj->ni", C_a, sculling_dv(dth, dvv))
    dw = np.add.reduceat(dw, lb[:-1], axis=0)
    g_n = np.array([0.0, 0.0, -site.gravity_mps2])
    trig = np.stack([np.cos(2 * rate * t_mid) * dt, np.sin(2 * rate * t_mid) * dt], axis=1)
    cs = np.add.reduceat(trig, lb[:-1], axis=0)
    # R(a) g = g cos a + (u x g) sin a + (1 - cos a)(u . g) u, summed with weights h.
    dw += (
        np.outer(cs[:, 0], g_n - (axis @ g_n) * axis)
        + np.outer(cs[:, 1], np.cross(axis, g_n))
        + np.outer(np.add.reduceat(dt, lb[:-1]), (axis @ g_n) * axis)
    )
    w = carry.w + np.cumsum(dw, axis=0)
    carry.w = w[-1]
    y = rotate_about(axis, -2.0 * rate * t[lb[1:]], w)
    return q, y, axis, rate


def _interval_sums(lb: np.ndarray, t: np.ndarray, orders: int):
    """Sparse ``(orders * Kc, m)`` matrix of ``tau^w`` per sample and interval, for the moments."""
    import scipy.sparse as sp  # only with optional terms: importing scipy costs every start 0.1 s

    m, Kc = lb[-1], len(lb) - 1
    idx = np.repeat(np.arange(Kc), np.diff(lb))
    tau = t[lb[1:]][idx] - 0.5 * (t[1:] + t[:-1])
    rows = np.concatenate([idx + w * Kc for w in range(orders)])
    cols = np.tile(np.arange(m), orders)
    data = np.concatenate([tau**w for w in range(orders)])
    return sp.csr_matrix((data, (rows, cols)), shape=(orders * Kc, m))


def _moments(C_mid, dth, dvv, h, lb, t):
    """The N_MOMENTS moments of a chunk's intervals (layout of :func:`calib.nav.jacobian.trajectory_moments`).

    Intervals of equal length are reduced together as one batched product
    ``C^T [inc tau^w, h tau^w]`` (BLAS), since the moments are sums of outer products.
    """
    m, lengths = len(h), np.diff(lb)
    Cf, t_end, t_mid = C_mid.reshape(m, 9), t[lb[1:]], 0.5 * (t[1:] + t[:-1])
    out = np.empty((len(lengths), N_MOMENTS))
    for L in np.unique(lengths):
        ks = np.flatnonzero(lengths == L)
        idx = lb[ks][:, None] + np.arange(L)
        tau = (t_end[ks][:, None] - t_mid[idx])[..., None]
        tau2 = tau * tau
        # [inc, inc tau, inc tau^2, dv, dv tau, h, h tau, h tau^2] written in place: no temporaries.
        right = np.empty(idx.shape + (18,))
        th, dv, hh = right[..., 0:3], right[..., 9:12], right[..., 15:16]
        th[...], dv[...], hh[...] = dth[idx], dvv[idx], h[idx][..., None]
        for col, x, w in ((3, th, tau), (6, th, tau2), (12, dv, tau), (16, hh, tau), (17, hh, tau2)):
            np.multiply(x, w, out=right[..., col : col + x.shape[-1]])
        R = np.matmul(Cf[idx].transpose(0, 2, 1), right)  # (nk, 9, 18)
        n = len(ks)
        # gyro w = 0, 1, 2 then accel w = 0, 1: [27 K (a, i, m), 9 B (a, i)] each
        for col, inc, bias in ((0, 0, 15), (36, 3, 16), (72, 6, 17), (108, 9, 15), (144, 12, 16)):
            out[ks, col : col + 27] = R[:, :, inc : inc + 3].reshape(n, 27)
            out[ks, col + 27 : col + 36] = R[:, :, bias]
    return out


def _extra_moments(C_mid, dth_ctx, dvv_ctx, h_ctx, turn, S3, extras: OptionalTerms, site: Site):
    """Inputs of the optional terms per interval (as :func:`calib.nav.jacobian.extra_inputs`)."""
    m, Kc = len(C_mid), S3.shape[0] // 3
    skip = len(h_ctx) - m
    turn_ctx = np.vstack([turn[:1]] * skip + [turn])
    D = X.dv_sensitivity(extras, dth_ctx, dvv_ctx, h_ctx, turn_ctx)[skip:]
    CD = np.einsum("nai,nic->nac", C_mid, D).reshape(m, -1)
    R = (S3[: 2 * Kc] @ CD).reshape(2, Kc, 3, extras.n)
    mom = np.concatenate([R[0], R[1]], axis=1)  # (Kc, 6, e)
    G = step_model(site).extra_map
    return np.einsum("sm,kmc->ksc", G, mom)


def navigate_pass(run: Passes, site: Site, estimate: Estimate, with_moments: bool = True) -> PassResult:
    """Compensate, navigate and reduce a run to its per-interval quantities in one pass.

    Parameters
    ----------
    run : Passes
        The run, read once more by this pass.
    site : Site
    estimate : Estimate
        What compensates the raw increments, and the attitude the run began at.
    with_moments : bool
        Skip the moments (and the optional terms' inputs) when the Jacobian is not wanted.
    """
    grid, t0, extras, extra_values = run.grid, run.t0, estimate.extras, estimate.extra_values
    turn, gyro_correction = estimate.turn, estimate.gyro_correction
    b, K = grid.bounds, grid.n_intervals
    model, carry = ErrorModel(estimate.values), _Carry(estimate.C_b_n0, site.omega_ie_n)
    y, t_bounds, C_mid = np.zeros((K + 1, 3)), np.full(K + 1, t0), np.empty((K, 3, 3))
    moments, extra = np.empty((K, N_MOMENTS)) if with_moments else None, np.zeros((K, 6, extras.n))
    turn_out = np.empty((b[-1], 3)) if extras.n else None
    for ch in run.chunks():
        m = len(ch.time_s)
        t = np.concatenate([[ch.t_before], ch.time_s]) - t0
        dt = np.diff(t)
        tn = turn[ch.start : ch.start + m] if extras.n and turn is not None else None
        prev_dth = carry.dtheta
        dth, dvv = _compensate(ch, dt, model, extras, extra_values, tn, carry)
        k0, k1 = np.searchsorted(b, [ch.start, ch.start + m])
        lb = b[k0 : k1 + 1] - ch.start
        if gyro_correction is not None:  # the estimator's attitude feedback (a MEMS unit's wander)
            dth = dth + np.repeat(gyro_correction[k0:k1], np.diff(lb), axis=0) * dt[:, None]
        q, y[k0 + 1 : k1 + 1], axis, rate = _navigate_chunk(dth, dvv, t, lb, site, carry)
        t_bounds[k0 + 1 : k1 + 1] = t[lb[1:]] + t0
        mid = (lb[:-1] + lb[1:]) // 2
        C_mid[k0:k1] = earth_fixed_dcm(q[mid], axis, -rate * t[mid])
        if not (with_moments or extras.n):
            continue
        C_b_n = earth_fixed_dcm(q, axis, -rate * t)
        Cm = 0.5 * (C_b_n[1:] + C_b_n[:-1])
        if extras.n:
            assert turn_out is not None  # allocated when extras.n
            turn_out[ch.start : ch.start + m] = X.earth_turn(Cm, site.omega_ie_n, dt)
        if not with_moments:
            continue
        assert moments is not None  # allocated when with_moments
        moments[k0:k1] = _moments(Cm, dth, dvv, dt, lb, t)
        if extras.n:
            assert turn_out is not None  # allocated when extras.n
            S3 = _interval_sums(lb, t, 3)
            ctx = prev_dth is not None
            extra[k0:k1] = _extra_moments(
                Cm,
                np.vstack([prev_dth, dth]) if prev_dth is not None else dth,
                np.vstack([dvv[:1], dvv]) if ctx else dvv,
                np.concatenate([[dt[0]], dt]) if ctx else dt,
                turn_out[ch.start : ch.start + m],
                S3,
                extras,
                site,
            )
    return PassResult(y=y, t_bounds=t_bounds, moments=moments, C_mid=C_mid, extra=extra, turn=turn_out)
