"""Rerun recordings (``.rrd``) of a calibration run and of a sequence analysis.

Two entry points, both pure (they read nothing but their arguments and write
only ``path``, atomically):

* :func:`record_run` -- one run log: the gimbal and IMU turning in 3D, the raw
  sensor signals, the navigation velocity errors before and after calibration,
  the attitude, the sequence's positions and flips, and the calibration result
  against its requirements (and against the truth of a simulated run).
* :func:`record_analysis` -- the observability analysis of a sequence: the
  correlation matrix as a heat map, 3 sigma / requirement bars, and the rest
  attitudes in 3D (animated over the sequence's nominal time line and as a
  static gallery of the positions).

Everything temporal is on the timeline ``time`` (a duration, seconds since
the run's first sample starts, ``time_s - (time_s[0] - (time_s[1] - time_s[0]))``,
the estimator's start instant),
written with explicit time columns through ``send_columns``. Nothing is
logged with per-sample ``log`` calls, so no wall-clock or tick timeline is
added and the recording's content depends only on the inputs (its row ids,
which rerun draws from the clock, differ from file to file).

Entity paths (run recording)::

    about                                   TextDocument: sources, units, decimation
    events                                  TextLog: "position k ..." at every rest start,
                                            "flip k ..." at every flip start (wrapped rows)
    world                                   ViewCoordinates RIGHT_HAND_Z_UP (x east, y north, z up)
    world/enu                               Arrows3D E, N, U (static)
    world/gravity                           Arrows3D: gravity (down), labelled with g in m/s^2
    world/label                             Points3D whose label is the current position / flip
    world/base                              Transform3D: the base mounting rotation R_mount (static);
                                            base plate and stand
    world/base/gimbal                       Transform3D: C_start (static)
    world/base/gimbal/outer                 Transform3D R_Z(outer) over time; outer ring
    world/base/gimbal/outer/middle          Transform3D R_X(middle) over time; middle ring
    world/base/gimbal/outer/middle/inner    Transform3D R_Y(inner) over time; inner ring
    world/base/gimbal/outer/middle/inner/imu       Boxes3D: the IMU
    world/base/gimbal/outer/middle/inner/imu/axes  Arrows3D: body X, Y, Z
    signals/gyro_dps                        Scalars x, y, z: dtheta/dt, deg/s (block means)
    signals/accel_mps2                      Scalars x, y, z: dv/dt, m/s^2 (block means)
    residuals/before/velocity_mps           Scalars E, N, U: navigation velocity (= error) of the raw
                                            increments from the coarse alignment, every sample
    residuals/after/velocity_mps            Scalars E, N, U: the same after compensating with the
                                            result, from its initial attitude, every sample
    residuals/after/noise_3sigma_mps        Scalars +3σ E, N, U, -3σ E, N, U: what the line above
                                            should stay inside if the calibration is right: the
                                            predicted noise envelope (calib.review.velocity_noise_sigma,
                                            the result's profile), on the fit's grid (1 s at rest,
                                            0.1 s turning)
    attitude/gimbal_deg                     Scalars outer, middle, inner (the scene's angles)
    attitude/nav_minus_gimbal_arcsec        Scalars E, N, U: rotation vector of C_nav C_scene^T
                                            (calibrated navigation vs the scene; needs a result)
    sequence/position                       Scalars: rest position number, 0 while turning
    results/ratio                           BarChart: 3 sigma / requirement, parameters in spec order;
                                            and LineStrips2D: the same as labelled horizontal bars
                                            (row i = parameter i, labels = names), with
      .../names, .../values                 Points2D whose labels are the names / the values,
      .../guide                             LineStrips2D at 0 and at the value 1, Points2D naming it
    results/error_over_requirement          the same for |estimate - truth| / requirement (with truth)
    results/error_over_sigma                the same for (estimate - truth) / sigma (with truth)
    results/correlation                     Tensor 21 x 21 (when the result carries it), with
      .../image                             Image 21 x 21 RGB, pixel (row i, column j); blue -1, red +1
      .../rows, .../columns                 Points2D labelled with the names, left of / above the image
      .../cells                             Points2D at every pixel, hidden labels "a / b: rho"
    results/table                           TextDocument: every parameter, value, sigma, ratio, truth

The IMU's attitude in the scene is ``R_mount C_start R_Z(outer) R_X(middle)
R_Y(inner)`` (conventions.md) with the transforms composed along the entity
path; the gimbal angles come from the run's encoder columns when it has
them, else from the sequence's nominal attitude (decomposed and unwrapped),
else from the navigation attitude.

Entity paths (analysis recording): ``about``, ``events``, the same ``world/...``
scene over the sequence's nominal time line, ``positions/p<k>`` (Transform3D
placing the IMU of rest position k in a 3 x 3 gallery with its attitude;
Boxes3D, ``positions/p<k>/axes`` Arrows3D), ``analysis/ratio``,
``analysis/sigma_over_requirement`` (BarCharts with labelled 2D bars, as
``results/ratio``), ``analysis/correlation`` (Tensor, 21 x 21, with the
labelled image of ``results/correlation``) and ``analysis/table`` (TextDocument).

Readable as it opens: BarChart and Tensor views show no category names, so
the views of the bars and of the matrix are 2D views of the labelled
drawings (the BarChart and Tensor stay, for programs). TextLog rows are
wrapped at ``EVENT_WIDTH`` characters (continuation rows indented) and the
events view shows only time and message, so nothing is cut at 1920 px.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calib import earth
from calib import params as P
from calib.errors import CalibError
from calib.fileio import default_mode, remove_quietly

TIMELINE = "time"
APPLICATION_ID = "seqdesign"

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

_REST, _FLIP = "rest", "flip"


@dataclass
class Event:
    """A rest start or a flip start on the recording's time line."""

    time: float
    kind: str  # "rest" or "flip"
    number: int  # position number (rest) or flip number (flip), from 1
    text: str


@dataclass
class Summary:
    """What a recording holds (also what ``view --json`` prints)."""

    path: str
    entities: dict[str, int] = field(default_factory=dict)  # entity path -> rows (static = 1)
    notes: list[str] = field(default_factory=list)
    scene_source: str = ""
    mount_source: str = ""

    def to_dict(self) -> dict:
        return {
            "rrd": self.path,
            "scene_source": self.scene_source,
            "mount_source": self.mount_source,
            "entities": dict(self.entities),
            "notes": list(self.notes),
        }


