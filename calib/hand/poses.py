"""A pose list for a run placed by hand: which face is up in each pose, how long it is held.

The file (TOML, ``docs/by-hand.md``)::

    name = "cube-6"
    first_rest_s = 30        # the first pose is held this long (a static start)
    hold_s = 8               # each pose, unless it says otherwise
    move_s = 3               # a move: lift, turn, put down
    [[pose]]
    up = "+z"                # the body axis that points up ("+x" ... "-z"), or a body vector
    [[pose]]
    up = [1, 1, 0]
    hold_s = 12

A person tips the unit over from one pose to the next: each pose's attitude is the previous
one turned about a horizontal axis until its ``up`` points up (the smallest such turn; a
half-turn is about the nav frame's east). The first pose's heading is arbitrary (0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.io.fields import Fields, check_format_version
from calib.io.files import load_toml
from calib.nav.transform import dcm_to_rotvec, rotvec_to_dcm

from .plan import HandPlan

AXES = {f"{s}{a}": (1.0 if s == "+" else -1.0) * np.eye(3)[i] for s in "+-" for i, a in enumerate("xyz")}
TURN_FRACTION = 0.6  # of a move the turn takes (the rest: reaching, lifting, putting down)
_KEYS = ("name", "format_version", "first_rest_s", "hold_s", "move_s", "pose")


@dataclass(frozen=True)
class PoseList:
    """The poses of a hand-placed run: body up vectors (unit), hold and move times (s)."""

    name: str
    up: np.ndarray  # (K, 3)
    hold_s: np.ndarray  # (K,)
    move_s: np.ndarray  # (K - 1,)

    def attitudes(self) -> np.ndarray:
        """Each pose's body-to-ENU attitude, tipped over from the previous one."""
        C = np.empty((len(self.up), 3, 3))
        C[0] = tip_to(np.eye(3), self.up[0])
        for k in range(1, len(self.up)):
            C[k] = tip_to(C[k - 1], self.up[k])
        return C

    def plan(self) -> HandPlan:
        """The simulator's plan of these poses: fixed-axis turns, no translation."""
        return tipping_plan(self.attitudes(), self.hold_s, self.move_s)

    @property
    def duration_s(self) -> float:
        return float(self.hold_s.sum() + self.move_s.sum())


def tip_to(C: np.ndarray, up_body: np.ndarray) -> np.ndarray:
    """``C`` turned about a horizontal axis until body ``up_body`` points up."""
    u = C @ (up_body / np.linalg.norm(up_body))
    axis = np.cross(u, [0.0, 0.0, 1.0])
    s = float(np.linalg.norm(axis))
    angle = math.atan2(s, u[2])
    if s < 1e-12:
        if u[2] > 0:
            return C
        axis, s = np.array([1.0, 0.0, 0.0]), 1.0  # a half-turn: about east
    return rotvec_to_dcm(axis / s * angle) @ C


def tipping_plan(C_b_n: np.ndarray, hold_s: np.ndarray, move_s: np.ndarray) -> HandPlan:
    """The simulator's plan of rests at ``C_b_n``: each move the smallest turn to the next rest,
    fixed-axis (no wobble) over :data:`TURN_FRACTION` of it, no translation.
    """
    n = len(C_b_n) - 1
    rotvec = dcm_to_rotvec(np.einsum("kji,kjl->kil", C_b_n[:-1], C_b_n[1:])).reshape(n, 3)
    # The plan asks for a wobble axis perpendicular to each turn, even without a wobble.
    helper = np.eye(3)[np.argmin(np.abs(rotvec), axis=1)]
    axis = np.cross(rotvec, helper)
    axis[np.linalg.norm(axis, axis=1) < 1e-12] = [1.0, 0.0, 0.0]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return HandPlan(
        C_b_n, hold_s, move_s, TURN_FRACTION * np.asarray(move_s), np.zeros((n, 3)), np.zeros(n), axis
    )


def load_poses(path: str | Path) -> PoseList:
    """Read and check a pose file (every refusal names the file, the pose and the key)."""
    where = str(path)
    doc = load_toml(path)
    check_format_version(doc, "pose list", where)
    top = Fields(doc, where)
    top.check_keys(_KEYS, "pose list")
    hold = top.number("hold_s", 8.0, positive=True, high=3600.0, unit=" s")
    move = top.number("move_s", 3.0, positive=True, high=600.0, unit=" s")
    first = top.number("first_rest_s", hold, positive=True, high=36000.0, unit=" s")
    poses = doc.get("pose")
    if not isinstance(poses, list) or len(poses) < 2:
        raise CalibError(
            "a pose list needs at least two [[pose]] tables", where, 'add [[pose]] tables with up = "+z" ...'
        )
    ups, holds = [], []
    for k, table in enumerate(poses):
        f = Fields(table, f"{where}: pose {k + 1}")
        f.check_keys(("up", "hold_s"), "pose")
        ups.append(_up(table.get("up"), f))
        holds.append(f.number("hold_s", first if k == 0 else hold, positive=True, high=36000.0, unit=" s"))
    return PoseList(
        str(doc.get("name", Path(path).stem)), np.array(ups), np.array(holds), np.full(len(ups) - 1, move)
    )


def _up(raw, f: Fields) -> np.ndarray:
    fix = 'give the body axis that points up, "+x" ... "-z", or a body vector [x, y, z]'
    if raw is None:
        raise CalibError("missing key 'up'", f.where, fix)
    if isinstance(raw, str):
        if raw.strip().lower() not in AXES:
            raise CalibError(f"'up' = {raw!r} is not an axis", f.here("up"), fix)
        return AXES[raw.strip().lower()]
    v = np.array(f.numbers("up", length=3, fix=fix))
    if np.linalg.norm(v) < 1e-9:
        raise CalibError("'up' is the zero vector", f.here("up"), fix)
    return v / np.linalg.norm(v)
