"""Calibration sequences: an initial attitude, dwells, and flips about body axes.

A sequence file is the TOML of ``docs/formats.md``. In memory a :class:`Sequence`
is expanded into a :class:`Timeline` of segments (rest or constant-rate
rotation) from which the nominal attitude at any time follows exactly.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.io.fields import FORMAT_VERSION, REQUIRED, Fields, check_format_version
from calib.io.files import atomic_write_text, load_toml
from calib.io.kinds import expect
from calib.nav.transform import attitude_from_directions, axis_index, rot_axis

from .rate_profile import RateProfile

DEFAULT_RATE_DPS = 10.0
MIN_RATE_DPS = 1.0  # twice the estimator's motion threshold (0.01 rad/s = 0.57 deg/s)
DEFAULT_DWELL_S = 180.0
DEFAULT_LATITUDE_DEG = 40.0
DEFAULT_HEIGHT_M = 0.0
DEFAULT_SAMPLE_RATE_HZ = 200.0

# The first rest seeds Gauss-Newton by levelling and gyrocompassing (the fit then estimates the
# initial attitude error itself); 8 s levels a navigation-grade unit to ~1e-5 rad. It sits below
# the designs' shortest dwell (10 s) by more than motion detection takes from a rest's ends, so a
# designed sequence whose first dwell is at the minimum still aligns (seqdesign.design checks
# --min-dwell-s against it).
MIN_ALIGN_S = 8.0
FIRST_REST_MARGIN_S = 1.0  # what motion detection may take from the first rest's end, at most


@dataclass(frozen=True)
class Step:
    """One flip: rotate about body ``axis`` by ``angle_deg`` at ``rate_dps``, then rest.

    ``accel_dps2`` (and ``jerk_dps3``) make the move a trapezoid (an S-curve)
    with cruise rate ``rate_dps`` (:mod:`calib.sequence.rate_profile`); ``None`` is
    the constant-rate move of files without them.
    """

    axis: str
    angle_deg: float
    rate_dps: float = DEFAULT_RATE_DPS
    dwell_s: float = DEFAULT_DWELL_S
    accel_dps2: float | None = None
    jerk_dps3: float | None = None

    @property
    def profile(self) -> RateProfile:
        """The move's rate profile in SI (rad/s, rad/s^2, rad/s^3)."""
        return RateProfile(
            rate=math.radians(self.rate_dps),
            accel=math.inf if self.accel_dps2 is None else math.radians(self.accel_dps2),
            jerk=math.inf if self.jerk_dps3 is None else math.radians(self.jerk_dps3),
        )

    @property
    def duration_s(self) -> float:
        if self.accel_dps2 is None:
            return abs(self.angle_deg) / self.rate_dps  # as before profiles, bit for bit
        return self.profile.duration_s(math.radians(self.angle_deg))


@dataclass(frozen=True)
class Sequence:
    """A calibration sequence (see ``docs/formats.md``)."""

    name: str
    start: tuple[str, str, str]
    steps: tuple[Step, ...]
    initial_dwell_s: float = DEFAULT_DWELL_S
    description: str = ""
    latitude_deg: float | None = None
    height_m: float | None = None
    provenance: dict = field(default_factory=dict, compare=False)

    @property
    def C_start(self) -> np.ndarray:
        """Nominal start attitude ``C_b_n`` (before the base mounting rotation)."""
        return attitude_from_directions(*self.start)

    @property
    def duration_s(self) -> float:
        return self.initial_dwell_s + sum(s.duration_s + s.dwell_s for s in self.steps)

    def with_flip_errors(self, errors_deg: np.ndarray) -> Sequence:
        """The same sequence with each flip's angle off by ``errors_deg[i]`` (same sign convention)."""
        steps = tuple(
            replace(s, angle_deg=s.angle_deg + float(e)) for s, e in zip(self.steps, errors_deg, strict=True)
        )
        return replace(self, steps=steps)

    def to_toml_dict(self) -> dict:
        d = {
            "format_version": FORMAT_VERSION,
            "name": self.name,
            "description": self.description,
            "start": list(self.start),
            "initial_dwell_s": self.initial_dwell_s,
        }
        if self.latitude_deg is not None:
            d["latitude_deg"] = self.latitude_deg
        if self.height_m is not None:
            d["height_m"] = self.height_m
        d["step"] = [_step_dict(s) for s in self.steps]
        if self.provenance:
            d["provenance"] = dict(self.provenance)
        return d


def _step_dict(s: Step) -> dict:
    d = {"axis": s.axis, "angle_deg": s.angle_deg, "rate_dps": s.rate_dps, "dwell_s": s.dwell_s}
    if s.accel_dps2 is not None:
        d["accel_dps2"] = s.accel_dps2
    if s.jerk_dps3 is not None:
        d["jerk_dps3"] = s.jerk_dps3
    return d


