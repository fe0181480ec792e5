"""Rotations, direction names and the gimbal decomposition of the conventions.

Attitude is the DCM ``C_b_n`` (columns = body axes written in ENU). A flip
about a body axis is a right-multiplication ``C_new = C_old @ rot_axis(...)``.

Quaternions are Hamilton, **scalar first**, ``(w, x, y, z)``, in ``(..., 4)``
arrays: the one convention of the package (:func:`quat_mult`,
:func:`rotvec_to_quat`, :func:`quat_to_dcm`, :func:`prefix_product`; the
blocked scan kernels of :mod:`calib.nav.chunk_pass` use it too).
"""

from __future__ import annotations

import numpy as np

from calib.errors import CalibError

AXES = "XYZ"
DIRECTIONS = {
    "east": (1.0, 0.0, 0.0),
    "west": (-1.0, 0.0, 0.0),
    "north": (0.0, 1.0, 0.0),
    "south": (0.0, -1.0, 0.0),
    "up": (0.0, 0.0, 1.0),
    "down": (0.0, 0.0, -1.0),
}


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``[v x]`` of a 3-vector (or ``(..., 3)`` array)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def axis_index(axis: str) -> int:
    """Index 0, 1, 2 of a body axis name ``X``, ``Y`` or ``Z``."""
    return AXES.index(axis.upper())


def rot_axis(axis: int, angle_rad: np.ndarray | float) -> np.ndarray:
    """Right-hand rotation matrix about coordinate axis ``axis`` (0, 1, 2).

    ``angle_rad`` may be an array; the result then has shape ``(..., 3, 3)``.
    """
    a = np.asarray(angle_rad, dtype=float)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(a.shape + (3, 3))
    i, j, k = axis, (axis + 1) % 3, (axis + 2) % 3
    out[..., i, i] = 1.0
    out[..., j, j] = c
    out[..., k, k] = c
    out[..., j, k] = -s
    out[..., k, j] = s
    return out


def rotvec_to_dcm(rotvec: np.ndarray) -> np.ndarray:
    """``exp([rotvec x])`` for a rotation vector or ``(n, 3)`` array of them.

    Through the unit quaternion ``(cos a/2, sin(a/2) u)``, orthonormal to
    rounding for any angle. Written with numpy rather than
    ``scipy.spatial.transform``, whose import costs every CLI start 0.1 s.
    """
    v = np.asarray(rotvec, dtype=float)
    angle = np.linalg.norm(v, axis=-1)
    small = angle <= 1e-3
    a2 = angle * angle
    # sin(a/2)/a by its Taylor series near 0, where the quotient loses digits.
    scale = np.where(
        small, 0.5 - a2 / 48.0 + a2 * a2 / 3840.0, np.sin(0.5 * angle) / np.where(small, 1.0, angle)
    )
    w = np.cos(0.5 * angle)
    x, y, z = (v[..., i] * scale for i in range(3))
    out = np.empty(v.shape[:-1] + (3, 3))
    out[..., 0, 0] = w * w + x * x - y * y - z * z
    out[..., 0, 1] = 2.0 * (x * y - z * w)
    out[..., 0, 2] = 2.0 * (x * z + y * w)
    out[..., 1, 0] = 2.0 * (x * y + z * w)
    out[..., 1, 1] = w * w - x * x + y * y - z * z
    out[..., 1, 2] = 2.0 * (y * z - x * w)
    out[..., 2, 0] = 2.0 * (x * z - y * w)
    out[..., 2, 1] = 2.0 * (y * z + x * w)
    out[..., 2, 2] = w * w - x * x - y * y + z * z
    return out


