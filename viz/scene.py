"""The 3D scene: the base, the three gimbal rings and the IMU, turning over time.

The IMU's attitude is ``R_mount C_start R_Z(outer) R_X(middle) R_Y(inner)``
(conventions.md), the transforms composed along the entity path.
"""

from __future__ import annotations

import math

import numpy as np

from calib.nav.transform import gimbal_from_relative, rot_axis, unwrap_gimbal

from .events import FLIP, REST, Event, position_series, wrap_event
from .rrd import Writer

SCENE_RATE_HZ = 20.0  # transforms at most this often at rest ...
SCENE_STEP_DEG = 2.0  # ... and in addition every this many degrees of rotation
SIGNAL_RATE_HZ = 20.0  # raw signals shown as block means at about this rate

# Entity paths.
BASE = "world/base"
GIMBAL = f"{BASE}/gimbal"
OUTER = f"{GIMBAL}/outer"
MIDDLE = f"{OUTER}/middle"
INNER = f"{MIDDLE}/inner"
IMU = f"{INNER}/imu"
IMU_AXES = f"{IMU}/axes"
GIMBAL_ENTITIES = (OUTER, MIDDLE, INNER)

# Geometry of the picture (arbitrary units).
RING_RADIUS = {"outer": 1.75, "middle": 1.5, "inner": 1.25}
IMU_HALF_SIZE = (0.55, 0.42, 0.3)
AXIS_LENGTH = 1.0
PLATE_Z = -2.1
GALLERY_STEP = 7.0  # between rest positions in the analysis gallery: room for their labels

AXIS_COLORS = [(230, 60, 60), (60, 200, 60), (70, 110, 255)]  # X/E red, Y/N green, Z/U blue
ENVELOPE_COLORS = [(240, 170, 170), (160, 215, 160), (170, 185, 250)]  # AXIS_COLORS, pale
RING_COLORS = {"outer": (200, 140, 40), "middle": (150, 150, 160), "inner": (90, 170, 200)}


def gimbal_from_attitudes(C_start: np.ndarray, C_b_n: np.ndarray) -> np.ndarray:
    """Continuous gimbal angles (rad, ``(n, 3)``) of densely sampled attitudes."""
    C_rel = np.einsum("ji,njk->nik", C_start, C_b_n)
    return unwrap_gimbal(gimbal_from_relative(C_rel))


def gimbal_matrix(angles_rad: np.ndarray) -> np.ndarray:
    """``R_Z(outer) R_X(middle) R_Y(inner)`` of gimbal angles (rad, ``(n, 3)``)."""
    return rot_axis(2, angles_rad[:, 0]) @ rot_axis(0, angles_rad[:, 1]) @ rot_axis(1, angles_rad[:, 2])


def scene_indices(
    time_rel: np.ndarray, dtheta: np.ndarray, rate_hz: float = SCENE_RATE_HZ, step_deg: float = SCENE_STEP_DEG
) -> np.ndarray:
    """Samples that carry a scene transform: one per ``1/rate_hz`` and one per ``step_deg`` turned.

    The turned angle is the gyros' accumulated ``|dtheta|``, so flips are
    drawn smoothly at any flip rate while long rests cost ``rate_hz`` rows/s.
    The first and last samples are always kept.
    """
    n = len(time_rel)
    slot = np.floor(time_rel * rate_hz)
    turned = np.floor(np.cumsum(np.linalg.norm(dtheta, axis=1)) / math.radians(step_deg))
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    keep[1:] |= (slot[1:] != slot[:-1]) | (turned[1:] != turned[:-1])
    return np.flatnonzero(keep)


def _ring(radius: float, plane: str, n: int = 96) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * np.pi, n + 1)
    c, s = radius * np.cos(a), radius * np.sin(a)
    z = np.zeros_like(a)
    return {"xy": np.c_[c, s, z], "xz": np.c_[c, z, s], "yz": np.c_[z, c, s]}[plane]