# ---------------------------------------------------------------------------
# Reading and writing


def _number(table: dict, key: str, where: str, default=None, positive=False, nonnegative=False) -> float:
    """A finite number from a sequence table (the shared validator, :mod:`calib.io.fields`)."""
    value = Fields(table, where).number(
        key,
        REQUIRED if default is None else float(default),
        positive=positive,
        low=0.0 if nonnegative else None,
    )
    return float(value)


SEQUENCE_KEYS = (
    "format_version",
    "name",
    "description",
    "start",
    "initial_dwell_s",
    "latitude_deg",
    "height_m",
    "step",
    "provenance",
    "accel_dps2",
    "jerk_dps3",
)
STEP_KEYS = ("axis", "angle_deg", "rate_dps", "dwell_s", "accel_dps2", "jerk_dps3")


# A key named as a quantity in a unit (wait_s, speed_dps) is a setting: run without it, the
# sequence would play the defaults (a 180 s dwell, 10 deg/s) while the file says otherwise.
SETTING_SUFFIXES = ("_s", "_min", "_h", "_deg", "_rad", "_dps", "_dps2", "_dps3", "_radps", "_m", "_hz")


def _check_keys(table: dict, known, kind: str, where: str, every_key_sets: bool = False) -> None:
    """Refuse a near miss of a known key and a setting the tool does not read; warn about any other key.

    ``every_key_sets``: the table holds settings alone (a ``[[step]]`` is its motion), so
    any key it does not read is refused.
    """
    fields = Fields(table, where)
    notes = fields.check_keys(known, kind)  # near misses refused first, naming the closest
    for key in table:
        if key in known or not (every_key_sets or key.endswith(SETTING_SUFFIXES)):
            continue
        dwell = "; a rest's length is 'dwell_s' in its [[step]]" if key.endswith("_s") else ""
        raise CalibError(
            "not a key the tool reads, and it would change the run (the default would be played instead)",
            fields.here(key),
            f"use the {kind} keys: {', '.join(known)}{dwell}",
        )
    for message in notes:
        warnings.warn(message, stacklevel=3)


def _profile_keys(table: dict, where: str, default: tuple) -> tuple[float | None, float | None]:
    """``accel_dps2`` and ``jerk_dps3`` of a step (or the file's defaults): None means unlimited."""
    accel = _number(table, "accel_dps2", where, positive=True) if "accel_dps2" in table else default[0]
    jerk = _number(table, "jerk_dps3", where, positive=True) if "jerk_dps3" in table else default[1]
    if jerk is not None and accel is None:
        raise CalibError(
            "'jerk_dps3' without 'accel_dps2'",
            where,
            "give the acceleration limit too (an S-curve needs both)",
        )
    return accel, jerk


def sequence_from_dict(doc: dict, where: str) -> Sequence:
    """Validate a parsed sequence TOML document and build a :class:`Sequence`."""
    check_format_version(doc, "sequence", where)
    _check_keys(doc, SEQUENCE_KEYS, "sequence", where)
    start = doc.get("start")
    if not isinstance(start, list) or len(start) != 3 or not all(isinstance(s, str) for s in start):
        raise CalibError(
            '\'start\' must be a list of three directions, e.g. ["east", "up", "south"]',
            f"{where}: key 'start'",
        )
    attitude_from_directions(start[0], start[1], start[2], where=f"{where}: key 'start'")
    name = doc.get("name", Path(where).stem)
    if not isinstance(name, str) or not name:
        raise CalibError("'name' must be a non-empty string", f"{where}: key 'name'")
    description = doc.get("description", "")
    if not isinstance(description, str):
        raise CalibError("'description' must be a string", f"{where}: key 'description'")
    initial_dwell = _number(doc, "initial_dwell_s", where, DEFAULT_DWELL_S, positive=True)
    latitude = None
    if "latitude_deg" in doc:
        latitude = _number(doc, "latitude_deg", where)
        if not -90.0 < latitude < 90.0:
            raise CalibError(
                f"latitude_deg = {latitude} is outside (-90, 90)", f"{where}: key 'latitude_deg'"
            )
    height = _number(doc, "height_m", where) if "height_m" in doc else None
    if height is not None and not -1000.0 <= height <= 10000.0:
        raise CalibError(
            f"height_m = {height} is outside [-1000, 10000] m",
            f"{where}: key 'height_m'",
            "give the ellipsoidal height of the site",
        )
    default_profile = _profile_keys(doc, where, (None, None))
    raw_steps = doc.get("step", [])
    if not isinstance(raw_steps, list):
        raise CalibError("'step' must be an array of tables ([[step]])", where)
    steps = [
        _step_from_dict(raw, f"{where}: step {i}", default_profile)
        for i, raw in enumerate(raw_steps, start=1)
    ]
    if not steps:
        raise CalibError("a sequence needs at least one [[step]]", where)
    provenance = doc.get("provenance", {})
    seq = Sequence(
        name=name,
        start=tuple(s.lower() for s in start),
        steps=tuple(steps),
        initial_dwell_s=initial_dwell,
        description=description,
        latitude_deg=latitude,
        height_m=height,
        provenance=provenance if isinstance(provenance, dict) else {},
    )
    if seq.duration_s > 6 * 3600:
        raise CalibError(
            f"sequence lasts {seq.duration_s / 3600:.1f} h; more than 6 h is refused", where, "shorten dwells"
        )
    return seq