def quat_mult(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product of ``(..., 4)`` quaternions, scalar first."""
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[..., 0] = pw * qw - px * qx - py * qy - pz * qz
    out[..., 1] = pw * qx + px * qw + py * qz - pz * qy
    out[..., 2] = pw * qy - px * qz + py * qw + pz * qx
    out[..., 3] = pw * qz + px * qy - py * qx + pz * qw
    return out


def rotvec_to_quat(phi: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)``, scalar first, of rotation vectors ``(..., 3)``."""
    angle = np.sqrt(np.einsum("...i,...i->...", phi, phi))
    # sin(a/2)/a written with numpy's sinc to stay exact at a = 0.
    k = 0.5 * np.sinc(angle / (2.0 * np.pi))
    return np.concatenate([np.cos(0.5 * angle)[..., None], k[..., None] * phi], axis=-1)


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """Direction cosines of quaternions ``(..., 4)`` (normalised first)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def prefix_product(q: np.ndarray) -> np.ndarray:
    """Inclusive prefix products ``q[0] q[1] ... q[k]`` (Hillis-Steele scan, log2 n passes)."""
    out = q.copy()
    d = 1
    n = len(out)
    while d < n:
        out[d:] = quat_mult(out[:-d], out[d:])
        d *= 2
    return out


def _dcm_to_quat(C: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(w, x, y, z)`` of ``(n, 3, 3)`` rotation matrices.

    From the largest of the trace and the diagonal (Shepperd's choice), so
    no component is found by dividing by a small one.
    """
    trace = C[:, 0, 0] + C[:, 1, 1] + C[:, 2, 2]
    choice = np.argmax(np.stack([C[:, 0, 0], C[:, 1, 1], C[:, 2, 2], trace], axis=1), axis=1)
    q = np.empty((len(C), 4))
    for i in range(3):
        rows = choice == i
        j, k = (i + 1) % 3, (i + 2) % 3
        M = C[rows]
        q[rows, 1 + i] = 1.0 - trace[rows] + 2.0 * M[:, i, i]
        q[rows, 1 + j] = M[:, j, i] + M[:, i, j]
        q[rows, 1 + k] = M[:, k, i] + M[:, i, k]
        q[rows, 0] = M[:, k, j] - M[:, j, k]
    rows = choice == 3
    M = C[rows]
    q[rows, 1] = M[:, 2, 1] - M[:, 1, 2]
    q[rows, 2] = M[:, 0, 2] - M[:, 2, 0]
    q[rows, 3] = M[:, 1, 0] - M[:, 0, 1]
    q[rows, 0] = 1.0 + trace[rows]
    # The norm sums x, y, z, then w: the order these rotation vectors were always computed in.
    return q / np.linalg.norm(q[:, [1, 2, 3, 0]], axis=1)[:, None]


def dcm_to_rotvec(dcm: np.ndarray) -> np.ndarray:
    """Rotation vector of a DCM or ``(n, 3, 3)`` array (inverse of :func:`rotvec_to_dcm`).

    A matrix that is not orthonormal to 1e-12 is replaced by its nearest
    rotation (polar factor) first; a reflection is refused (ValueError).
    """
    C = np.asarray(dcm, dtype=float)
    M = C.reshape(-1, 3, 3)
    if np.any(np.linalg.det(M) <= 0):
        raise ValueError("a rotation matrix has a non-positive determinant (a reflection)")
    if not np.allclose(M @ M.transpose(0, 2, 1), np.eye(3), rtol=0.0, atol=1e-12):
        U, _, Vt = np.linalg.svd(M)
        M = U @ Vt
    q = _dcm_to_quat(M)
    q[q[:, 0] < 0] *= -1.0  # the angle in [0, pi]
    sin_half = np.linalg.norm(q[:, 1:], axis=1)
    angle = 2.0 * np.arctan2(sin_half, q[:, 0])
    small = angle <= 1e-3
    a2 = angle * angle
    # angle / sin(angle/2) by its Taylor series near 0.
    scale = np.where(small, 2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0, angle / np.where(small, 1.0, sin_half))
    return (q[:, 1:] * scale[:, None]).reshape(C.shape[:-2] + (3,))


def direction_vector(name: str, where: str = "") -> np.ndarray:
    """ENU unit vector of a direction name (``east``, ``up``, ...)."""
    key = str(name).strip().lower()
    if key not in DIRECTIONS:
        raise CalibError(f"unknown direction {name!r}", where, "use one of " + ", ".join(DIRECTIONS))
    return np.array(DIRECTIONS[key])


def attitude_from_directions(x: str, y: str, z: str, where: str = "") -> np.ndarray:
    """``C_b_n`` of a grid attitude given where body X, Y, Z point."""
    C = np.column_stack([direction_vector(d, where) for d in (x, y, z)])
    if not np.allclose(C.T @ C, np.eye(3)) or np.linalg.det(C) < 0.5:
        raise CalibError(
            f"body axes pointing {x}, {y}, {z} are not a right-handed frame",
            where,
            "choose three mutually perpendicular directions with X x Y = Z",
        )
    return C


def nearest_direction(v: np.ndarray) -> str:
    """Name of the grid direction closest to the ENU vector ``v``."""
    names = list(DIRECTIONS)
    dots = np.array([DIRECTIONS[n] for n in names]) @ np.asarray(v)
    return names[int(np.argmax(dots))]


def directions_of(C_b_n: np.ndarray) -> tuple[str, str, str]:
    """Where body X, Y, Z point (nearest grid directions) for an attitude."""
    return nearest_direction(C_b_n[:, 0]), nearest_direction(C_b_n[:, 1]), nearest_direction(C_b_n[:, 2])


def describe_axis(v: np.ndarray, tol: float = 1e-6) -> str:
    """A direction name for a grid axis, else its ENU components, e.g. ``[+0.707 -0.707 +0.000]``."""
    v = np.asarray(v, dtype=float)
    if np.max(np.abs(v)) > 1.0 - tol:
        return nearest_direction(v)
    return "[" + " ".join(f"{x:+.3f}" for x in v) + "]"


def on_grid(C_b_n: np.ndarray, tol: float = 1e-6) -> bool:
    """Whether every body axis points along a grid direction (E, N, U or opposite)."""
    return bool(np.all(np.max(np.abs(C_b_n), axis=0) > 1.0 - tol))


def gimbal_from_relative(C_rel: np.ndarray) -> np.ndarray:
    """Principal gimbal angles (rad) of ``C_rel = R_Z(outer) R_X(middle) R_Y(inner)``.

    Works on ``(3, 3)`` or ``(n, 3, 3)``; ``middle`` lies in ``[-pi/2, pi/2]``.
    At gimbal lock (``|middle| = pi/2``) outer and inner are not separable:
    the split returned there puts the whole rotation on the outer gimbal;
    callers that care test :func:`is_gimbal_lock`.
    """
    C = np.asarray(C_rel, dtype=float)
    middle = np.arcsin(np.clip(C[..., 2, 1], -1.0, 1.0))
    outer = np.arctan2(-C[..., 0, 1], C[..., 1, 1])
    inner = np.arctan2(-C[..., 2, 0], C[..., 2, 2])
    lock = is_gimbal_lock(C)
    if np.any(lock):
        # Only outer + inner (or outer - inner) is defined: put it all on outer.
        outer_lock = np.arctan2(C[..., 1, 0], C[..., 0, 0])
        outer = np.where(lock, outer_lock, outer)
        inner = np.where(lock, 0.0, inner)
    return np.stack([outer, middle, inner], axis=-1)


def is_gimbal_lock(C_rel: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """True where the middle gimbal is at +-90 deg (body Y along the outer axis)."""
    C = np.asarray(C_rel, dtype=float)
    return np.hypot(C[..., 0, 1], C[..., 1, 1]) < tol


def gimbal_to_relative(angles_rad: np.ndarray) -> np.ndarray:
    """``R_Z(outer) R_X(middle) R_Y(inner)`` from ``(..., 3)`` angles in rad."""
    a = np.asarray(angles_rad, dtype=float)
    return rot_axis(2, a[..., 0]) @ rot_axis(0, a[..., 1]) @ rot_axis(1, a[..., 2])


def unwrap_gimbal(angles_rad: np.ndarray) -> np.ndarray:
    """Continuous (encoder-like) gimbal angles along a densely sampled ``(n, 3)`` series.

    Each principal decomposition has a twin ``(o + pi, pi - m, i + pi)``. When
    the middle gimbal passes +-90 deg the principal branch swaps to the twin,
    which shows as a jump of ~180 deg in outer between two samples; motion
    between samples is far smaller than that (at most a few degrees for the
    sampling used here), so each such jump toggles the branch. The result is
    then unwrapped by 360 deg, as an encoder counting through the motion would.
    """
    a = np.asarray(angles_rad, dtype=float).reshape(-1, 3).copy()
    d_outer = np.angle(np.exp(1j * np.diff(a[:, 0])))  # wrapped to (-pi, pi]
    flips = np.abs(d_outer) > 0.5 * np.pi
    twin = np.concatenate([[False], np.cumsum(flips) % 2 == 1])
    a[twin, 0] += np.pi
    a[twin, 1] = np.pi - a[twin, 1]
    a[twin, 2] += np.pi
    return np.unwrap(a, axis=0)