def _log_scene_static(w: Writer, R_mount: np.ndarray, C_start: np.ndarray, gravity: float) -> None:
    rr = w.rr
    w.static("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP)
    corner = np.array([-1.9, -1.9, PLATE_Z + 0.02])
    w.static(
        "world/enu",
        rr.Arrows3D(
            origins=[corner] * 3,
            vectors=np.eye(3) * 0.9,
            labels=["E", "N", "U"],
            colors=AXIS_COLORS,
            radii=0.025,
        ),
    )
    w.static(
        "world/gravity",
        rr.Arrows3D(
            origins=[[2.0, 2.0, 1.2]],
            vectors=[[0.0, 0.0, -1.2]],
            labels=[f"g = {gravity:.6f} m/s^2"],
            colors=[(150, 90, 210)],
            radii=0.03,
        ),
    )
    # Base: mounting rotation, plate, and the stand holding the outer axis.
    pivot = C_start[:, 2] * RING_RADIUS["outer"]
    stand = [np.array([[p[0], p[1], PLATE_Z], p]) for p in (pivot, -pivot)]
    w.static(
        BASE,
        rr.Transform3D(mat3x3=R_mount),
        rr.Boxes3D(
            centers=[[0.0, 0.0, PLATE_Z - 0.05]],
            half_sizes=[[2.2, 2.2, 0.05]],
            colors=[(110, 110, 110)],
            fill_mode="solid",
        ),
        rr.LineStrips3D(stand, colors=[(160, 160, 160)] * 2, radii=0.04),
    )
    w.static(GIMBAL, rr.Transform3D(mat3x3=C_start))
    # Rings: each contains its own axis and the next gimbal's axis.
    for entity, name, plane in ((OUTER, "outer", "xz"), (MIDDLE, "middle", "xy"), (INNER, "inner", "yz")):
        w.static(
            entity,
            rr.LineStrips3D(
                [_ring(RING_RADIUS[name], plane)],
                colors=[RING_COLORS[name]],
                radii=0.035,
                labels=[f"{name} gimbal"],
                show_labels=False,
            ),
        )
    w.static(
        IMU,
        rr.Boxes3D(
            half_sizes=[IMU_HALF_SIZE],
            colors=[(235, 200, 80)],
            fill_mode="solid",
            labels=["IMU"],
            show_labels=False,
        ),
    )
    w.static(
        IMU_AXES,
        rr.Arrows3D(vectors=np.eye(3) * AXIS_LENGTH, labels=["X", "Y", "Z"], colors=AXIS_COLORS, radii=0.03),
    )


def log_scene(
    w: Writer,
    times: np.ndarray,
    angles_rad: np.ndarray,
    R_mount: np.ndarray,
    C_start: np.ndarray,
    gravity: float,
    events: list[Event],
) -> None:
    """The scene over ``times`` (gimbal transforms, angles, position number) and the events as text."""
    rr = w.rr
    _log_scene_static(w, R_mount, C_start, gravity)
    for entity, axis, k in ((OUTER, 2, 0), (MIDDLE, 0, 1), (INNER, 1, 2)):
        w.columns(entity, times, rr.Transform3D.columns(mat3x3=rot_axis(axis, angles_rad[:, k])))
    w.series(
        "attitude/gimbal_deg",
        times,
        np.degrees(angles_rad),
        ["outer", "middle", "inner"],
        [RING_COLORS["outer"], RING_COLORS["middle"], RING_COLORS["inner"]],
    )
    w.series("sequence/position", times, position_series(events, times), ["position"])
    if events:
        ev_t = np.array([e.time for e in events])
        rows = [
            (e.time, line, "INFO" if e.kind == REST else "DEBUG")
            for e in events
            for line in wrap_event(e.text)
        ]
        w.columns(
            "events",
            np.array([r[0] for r in rows]),
            rr.TextLog.columns(text=[r[1] for r in rows], level=[r[2] for r in rows]),
        )
        label = [e.text.split(":")[0] + (" (turning)" if e.kind == FLIP else "") for e in events]
        w.columns(
            "world/label",
            ev_t,
            rr.Points3D.columns(
                positions=np.tile([0.0, 0.0, 2.4], (len(events), 1)),
                labels=label,
                colors=np.tile([60, 60, 60, 255], (len(events), 1)).astype(np.uint8),
            ),
        )