def _step_from_dict(raw, here: str, default_profile: tuple) -> Step:
    """One validated ``[[step]]``."""
    if not isinstance(raw, dict):
        raise CalibError("each [[step]] must be a table", here)
    _check_keys(raw, STEP_KEYS, "step", here, every_key_sets=True)
    axis = raw.get("axis")
    if not isinstance(axis, str) or axis.upper() not in ("X", "Y", "Z"):
        raise CalibError(f'axis must be "X", "Y" or "Z", got {axis!r}', here)
    angle = _number(raw, "angle_deg", here)
    if angle == 0.0 or abs(angle) > 3600.0:
        raise CalibError(f"angle_deg = {angle} must be non-zero and within +-3600", here)
    rate = _number(raw, "rate_dps", here, DEFAULT_RATE_DPS, positive=True)
    if rate > 1000.0:
        raise CalibError(f"rate_dps = {rate} is beyond any gimbal (max 1000 deg/s)", here)
    if rate < MIN_RATE_DPS:
        raise CalibError(
            f"rate_dps = {rate} is below {MIN_RATE_DPS:g} deg/s: such a slow turn "
            "cannot be told from rest in the log (flips are detected above "
            "0.57 deg/s)",
            here,
            f"turn at {MIN_RATE_DPS:g} deg/s or faster",
        )
    dwell = _number(raw, "dwell_s", here, DEFAULT_DWELL_S, nonnegative=True)
    accel, jerk = _profile_keys(raw, here, default_profile)
    return Step(axis.upper(), angle, rate, dwell, accel, jerk)


def builtin_sequence_dir() -> Path:
    """Folder of the sequences shipped with the tool."""
    return Path(str(resources.files("sequences")))


def resolve_sequence_path(name_or_path: str | Path) -> Path:
    """A path as given, or the name of a shipped sequence (``paper-9pos``)."""
    p = Path(name_or_path)
    if p.exists():
        return p
    shipped = builtin_sequence_dir() / f"{p.name}.toml"
    if p.suffix == "" and shipped.exists():
        return shipped
    available = ", ".join(sorted(f.stem for f in builtin_sequence_dir().glob("*.toml")))
    raise CalibError(
        f"no sequence file {str(name_or_path)!r}",
        None,
        f"give a path to a .toml file or a shipped name: {available}",
    )


def load_sequence(name_or_path: Sequence | str | Path) -> Sequence:
    """Read a sequence file (or a shipped sequence by name); a :class:`Sequence` is returned as it is."""
    if isinstance(name_or_path, Sequence):
        return name_or_path
    path = resolve_sequence_path(name_or_path)
    expect(path, "sequence")
    doc = load_toml(path)
    return sequence_from_dict(doc, str(path))


def save_sequence(seq: Sequence, path: str | Path) -> None:
    """Write a sequence file atomically."""
    import tomli_w

    atomic_write_text(path, tomli_w.dumps(seq.to_toml_dict()))


# ---------------------------------------------------------------------------
# Timeline