# ---------------------------------------------------------------------------
# Writing


class _Writer:
    """A headless recording stream saving to a temporary file beside ``path``.

    ``commit()`` flushes and moves the file into place in one step; on any
    error the temporary file is removed and ``path`` is left as it was.
    """

    def __init__(self, path: str | os.PathLike, recording_id: str, name: str, blueprint):
        import rerun as rr

        self.rr = rr
        self.target = Path(path)
        if self.target.suffix.lower() != ".rrd":
            raise CalibError(
                f"unknown recording format {self.target.suffix!r}",
                str(self.target),
                "name the recording .rrd",
            )
        directory = self.target.parent
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{self.target.name}.", suffix=".tmp", dir=directory)
        except OSError as exc:
            raise CalibError(
                f"cannot write the file: {exc.strerror or exc}",
                str(self.target),
                "check that the directory exists and is writable",
            ) from None
        os.close(fd)
        self.tmp = tmp
        self.summary = Summary(path=str(self.target))
        self._static_only: set[str] = set()
        try:
            rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
            rec.set_log_time_enabled(False)
            rec.set_log_tick_enabled(False)
            rec.save(tmp, default_blueprint=blueprint)
            rec.send_recording_name(name)
        except BaseException:
            remove_quietly(tmp)
            raise
        self.rec = rec

    # -- logging helpers -------------------------------------------------

    def static(self, entity: str, *archetypes) -> None:
        for a in archetypes:
            self.rec.log(entity, a, static=True)
        if entity not in self.summary.entities:
            self.summary.entities[entity] = 1
            self._static_only.add(entity)

    def columns(self, entity: str, times: np.ndarray, columns) -> None:
        rr = self.rr
        self.rec.send_columns(
            entity,
            indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(times, dtype=np.float64))],
            columns=columns,
        )
        if entity in self._static_only:
            self._static_only.discard(entity)
            self.summary.entities[entity] = 0
        self.summary.entities[entity] = self.summary.entities.get(entity, 0) + len(times)

    def series(self, entity: str, times: np.ndarray, values: np.ndarray, names, colors=None) -> None:
        """A multi-channel time series: one entity, one row per time, ``names`` per channel."""
        rr = self.rr
        values = np.asarray(values, dtype=np.float64)
        if values.ndim == 1:
            values = values[:, None]
        self.static(entity, rr.SeriesLines(names=list(names), colors=colors, widths=[1.0] * len(names)))
        self.columns(entity, times, rr.Scalars.columns(scalars=values))

    def note(self, text: str) -> None:
        self.summary.notes.append(text)

    # -- finishing -------------------------------------------------------

    def commit(self) -> Summary:
        try:
            self.rec.flush()
            self.rec.disconnect()
            with open(self.tmp, "rb+") as handle:
                os.fsync(handle.fileno())
            os.chmod(self.tmp, default_mode(self.target))
            os.replace(self.tmp, self.target)
        except OSError as exc:
            remove_quietly(self.tmp)
            raise CalibError(
                f"cannot write the file: {exc.strerror or exc}",
                str(self.target),
                "check free disk space and permissions",
            ) from None
        except BaseException:
            self.abort()
            raise
        return self.summary

    def abort(self) -> None:
        try:
            self.rec.disconnect()
        except Exception:  # noqa: BLE001 - nothing more to do for a file we throw away
            pass
        remove_quietly(self.tmp)


def _recording_id(*parts) -> str:
    """A recording id derived from the content, so re-recording the same input gives the same id."""
    h = hashlib.sha256()
    for p in parts:
        h.update(np.ascontiguousarray(p).tobytes() if isinstance(p, np.ndarray) else repr(p).encode())
    return str(uuid.UUID(bytes=h.digest()[:16], version=5))


# ---------------------------------------------------------------------------
# Small numerics


def _rot(axis: int, angle_rad: np.ndarray) -> np.ndarray:
    from calib.transform import rot_axis

    return rot_axis(axis, angle_rad)


def _gimbal_from_attitudes(C_start: np.ndarray, C_b_n: np.ndarray) -> np.ndarray:
    """Continuous gimbal angles (rad, ``(n, 3)``) of densely sampled attitudes."""
    from calib.transform import gimbal_from_relative, unwrap_gimbal

    C_rel = np.einsum("ji,njk->nik", C_start, C_b_n)
    return unwrap_gimbal(gimbal_from_relative(C_rel))


def _gimbal_matrix(angles_rad: np.ndarray) -> np.ndarray:
    return _rot(2, angles_rad[:, 0]) @ _rot(0, angles_rad[:, 1]) @ _rot(1, angles_rad[:, 2])


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


def block_means(time_rel: np.ndarray, dt: np.ndarray, x: np.ndarray, block: int):
    """Mean rate ``sum(x) / sum(dt)`` over blocks of ``block`` samples, stamped at the block middle."""
    starts = np.arange(0, len(dt), block)
    sums = np.add.reduceat(x, starts, axis=0)
    durations = np.add.reduceat(dt, starts)
    ends = np.minimum(starts + block, len(dt)) - 1
    t_mid = 0.5 * ((time_rel[starts] - dt[starts]) + time_rel[ends])
    return t_mid, sums / durations[:, None]


def position_series(events: list[Event], times: np.ndarray) -> np.ndarray:
    """Rest position number at ``times`` (0 while turning) from the event list."""
    if not events:
        return np.zeros(len(times))
    ev_t = np.array([e.time for e in events])
    value = np.array([e.number if e.kind == _REST else 0 for e in events], dtype=float)
    k = np.searchsorted(ev_t, times, side="right") - 1
    return np.where(k >= 0, value[np.clip(k, 0, None)], 0.0)


# ---------------------------------------------------------------------------
# Events


EVENT_WIDTH = 60  # characters of a TextLog row: fits the events view as laid out at 1920 px


