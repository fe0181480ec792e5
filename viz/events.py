"""The positions and flips of a recording: rest and flip starts on its time line, as text rows."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.gimbal.encoders import rest_positions
from calib.sequence.definition import timeline

REST, FLIP = "rest", "flip"


@dataclass
class Event:
    """A rest start or a flip start on the recording's time line."""

    time: float
    kind: str  # "rest" or "flip"
    number: int  # position number (rest) or flip number (flip), from 1
    text: str


def position_series(events: list[Event], times: np.ndarray) -> np.ndarray:
    """Rest position number at ``times`` (0 while turning) from the event list."""
    if not events:
        return np.zeros(len(times))
    ev_t = np.array([e.time for e in events])
    value = np.array([e.number if e.kind == REST else 0 for e in events], dtype=float)
    k = np.searchsorted(ev_t, times, side="right") - 1
    return np.where(k >= 0, value[np.clip(k, 0, None)], 0.0)


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
                    REST,
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
                    FLIP,
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
        [Event(0.0, REST, 1, "position 1 (rest, from the gyros)")]
        if (len(starts) == 0 or starts[0] > 0)
        else []
    )
    for k, (a, b) in enumerate(zip(starts, ends, strict=True)):
        rv = dtheta[a:b].sum(axis=0)
        ax = int(np.argmax(np.abs(rv)))
        events.append(
            Event(
                float(time_rel[a] - dt[a]),
                FLIP,
                k + 1,
                f"flip {k + 1}: about body {'XYZ'[ax]} by {math.degrees(rv[ax]):+.2f} deg (integrated gyros)",
            )
        )
        if b < len(time_rel):
            number = len([e for e in events if e.kind == REST]) + 1
            events.append(
                Event(float(time_rel[b] - dt[b]), REST, number, f"position {number} (rest, from the gyros)")
            )
    return events