@dataclass(frozen=True)
class Timeline:
    """Segments of a sequence: ``t0[i]..t1[i]`` turning about body ``axis[i]``.

    ``rate[i]`` is the segment's mean rate (rad/s): 0 exactly at rest, so
    ``rate != 0`` means moving. A move is one segment per constant-jerk piece
    of its rate profile (one for a constant-rate move); within segment ``i``
    the angle turned is ``rate0 tau + accel tau^2 / 2 + jerk tau^3 / 6``
    (``tau = t - t0[i]``). ``rate0``/``accel``/``jerk`` may be None: the
    segments then turn at constant rate ``rate``.

    ``C0[i]`` is the nominal attitude at the segment's start (without the base
    mounting rotation). Rest segments have ``rate == 0`` and ``axis == -1``;
    ``position[i]`` numbers rest positions from 1 (0 for rotations) and
    ``step[i]`` is the step index (0-based) that a rotation segment realises.
    """

    t0: np.ndarray
    t1: np.ndarray
    rate: np.ndarray
    axis: np.ndarray
    C0: np.ndarray
    position: np.ndarray
    step: np.ndarray
    C_end: np.ndarray
    rate0: np.ndarray | None = None
    accel: np.ndarray | None = None
    jerk: np.ndarray | None = None

    @property
    def duration_s(self) -> float:
        return float(self.t1[-1])

    @property
    def rest(self) -> np.ndarray:
        return self.rate == 0.0

    def angle(self, seg: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Angle turned (rad) ``tau`` seconds into segments ``seg``."""
        if self.rate0 is None:
            return self.rate[seg] * tau
        assert self.accel is not None and self.jerk is not None  # set together with rate0
        return self.rate0[seg] * tau + 0.5 * self.accel[seg] * tau**2 + self.jerk[seg] * tau**3 / 6.0

    def angular_rate(self, seg: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Rate (rad/s) ``tau`` seconds into segments ``seg``."""
        if self.rate0 is None:
            return self.rate[seg] + 0.0 * tau
        assert self.accel is not None and self.jerk is not None  # set together with rate0
        return self.rate0[seg] + self.accel[seg] * tau + 0.5 * self.jerk[seg] * tau**2

    @property
    def polynomial(self) -> np.ndarray:
        """Per segment, whether the rate varies within it (accelerating or jerking)."""
        if self.accel is None:
            return np.zeros(len(self.t0), dtype=bool)
        return (self.accel != 0.0) | (self.jerk != 0.0)


def _move_rows(t: float, C: np.ndarray, ax: int, step: Step, k: int) -> tuple[list, float]:
    """Timeline rows (one per constant-jerk piece) of a step's move starting at ``t``."""
    if step.accel_dps2 is None:  # constant rate: one segment, exactly as before profiles
        sign = 1.0 if step.angle_deg > 0 else -1.0
        rate = sign * math.radians(step.rate_dps)
        return [(t, t + step.duration_s, rate, ax, C, 0, k, rate, 0.0, 0.0)], t + step.duration_s
    pc = step.profile.pieces(math.radians(step.angle_deg))
    rows = []
    for d, th0, r0, a0, j in zip(pc.duration, pc.theta0, pc.rate0, pc.accel0, pc.jerk, strict=True):
        swept = r0 * d + 0.5 * a0 * d * d + j * d**3 / 6.0
        rows.append((t, t + d, swept / d, ax, C @ rot_axis(ax, th0), 0, k, r0, a0, j))
        t += d
    return rows, t


def timeline(seq: Sequence) -> Timeline:
    """Expand a sequence into rest and rotation segments (zero-length rests dropped)."""
    t, C = 0.0, seq.C_start
    rows = []
    position = 1
    rows.append((t, t + seq.initial_dwell_s, 0.0, -1, C, position, -1, 0.0, 0.0, 0.0))
    t += seq.initial_dwell_s
    for k, s in enumerate(seq.steps):
        ax = axis_index(s.axis)
        move, t = _move_rows(t, C, ax, s, k)
        rows.extend(move)
        C = C @ rot_axis(ax, math.radians(s.angle_deg))
        if s.dwell_s > 0:
            position += 1
            rows.append((t, t + s.dwell_s, 0.0, -1, C, position, k, 0.0, 0.0, 0.0))
            t += s.dwell_s
    cols = list(zip(*rows, strict=True))
    return Timeline(
        t0=np.array(cols[0]),
        t1=np.array(cols[1]),
        rate=np.array(cols[2]),
        axis=np.array(cols[3], dtype=int),
        C0=np.array(cols[4]),
        position=np.array(cols[5], dtype=int),
        step=np.array(cols[6], dtype=int),
        C_end=C,
        rate0=np.array(cols[7]),
        accel=np.array(cols[8]),
        jerk=np.array(cols[9]),
    )


def nominal_attitude(tl: Timeline, t: np.ndarray) -> np.ndarray:
    """Nominal ``C_b_n`` (without mounting rotation) at times ``t``, shape ``(n, 3, 3)``."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    seg = np.clip(np.searchsorted(tl.t1, t, side="left"), 0, len(tl.t0) - 1)
    C = tl.C0[seg].copy()
    moving = tl.rate[seg] != 0.0
    if np.any(moving):
        idx = np.nonzero(moving)[0]
        angle = tl.angle(seg[idx], np.minimum(t[idx], tl.t1[seg[idx]]) - tl.t0[seg[idx]])
        for ax in range(3):
            sel = tl.axis[seg[idx]] == ax
            if np.any(sel):
                C[idx[sel]] = C[idx[sel]] @ rot_axis(ax, angle[sel])
    return C