def wrap_event(text: str, width: int = EVENT_WIDTH) -> list[str]:
    """An event's text as TextLog rows of at most ``width`` characters (a view cuts long rows).

    Breaks after ``"; "`` (then at spaces); continuation rows are indented by
    two spaces, so the first row of every event starts with its name.
    """
    rows, line = [], ""
    for part in text.split("; "):
        piece = part if not line else f"{line}; {part}"
        if len(piece) <= width or not line:
            line = piece
        else:
            rows.append(line + ";")
            line = "  " + part
    rows.append(line)
    out = []
    for row in rows:  # a single part longer than the width: break at spaces
        while len(row) > width and " " in row[2:width]:
            cut = row.rindex(" ", 2, width)
            out.append(row[:cut])
            row = "  " + row[cut + 1 :]
        out.append(row)
    return out


def sequence_events(seq, t_shift: float = 0.0) -> list[Event]:
    """Rest and flip starts of a sequence's nominal time line (+ ``t_shift``)."""
    from calib.sequence import rest_positions, timeline

    tl = timeline(seq)
    positions = {p.number: p for p in rest_positions(seq)}
    gimbal_names = ("outer", "middle", "inner")
    events = []
    for i in range(len(tl.t0)):
        t = float(tl.t0[i]) + t_shift
        if tl.rate[i] == 0.0:
            p = positions[int(tl.position[i])]
            lock = "; GIMBAL LOCK" if p.gimbal_lock else ""
            events.append(
                Event(
                    t,
                    _REST,
                    p.number,
                    (
                        f"position {p.number}: X {p.directions[0]}, Y {p.directions[1]}, "
                        f"Z {p.directions[2]}; gimbal outer {p.gimbal_deg[0]:.1f}, middle "
                        f"{p.gimbal_deg[1]:.1f}, inner {p.gimbal_deg[2]:.1f} deg; rest "
                        f"{tl.t1[i] - tl.t0[i]:.0f} s{lock}"
                    ),
                )
            )
        else:
            k = int(tl.step[i])
            s = seq.steps[k]
            before = [p for p in positions.values() if p.end_s <= tl.t0[i] + 1e-9]
            after = [p for p in positions.values() if p.start_s >= tl.t1[i] - 1e-9]
            moved = ""
            if before and after:
                d = np.abs(
                    min(after, key=lambda p: p.start_s).gimbal_deg
                    - max(before, key=lambda p: p.end_s).gimbal_deg
                )
                moved = f" ({gimbal_names[int(np.argmax(d))]} gimbal)"
            events.append(
                Event(
                    t,
                    _FLIP,
                    k + 1,
                    f"flip {k + 1}: about body {s.axis} by "
                    f"{s.angle_deg:+g} deg at {s.rate_dps:g} deg/s{moved}",
                )
            )
    return events


