"""A hand design as files a person uses: the pose list (TOML) and a printable protocol.

The protocol is a numbered list, one pose per line: which face, edge or corner goes down, how
long to hold it, and how to get there; with a PNG page of pictures (the unit in each pose, its
body axes drawn) when matplotlib is installed (the ``plot`` extra).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.hand.poses import PoseList
from calib.io.files import atomic_write_text

AXIS_NAMES = "xyz"


def describe_up(up: np.ndarray) -> str:
    """A sentence on how to place the unit so that body ``up`` points up."""
    signs = [(i, 1 if v > 0 else -1) for i, v in enumerate(up) if abs(v) > 1e-6]
    down = " and ".join(f"{'-' if s > 0 else '+'}{AXIS_NAMES[i]}" for i, s in signs)
    up_name = "".join(f"{'+' if s > 0 else '-'}{AXIS_NAMES[i]}" for i, s in signs)
    if len(signs) == 1:
        return f"on its {down} face ({up_name} up)"
    if len(signs) == 2:
        return (
            f"on the edge between its {down} faces ({up_name} up, tilted 45°: lean it in a corner or a wedge)"
        )
    return f"on the corner of its {down} faces ({up_name} up: a cup or a fixture holds it)"


def up_name(up: np.ndarray) -> str:
    """``[1, 1, 0] / sqrt(2)`` -> ``"+x+y"``."""
    return "".join(f"{'+' if v > 0 else '-'}{AXIS_NAMES[i]}" for i, v in enumerate(up) if abs(v) > 1e-6)


def pose_toml(poses: PoseList, header: str = "") -> str:
    """The pose list as the file ``analyze --by-hand`` reads."""
    lines = [f"# {line}" for line in header.splitlines()] + [
        f'name = "{poses.name}"',
        f"first_rest_s = {float(poses.hold_s[0]):.6g}",
        f"hold_s = {float(np.median(poses.hold_s[1:])):.6g}",
        f"move_s = {float(poses.move_s[0]) if len(poses.move_s) else 3.0:.6g}",
    ]
    typical = float(np.median(poses.hold_s[1:]))
    for k, up in enumerate(poses.up):
        lines += [
            "",
            "[[pose]]",
            f'up = "{up_name(up)}"' if np.sum(np.abs(up) > 1e-6) == 1 else f"up = {_vector(up)}",
        ]
        if k > 0 and abs(poses.hold_s[k] - typical) > 1e-9:
            lines.append(f"hold_s = {float(poses.hold_s[k]):.6g}")
    return "\n".join(lines) + "\n"


def _vector(up: np.ndarray) -> str:
    v = np.where(np.abs(up) > 1e-6, np.sign(up), 0.0)
    return "[" + ", ".join(f"{int(x)}" for x in v) + "]"


def protocol_markdown(poses: PoseList, summary: str, picture: str | None = None) -> str:
    """The numbered protocol a person follows with the unit in hand."""
    lines = [
        f"# Calibration by hand: {poses.name}",
        "",
        summary,
        "",
        "Mark the unit's body axes on its case (+x, +y, +z) before you start. Between poses, pick the",
        f"unit up, turn it over to the next pose and put it down within about {poses.move_s[0]:g} s; then",
        "take your hands off it and keep the table still until the hold is over.",
        "",
    ]
    if picture:
        lines += [f"![The poses]({picture})", ""]
    for k, up in enumerate(poses.up):
        what = "Start the log. Put the unit" if k == 0 else "Put it"
        lines.append(f"{k + 1}. {what} {describe_up(up)}. Hold still {poses.hold_s[k]:.0f} s.")
    lines += ["", f"Stop the log. Total {poses.duration_s / 60:.1f} min."]
    return "\n".join(lines) + "\n"


def write_protocol(poses: PoseList, path: str | Path, summary: str) -> list[Path]:
    """The protocol (Markdown) and, with matplotlib, its page of pictures beside it (PNG)."""
    path = Path(path)
    written = []
    picture = None
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        pass
    else:
        png = path.with_suffix(".png")
        pose_pictures(poses, png)
        picture = png.name
        written.append(png)
    atomic_write_text(path, protocol_markdown(poses, summary, picture))
    return [path, *written]


def pose_pictures(poses: PoseList, path: Path) -> None:
    """One small 3D picture per pose: the unit's box in the pose, its body axes, the table below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    C = poses.attitudes()
    n = len(C)
    cols = 6
    rows = -(-n // cols)
    fig = plt.figure(figsize=(2.2 * cols, 2.3 * rows))
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * np.array(
        [0.9, 0.6, 0.35]
    )
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    for k in range(n):
        ax = fig.add_subplot(rows, cols, k + 1, projection="3d")
        pts = corners @ C[k].T
        pts[:, 2] -= pts[:, 2].min()
        for a, b in edges:
            ax.plot(*pts[[a, b]].T, color="0.3", lw=0.8)
        centre = pts.mean(axis=0)
        for i, color in enumerate(("tab:red", "tab:green", "tab:blue")):
            tip = centre + C[k][:, i] * 1.1
            ax.plot(*np.array([centre, tip]).T, color=color, lw=2)
            ax.text(*tip, AXIS_NAMES[i], color=color, fontsize=8)
        ax.plot([-1.2, 1.2, 1.2, -1.2, -1.2], [-1.2, -1.2, 1.2, 1.2, -1.2], [0] * 5, color="0.7", lw=0.6)
        ax.set_xlim(-1.2, 1.2)
        ax.set_ylim(-1.2, 1.2)
        ax.set_zlim(0, 2.0)
        ax.set_axis_off()
        ax.set_title(f"{k + 1}: {up_name(poses.up[k])} up", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