def motion_events(
    time_rel: np.ndarray, dt: np.ndarray, dtheta: np.ndarray, moving: np.ndarray
) -> list[Event]:
    """Rest and flip starts found from the gyros, with each flip's measured angle."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], moving.astype(np.int8), [0]])))
    starts, ends = edges[::2], edges[1::2]
    events = (
        [Event(0.0, _REST, 1, "position 1 (rest, from the gyros)")]
        if (len(starts) == 0 or starts[0] > 0)
        else []
    )
    for k, (a, b) in enumerate(zip(starts, ends)):
        rv = dtheta[a:b].sum(axis=0)
        ax = int(np.argmax(np.abs(rv)))
        events.append(
            Event(
                float(time_rel[a] - dt[a]),
                _FLIP,
                k + 1,
                f"flip {k + 1}: about body {'XYZ'[ax]} by {math.degrees(rv[ax]):+.2f} deg (integrated gyros)",
            )
        )
        if b < len(time_rel):
            number = len([e for e in events if e.kind == _REST]) + 1
            events.append(
                Event(float(time_rel[b] - dt[b]), _REST, number, f"position {number} (rest, from the gyros)")
            )
    return events


# ---------------------------------------------------------------------------
# The 3D scene


def _ring(radius: float, plane: str, n: int = 96) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * np.pi, n + 1)
    c, s = radius * np.cos(a), radius * np.sin(a)
    z = np.zeros_like(a)
    return {"xy": np.c_[c, s, z], "xz": np.c_[c, z, s], "yz": np.c_[z, c, s]}[plane]


def _log_scene_static(w: _Writer, R_mount: np.ndarray, C_start: np.ndarray, gravity: float) -> None:
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


def _log_scene(
    w: _Writer,
    times: np.ndarray,
    angles_rad: np.ndarray,
    R_mount: np.ndarray,
    C_start: np.ndarray,
    gravity: float,
    events: list[Event],
) -> None:
    rr = w.rr
    _log_scene_static(w, R_mount, C_start, gravity)
    for entity, axis, k in ((OUTER, 2, 0), (MIDDLE, 0, 1), (INNER, 1, 2)):
        w.columns(entity, times, rr.Transform3D.columns(mat3x3=_rot(axis, angles_rad[:, k])))
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
            (e.time, line, "INFO" if e.kind == _REST else "DEBUG")
            for e in events
            for line in wrap_event(e.text)
        ]
        w.columns(
            "events",
            np.array([r[0] for r in rows]),
            rr.TextLog.columns(text=[r[1] for r in rows], level=[r[2] for r in rows]),
        )
        label = [e.text.split(":")[0] + (" (turning)" if e.kind == _FLIP else "") for e in events]
        w.columns(
            "world/label",
            ev_t,
            rr.Points3D.columns(
                positions=np.tile([0.0, 0.0, 2.4], (len(events), 1)),
                labels=label,
                colors=np.tile([60, 60, 60, 255], (len(events), 1)).astype(np.uint8),
            ),
        )


# ---------------------------------------------------------------------------
# Labelled charts (rr.BarChart and rr.Tensor carry no category names)

BAR_LENGTH = 12.0  # 2D units of the longest bar (or of the value 1, if all are shorter)
BAR_HALF_HEIGHT = 0.35  # of a row of 1 unit: bars are lines this thick (Boxes2D are not filled)
NAME_X = -1.6  # centre of the names, left of the zero line (labels are drawn centred)
# rerun draws a point's label centred horizontally and just BELOW the point: a label
# point LABEL_LIFT above its row's centre puts the text on the row at the zooms
# the views open with (rows of 13-20 px; the text's centre is ~12 px below the point).
LABEL_LIFT = 0.7
VALUE_GAP = 1.4  # centre of a value label, beyond the end of its bar
LABEL_COLOR = (40, 40, 40)
GUIDE_COLOR = (150, 150, 150)
COLUMN_LABEL_LEVELS = 3  # column names of a matrix on this many lines, every third on one
COLUMN_LABEL_STEP = 1.1  # 2D units between those lines (a cell is 1)


def bar_lines(values: np.ndarray) -> tuple[np.ndarray, float]:
    """Horizontal bars, one row per value (row i centred on y = i + 0.5, y down).

    Returns the bars as line segments ``(n, 2, 2)`` from the zero line to
    ``value * scale``, and the scale (2D units per unit of value). A value
    that is not finite gets a bar of length zero.
    """
    v = np.asarray(values, dtype=float)
    finite = np.isfinite(v)
    top = max(1.0, float(np.max(np.abs(v[finite]))) if finite.any() else 1.0)
    scale = BAR_LENGTH / top
    y = np.arange(len(v), dtype=float) + 0.5
    end = np.where(finite, v * scale, 0.0)
    return np.stack([np.c_[np.zeros(len(v)), y], np.c_[end, y]], axis=1), scale


def _labelled_bars(w: _Writer, entity: str, values: np.ndarray, color, guide: str) -> None:
    """``values`` (spec order) as a BarChart (for programs) and as labelled 2D bars (for eyes).

    The 2D bars are LineStrips2D on the same entity, one per parameter,
    labelled with its name; ``entity/names`` writes the names left of the
    bars and ``entity/values`` the values beyond their ends; ``entity/guide``
    marks 0 and the value 1 (``guide`` names it).
    """
    rr = w.rr
    v = np.asarray(values, dtype=float)
    n = len(v)
    names = list(P.NAMES[:n])
    w.static(entity, rr.BarChart(v, abscissa=np.arange(n, dtype=np.float64), color=color))
    lines, scale = bar_lines(v)
    w.static(
        entity,
        rr.LineStrips2D(lines, radii=BAR_HALF_HEIGHT, colors=[color] * n, labels=names, show_labels=False),
    )
    y = lines[:, 0, 1] - LABEL_LIFT
    w.static(
        f"{entity}/names",
        rr.Points2D(
            np.c_[np.full(n, NAME_X), y], radii=0.01, labels=names, colors=[LABEL_COLOR] * n, show_labels=True
        ),
    )
    end = lines[:, 1, 0]
    w.static(
        f"{entity}/values",
        rr.Points2D(
            np.c_[end + np.where(end < 0, -VALUE_GAP, VALUE_GAP), y],
            radii=0.01,
            labels=[f"{x:.2f}" if np.isfinite(x) else "unobservable" for x in v],
            colors=[LABEL_COLOR] * n,
            show_labels=True,
        ),
    )
    marks = [0.0, scale] + ([-scale] if np.nanmin(np.where(np.isfinite(v), v, 0.0)) < 0 else [])
    w.static(
        f"{entity}/guide",
        rr.LineStrips2D(
            [[[x, 0.0], [x, float(n)]] for x in marks], colors=[GUIDE_COLOR] * len(marks), radii=0.04
        ),
        rr.Points2D(
            [[scale, -0.8 - LABEL_LIFT]], radii=0.01, labels=[guide], colors=[GUIDE_COLOR], show_labels=True
        ),
    )


def correlation_colors(corr: np.ndarray) -> np.ndarray:
    """RGB (n, n, 3) uint8 of a correlation matrix: blue -1, white 0, red +1."""
    c = np.clip(np.nan_to_num(np.asarray(corr, dtype=float)), -1.0, 1.0)[..., None]
    white, red, blue = np.array([255.0] * 3), np.array([200.0, 30, 40]), np.array([40.0, 70, 200])
    rgb = np.where(c >= 0, white + c * (red - white), white - c * (blue - white))
    return np.round(rgb).astype(np.uint8)


def _labelled_matrix(w: _Writer, entity: str, corr: np.ndarray) -> None:
    """A correlation matrix as a Tensor (for programs) and as a labelled image (for eyes).

    The image has one pixel per pair (row i, column j at x in [j, j + 1], y
    in [i, i + 1]); ``entity/rows`` names the rows on the left and
    ``entity/columns`` the columns above it, on three staggered lines so
    that neighbouring names do not overlap; ``entity/cells`` carries every
    pair's value as a hover label.
    """
    rr = w.rr
    n = len(corr)
    w.static(entity, rr.Tensor(corr, dim_names=["row", "col"], value_range=(-1.0, 1.0)))
    w.static(f"{entity}/image", rr.Image(correlation_colors(corr), color_model="RGB"))
    centres = np.arange(n, dtype=float) + 0.5
    names = list(P.NAMES[:n])
    w.static(
        f"{entity}/rows",
        rr.Points2D(
            np.c_[np.full(n, -1.2), centres - LABEL_LIFT],
            labels=names,
            radii=0.01,
            colors=[LABEL_COLOR] * n,
            show_labels=True,
        ),
    )
    w.static(
        f"{entity}/columns",
        rr.Points2D(
            np.c_[centres, -0.7 - LABEL_LIFT - COLUMN_LABEL_STEP * (np.arange(n) % COLUMN_LABEL_LEVELS)],
            labels=names,
            radii=0.01,
            colors=[LABEL_COLOR] * n,
            show_labels=True,
        ),
    )
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    w.static(
        f"{entity}/cells",
        rr.Points2D(
            np.c_[j.ravel() + 0.5, i.ravel() + 0.5],
            radii=0.01,
            show_labels=False,
            labels=[f"{names[a]} / {names[b]}: {corr[a, b]:+.3f}" for a, b in zip(i.ravel(), j.ravel())],
        ),
    )


# ---------------------------------------------------------------------------
# Run recording


def _results_table(result, truth) -> str:
    vals, sig = P.from_si(result.values), P.from_si(result.sigma)
    req = result.requirements
    ratio = req.ratio(result.sigma)
    head = "| # | name | unit | estimate | sigma | 3 sigma / req |"
    rule = "|---|---|---|---|---|---|"
    if truth is not None:
        tv = truth.errors.in_units()
        head += " truth | error | error / req | error / sigma |"
        rule += "---|---|---|---|"
    lines = [
        f"# Calibration result (profile {result.profile or '?'}, requirements {req.name})",
        "",
        f"converged: {result.converged}, iterations {result.iterations}, residual RMS "
        f"{result.residual_rms_mps:.3g} m/s, chi2/dof {result.chi2_per_dof:.3f}",
        "",
        "Bars in results/* are named and follow the # column (spec order).",
        "",
        head,
        rule,
    ]
    for p in P.PARAMETERS:
        i = p.index
        row = (
            f"| {i} | {p.name} | {p.unit} | {vals[i]:.5g} | {sig[i]:.3g} | "
            f"{ratio[i]:.2f}{' MISS' if ratio[i] > 1 else ''} |"
        )
        if truth is not None:
            e = vals[i] - tv[i]
            row += (
                f" {tv[i]:.5g} | {e:+.3g} | {abs(e) / req.values[i]:.2f} | "
                f"{e / sig[i] if sig[i] > 0 else float('nan'):+.2f} |"
            )
        lines.append(row)
    i = int(np.argmax(ratio))
    lines += ["", f"worst 3 sigma / requirement: {ratio[i]:.2f} ({P.NAMES[i]})"]
    return "\n".join(lines)


def _log_results(w: _Writer, result, truth) -> None:
    rr = w.rr
    # The result carries the requirements it was judged against (--requirements): draw those.
    req = result.requirements
    _labelled_bars(w, "results/ratio", req.ratio(result.sigma), (90, 170, 230), "1 = requirement")
    if truth is not None:
        err = result.values - truth.errors.values
        _labelled_bars(
            w,
            "results/error_over_requirement",
            np.abs(err) / req.si,
            (230, 150, 60),
            "1 = requirement",
        )
        with np.errstate(divide="ignore", invalid="ignore"):
            _labelled_bars(w, "results/error_over_sigma", err / result.sigma, (160, 110, 220), "1 sigma")
    if result.correlation is not None:
        _labelled_matrix(w, "results/correlation", result.correlation)
    w.static("results/table", rr.TextDocument(_results_table(result, truth), media_type="text/markdown"))


def _panels():
    """Side panels folded away (the views get the room) and the time panel on ``time``, paused."""
    import rerun.blueprint as rrb

    return [
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline=TIMELINE, play_state="paused", state="collapsed"),
    ]


def _events_view():
    """The positions and flips as text: time and message only (no entity or level columns,
    so that the message gets the view's width).
    """
    import rerun.blueprint as rrb
    from rerun.blueprint.encodings import TextLogColumn, TextLogColumnKind, TimelineColumn

    return rrb.TextLogView(
        origin="events",
        name="positions and flips",
        columns=rrb.archetypes.TextLogColumns(
            timeline_columns=[TimelineColumn(TIMELINE)],
            text_log_columns=[
                TextLogColumn(TextLogColumnKind.EntityPath, visible=False),
                TextLogColumn(TextLogColumnKind.LogLevel, visible=False),
                TextLogColumn(TextLogColumnKind.Body),
            ],
        ),
    )


def _bars_view(origin: str, name: str):
    """A 2D view of :func:`_labelled_bars`: names on the left, bars to the right."""
    import rerun.blueprint as rrb

    return rrb.Spatial2DView(
        origin=origin,
        name=name,
        visual_bounds=rrb.VisualBounds2D(
            x_range=(NAME_X - 1.5, BAR_LENGTH + 2.0 * VALUE_GAP), y_range=(-1.5, P.N_PARAMS + 1.5)
        ),
    )


def _matrix_view(origin: str, name: str):
    """A 2D view of :func:`_labelled_matrix`, the names around it in view."""
    import rerun.blueprint as rrb

    return rrb.Spatial2DView(
        origin=origin,
        name=name,
        visual_bounds=rrb.VisualBounds2D(
            x_range=(-3.0, P.N_PARAMS + 0.5),
            y_range=(-1.5 - LABEL_LIFT - COLUMN_LABEL_STEP * COLUMN_LABEL_LEVELS, P.N_PARAMS + 1.0),
        ),
    )


def _scene_view(origin: str, name: str):
    """A 3D view looking at the gimbal from the south-east, a little above."""
    import rerun.blueprint as rrb

    return rrb.Spatial3DView(
        origin=origin,
        name=name,
        eye_controls=rrb.EyeControls3D(
            position=(5.0, -6.5, 3.5), look_target=(0.0, 0.0, -0.4), eye_up=(0.0, 0.0, 1.0)
        ),
    )


def _whole_run(duration_s: float):
    """Time axis of a time-series view showing the whole run (not just the latest seconds)."""
    import rerun.blueprint as rrb

    return rrb.TimeAxis(
        view_range=rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seconds=0.0),
            end=rrb.TimeRangeBoundary.absolute(seconds=float(duration_s)),
        )
    )


def run_blueprint(duration_s: float, with_results: bool = True):
    """The layout a run recording opens with: 3D | signals | residuals | results."""
    import rerun.blueprint as rrb

    def plot(origin, name):
        return rrb.TimeSeriesView(origin=origin, name=name, axis_x=_whole_run(duration_s))

    scene = rrb.Vertical(_scene_view("world", "gimbal and IMU"), _events_view(), row_shares=[3, 1])
    signals = rrb.Vertical(
        plot("signals/gyro_dps", "gyro rate, deg/s"),
        plot("signals/accel_mps2", "specific force, m/s^2"),
        plot("attitude/gimbal_deg", "gimbal angles, deg"),
        plot("sequence", "rest position (0 = turning)"),
        row_shares=[3, 3, 2, 1],
    )
    residuals = rrb.Vertical(
        plot("residuals/before", "velocity error before calibration, m/s"),
        plot("residuals/after", "velocity error after calibration, m/s (pale: ±3σ of the noise)"),
        plot("attitude/nav_minus_gimbal_arcsec", "navigation - gimbal attitude, arcsec"),
    )
    columns = [scene, signals, residuals]
    if with_results:
        columns.append(
            rrb.Vertical(
                _bars_view("results/ratio", "3 sigma / requirement"),
                _bars_view("results/error_over_requirement", "|error| / requirement (truth)"),
                rrb.Tabs(
                    _matrix_view("results/correlation", "correlation (blue -1, red +1)"),
                    rrb.TextDocumentView(origin="results/table", name="result"),
                    rrb.TextDocumentView(origin="about", name="about"),
                ),
                row_shares=[3, 3, 3],
            )
        )
    else:
        columns.append(rrb.TextDocumentView(origin="about", name="about"))
    return rrb.Blueprint(rrb.Horizontal(*columns, column_shares=[3, 3, 3, 3][: len(columns)]), *_panels())


def record_run(
    run, path: str | os.PathLike, review, sequence=None, result=None, truth=None, *, name: str | None = None
) -> Summary:
    """Write a rerun recording of one run log (see the module docstring for its entities).

    Parameters
    ----------
    run : calib.runlog.Run
        The log.
    path : str or os.PathLike
        The ``.rrd`` to write (atomically: complete or untouched).
    review : calib.review.RunReview
        Its motion and navigations (:func:`calib.review.review_run`): viz
        only logs what it is given.
    sequence : calib.sequence.Sequence, optional
        The sequence the run followed: names the positions and flips, and
        gives the gimbal angles when the run has no encoder columns.
    result : calib.result.CalibrationResult, optional
        Adds the results bars (the review carries its navigation).
    truth : calib.sim.Truth, optional
        Adds the errors against the truth; its mounting rotation places the base.
    name : str, optional
        Recording name (default: the run's source).

    Returns
    -------
    Summary
        Entities and row counts, notes, where the scene came from.
    """
    n = run.n_samples
    lat_deg, g, dt = review.latitude_deg, review.gravity_mps2, review.dt
    t_rel = run.time_s - review.t0
    dtheta, dv = run.dtheta_rad, run.dv_mps
    rid = _recording_id(
        run.time_s[:: max(1, n // 1000)],
        dtheta,
        dv,
        None if result is None else result.values,
        None if sequence is None else sequence.name,
    )
    w = _Writer(path, rid, name or Path(run.source).name, run_blueprint(float(t_rel[-1]), result is not None))
    try:
        for note in review.notes:
            w.note(note)
        moving, nav_before, nav_after = review.moving, review.before, review.after
        _log_residuals(w, t_rel, review)

        block = _log_signals(w, run, t_rel, dt)

        # Events: the sequence's nominal time line, else the gyros.
        events = (
            sequence_events(sequence) if sequence is not None else motion_events(t_rel, dt, dtheta, moving)
        )

        # The scene: gimbal angles from encoders, else the sequence, else navigation.
        keep = scene_indices(t_rel, dtheta)
        t_scene = t_rel[keep]
        nav_best = nav_after if nav_after is not None else nav_before
        angles, C_start, R_mount, scene_source, mount_source = _scene_frames(
            run, keep, t_scene, sequence, result, truth, nav_best, nav_after is not None, w
        )
        _log_scene(w, t_scene, angles, R_mount, C_start, g, events)
        if nav_after is not None and scene_source.startswith(("encoders", "sequence")):
            C_scene = R_mount @ C_start @ _gimbal_matrix(angles)
            _log_attitude_error(w, t_scene, nav_after.C_b_n[keep + 1], C_scene)
        if result is not None:
            _log_results(w, result, truth)
        w.summary.scene_source, w.summary.mount_source = scene_source, mount_source
        w.static(
            "about",
            w.rr.TextDocument(
                _about_run(
                    run,
                    n,
                    t_rel,
                    block,
                    len(keep),
                    sequence,
                    result,
                    truth,
                    scene_source,
                    mount_source,
                    lat_deg,
                    g,
                    w.summary.notes,
                    review,
                ),
                media_type="text/markdown",
            ),
        )
    except BaseException:
        w.abort()
        raise
    return w.commit()


def _log_signals(w: _Writer, run, t_rel: np.ndarray, dt: np.ndarray) -> int:
    """Raw gyro rates and specific force as block means; returns the block length."""
    block = max(1, int(round(run.sample_rate_hz / SIGNAL_RATE_HZ)))
    t_sig, rate = block_means(t_rel, dt, run.dtheta_rad, block)
    _, force = block_means(t_rel, dt, run.dv_mps, block)
    w.series("signals/gyro_dps", t_sig, np.degrees(rate), "xyz", AXIS_COLORS)
    w.series("signals/accel_mps2", t_sig, force, "xyz", AXIS_COLORS)
    return block


def _log_attitude_error(w: _Writer, t_scene: np.ndarray, C_nav: np.ndarray, C_scene: np.ndarray) -> None:
    """The calibrated navigation's attitude against the scene's (rotation vector, arcsec)."""
    from calib.transform import dcm_to_rotvec

    err = dcm_to_rotvec(np.einsum("nij,nkj->nik", C_nav, C_scene))
    w.series("attitude/nav_minus_gimbal_arcsec", t_scene, err / P.ARCSEC, "ENU", AXIS_COLORS)


def _log_residuals(w: _Writer, t_rel: np.ndarray, review) -> None:
    """Velocity errors before and after calibration (every sample) and the predicted envelope."""
    if review.before is not None:
        w.series("residuals/before/velocity_mps", t_rel, review.before.v_n[1:], "ENU", AXIS_COLORS)
    if review.after is not None:
        w.series("residuals/after/velocity_mps", t_rel, review.after.v_n[1:], "ENU", AXIS_COLORS)
    if review.noise_sigma_v is not None:
        s3 = 3.0 * review.noise_sigma_v
        w.series(
            "residuals/after/noise_3sigma_mps",
            review.noise_time,
            np.c_[s3, -s3],
            [f"{sign}3σ {a}" for sign in "+-" for a in "ENU"],
            ENVELOPE_COLORS * 2,
        )


def _scene_frames(run, keep, t_scene, sequence, result, truth, nav, calibrated, w):
    """Gimbal angles (rad), C_start, R_mount and where they came from, for the run's scene.

    Encoder and sequence angles are relative to the sequence's start attitude,
    placed by the mounting rotation (truth, else estimated from the result's
    initial attitude, else identity). Without a sequence the start attitude is
    the measured one (the navigation's first attitude, mounting included).
    """
    from calib.sequence import nominal_attitude, timeline

    if run.gimbal_deg is not None:
        angles = np.radians(run.gimbal_deg[keep])
        source = "encoders (the run's outer_deg, middle_deg, inner_deg columns)"
    elif sequence is not None:
        angles = _gimbal_from_attitudes(sequence.C_start, nominal_attitude(timeline(sequence), t_scene))
        source = f"sequence {sequence.name!r} (nominal attitude, decomposed and unwrapped)"
    elif nav is not None:
        angles = _gimbal_from_attitudes(nav.C_b_n[0], nav.C_b_n[keep + 1])
        source = (
            "navigation attitude after calibration"
            if calibrated
            else "navigation attitude before calibration (coarse alignment)"
        )
    else:
        angles = np.zeros((len(keep), 3))
        source = "none (no encoders, sequence or alignment): the IMU stays at its start"
        w.note("nothing gives the attitude: the IMU is drawn at identity")
    if sequence is not None:
        C_start = sequence.C_start
        if truth is not None:
            return angles, C_start, truth.R_setup, source, "truth file (setup rotation)"
        if result is not None:
            return (
                angles,
                C_start,
                result.C_b_n0 @ C_start.T,
                source,
                "estimated: the result's initial attitude times C_start^T",
            )
        return angles, C_start, np.eye(3), source, "nominal (identity)"
    if nav is not None:
        return (
            angles,
            nav.C_b_n[0],
            np.eye(3),
            source,
            "included in the measured start attitude (no sequence)",
        )
    return angles, np.eye(3), np.eye(3), source, "unknown (identity)"


def _about_envelope(review) -> list[str]:
    if review.noise_sigma_v is None:
        return []
    return [
        "",
        "## Noise envelope",
        "",
        f"- residuals/after/noise_3sigma_mps: ±3σ of the velocity error that the noise of profile "
        f"{review.noise_profile!r} (ARW, VRW, Gauss-Markov drift) builds up at rest, propagated "
        f"with the fit's own error-state model; {len(review.noise_time)} rows (1 s at rest, "
        "0.1 s turning).",
        "- It starts at zero: the navigation starts at zero velocity from the fit's initial "
        "attitude. Left out: the uncertainty of that attitude (a g·phi0·t ramp) and of the 21 "
        "parameters; the fit absorbs part of the noise, so a good run stays well inside.",
    ]


def _about_run(
    run,
    n,
    t_rel,
    block,
    n_scene,
    sequence,
    result,
    truth,
    scene_source,
    mount_source,
    lat_deg,
    g,
    notes,
    review,
) -> str:
    fs = run.sample_rate_hz
    lines = (
        [
            f"# Run {run.source}",
            "",
            f"- {n} samples at {fs:g} Hz, {t_rel[-1]:.1f} s; latitude {lat_deg:g} deg, gravity {g:.6f} m/s^2",
            f"- sequence: {sequence.name if sequence is not None else 'none (flips found from the gyros)'}",
            f"- result: {'yes, profile ' + result.profile if result is not None else 'none'}; "
            f"truth: {'yes' if truth is not None else 'none'}",
            "",
            "## Time line",
            "",
            f"`time` = seconds since the first sample starts (`time_s - {run.time_s[0] - t_rel[0]:.9g}`).",
            "",
            "## Rates (what is decimated)",
            "",
            f"- residuals/before, residuals/after: FULL rate, one row per sample at its end time "
            f"({n} rows each; the navigation's initial zero at time 0 is not logged).",
            f"- signals/*: DECIMATED for display: means over blocks of {block} samples "
            f"({fs / block:g} Hz), i.e. sum(increments) / sum(dt), stamped at the block middle.",
            f"- world/... transforms, attitude/*, sequence/position: DECIMATED: {n_scene} rows, one per "
            f"1/{SCENE_RATE_HZ:g} s and one per {SCENE_STEP_DEG:g} deg turned (gyros).",
        ]
        + _about_envelope(review)
        + [
            "",
            "## Scene",
            "",
            "- IMU attitude = R_mount C_start R_Z(outer) R_X(middle) R_Y(inner).",
            f"- gimbal angles from: {scene_source}",
            f"- R_mount from: {mount_source}",
            "- rings: outer (orange) about start-Z, middle (grey) about X, inner (blue) about Y;"
            " body axes X red, Y green, Z blue; ENU axes in the corner; the purple arrow is gravity.",
        ]
    )
    if notes:
        lines += ["", "## Notes", ""] + [f"- {x}" for x in notes]
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# Analysis recording


def _analysis_table(obs, seq) -> str:
    sig = P.from_si(obs.sigma)
    ratio = obs.ratio
    lines = [
        f"# Observability of {seq.name}",
        "",
        f"duration {obs.duration_s:.0f} s ({obs.duration_s / 60:.1f} min), profile "
        f"{obs.profile}, mounting rotation {np.degrees(obs.setup_rotvec).round(3).tolist()} deg, "
        f"rank {obs.rank} of {P.N_PARAMS}",
        "",
        "| # | name | unit | sigma | requirement | 3 sigma / req |",
        "|---|---|---|---|---|---|",
    ]
    for p in P.PARAMETERS:
        i = p.index
        r = (
            "unobservable"
            if not np.isfinite(ratio[i])
            else (f"{ratio[i]:.2f}{' MISS' if ratio[i] > 1 else ''}")
        )
        lines.append(f"| {i} | {p.name} | {p.unit} | {sig[i]:.3g} | {p.requirement:g} | {r} |")
    if obs.rank == P.N_PARAMS:
        name, worst = obs.worst
        lines += ["", f"worst 3 sigma / requirement: {worst:.2f} ({name})"]
        pairs = obs.correlated_pairs()
        if pairs:
            lines += [
                "",
                "correlated pairs (|rho| > 0.9): " + ", ".join(f"{a}/{b} {r:+.3f}" for a, b, r in pairs),
            ]
    else:
        lines += ["", "UNOBSERVABLE directions:"] + [f"- {u}" for u in obs.unobservable]
    return "\n".join(lines)


def analysis_blueprint(duration_s: float):
    """The layout an analysis recording opens with."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(_scene_view("world", "sequence (nominal)"), _events_view(), row_shares=[3, 1]),
            rrb.Spatial3DView(
                origin="positions",
                name="rest positions",
                eye_controls=rrb.EyeControls3D(
                    position=(GALLERY_STEP, -GALLERY_STEP - 23.0, 34.0),
                    look_target=(GALLERY_STEP, -GALLERY_STEP, 0.0),
                    eye_up=(0.0, 0.0, 1.0),
                ),
            ),
            rrb.Vertical(
                _bars_view("analysis/ratio", "3 sigma / requirement"),
                _matrix_view("analysis/correlation", "correlation (blue -1, red +1)"),
            ),
            rrb.Tabs(
                rrb.TextDocumentView(origin="analysis/table", name="analysis"),
                rrb.TextDocumentView(origin="about", name="about"),
            ),
            column_shares=[3, 3, 3, 3],
        ),
        *_panels(),
    )


def record_analysis(
    obs, seq, path: str | os.PathLike, *, gravity_mps2: float | None = None, name: str | None = None
) -> Summary:
    """Write a rerun recording of a sequence's observability analysis.

    Parameters
    ----------
    obs : seqdesign.observability.Observability
    seq : calib.sequence.Sequence
    path : str or os.PathLike
        The ``.rrd`` to write (atomically).
    gravity_mps2 : float, optional
        Only labels the gravity arrow (default: WGS-84 at the sequence's site or 40 deg).
    name : str, optional
        Recording name (default ``analysis of <sequence>``).

    Returns
    -------
    Summary
    """
    from calib.sequence import nominal_attitude, rest_positions, timeline
    from calib.transform import rotvec_to_dcm

    rid = _recording_id("analysis", seq.name, obs.information, obs.setup_rotvec)
    w = _Writer(path, rid, name or f"analysis of {seq.name}", analysis_blueprint(seq.duration_s))
    try:
        rr = w.rr
        lat = math.radians(seq.latitude_deg if seq.latitude_deg is not None else 40.0)
        g = (
            gravity_mps2
            if gravity_mps2 is not None
            else earth.gravity(lat, seq.height_m if seq.height_m is not None else 0.0)
        )
        tl = timeline(seq)
        t_scene = _nominal_scene_times(tl)
        angles = _gimbal_from_attitudes(seq.C_start, nominal_attitude(tl, t_scene))
        R_mount = rotvec_to_dcm(np.asarray(obs.setup_rotvec, dtype=float))
        events = sequence_events(seq)
        _log_scene(w, t_scene, angles, R_mount, seq.C_start, g, events)

        _log_gallery(w, rest_positions(seq), R_mount)

        ratio = np.where(np.isfinite(obs.ratio), obs.ratio, np.nan)
        _labelled_bars(w, "analysis/ratio", ratio, (90, 170, 230), "1 = requirement")
        _labelled_bars(
            w,
            "analysis/sigma_over_requirement",
            np.where(np.isfinite(obs.sigma), obs.sigma, np.nan) / obs.requirements.si,
            (120, 200, 120),
            "1 = requirement",
        )
        if obs.covariance is not None:
            _labelled_matrix(w, "analysis/correlation", obs.correlation)
        else:
            w.note("rank deficient: no covariance, no correlation matrix")
        w.static("analysis/table", rr.TextDocument(_analysis_table(obs, seq), media_type="text/markdown"))
        w.summary.scene_source = f"sequence {seq.name!r} (nominal attitude, decomposed)"
        w.summary.mount_source = "the analysis's mounting rotation"
        w.static(
            "about",
            rr.TextDocument(_about_analysis(seq, len(t_scene), w.summary.notes), media_type="text/markdown"),
        )
    except BaseException:
        w.abort()
        raise
    return w.commit()


def _nominal_scene_times(tl) -> np.ndarray:
    """Nominal time line: SCENE_RATE_HZ, plus every SCENE_STEP_DEG during flips."""
    times = [np.arange(0.0, tl.duration_s, 1.0 / SCENE_RATE_HZ), [tl.duration_s]]
    for a, b, rate in zip(tl.t0, tl.t1, tl.rate):
        if rate != 0.0:
            m = int(math.ceil(abs(math.degrees(rate)) * (b - a) / SCENE_STEP_DEG))
            times.append(np.linspace(a, b, m + 1))
    return np.unique(np.concatenate(times))


def _log_gallery(w: _Writer, positions, R_mount: np.ndarray) -> None:
    """The rest positions side by side, three to a row, each labelled with where X, Y, Z point."""
    rr = w.rr
    for p in positions:
        k = p.number - 1
        where = [GALLERY_STEP * (k % 3), -GALLERY_STEP * (k // 3), 0.0]
        base = f"positions/p{p.number}"
        w.static(
            base,
            rr.Transform3D(translation=where, mat3x3=R_mount @ p.C_b_n),
            rr.Boxes3D(
                half_sizes=[IMU_HALF_SIZE],
                colors=[(235, 200, 80)],
                fill_mode="solid",
                labels=[f"{p.number}: X {p.directions[0]}, Y {p.directions[1]}, Z {p.directions[2]}"],
            ),
        )
        w.static(
            f"{base}/axes",
            rr.Arrows3D(vectors=np.eye(3) * 1.3, labels=["X", "Y", "Z"], colors=AXIS_COLORS, radii=0.04),
        )


def _about_analysis(seq, n_scene: int, notes) -> str:
    return "\n".join(
        [
            f"# Analysis of {seq.name}",
            "",
            "`time` = seconds along the sequence's nominal time line.",
            f"- world/... transforms: {n_scene} rows, {SCENE_RATE_HZ:g} Hz and every "
            f"{SCENE_STEP_DEG:g} deg during flips.",
            "- positions/p<k>: the IMU at rest position k (gallery, static).",
            "- analysis/ratio: 3 sigma / requirement; bars named, in spec order (the table's #).",
            "- analysis/correlation: 21 x 21, rows and columns named, in spec order; blue -1, red +1.",
        ]
        + [f"- note: {x}" for x in notes]
    )


# ---------------------------------------------------------------------------
# Reading back (used by the tests and the README picture)


def read_recording(path: str | os.PathLike) -> dict[str, list]:
    """Every chunk of an ``.rrd``'s recording, as pyarrow record batches by entity path.

    Uses rerun's own reader (``rerun.chunk.RrdReader``). Entity paths are
    returned without their leading ``/``.
    """
    from rerun.chunk import RrdReader

    out: dict[str, list] = {}
    for chunk in RrdReader(str(path)).stream():
        out.setdefault(chunk.entity_path.lstrip("/"), []).append(chunk.to_record_batch())
    return out
