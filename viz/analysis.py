"""A sequence's observability analysis in a recording: its table, the rest positions' gallery."""

from __future__ import annotations

import math

import numpy as np

from calib import params as P

from .rrd import Writer
from .scene import AXIS_COLORS, GALLERY_STEP, IMU_HALF_SIZE, SCENE_RATE_HZ, SCENE_STEP_DEG


def analysis_table(obs, seq) -> str:
    """The analysis as a markdown table: sigma, requirement and ratio per parameter, then the verdict."""
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


def nominal_scene_times(tl) -> np.ndarray:
    """Nominal time line: SCENE_RATE_HZ, plus every SCENE_STEP_DEG during flips."""
    times = [np.arange(0.0, tl.duration_s, 1.0 / SCENE_RATE_HZ), [tl.duration_s]]
    for a, b, rate in zip(tl.t0, tl.t1, tl.rate):
        if rate != 0.0:
            m = int(math.ceil(abs(math.degrees(rate)) * (b - a) / SCENE_STEP_DEG))
            times.append(np.linspace(a, b, m + 1))
    return np.unique(np.concatenate(times))


def log_gallery(w: Writer, positions, R_mount: np.ndarray) -> None:
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


def about_analysis(seq, n_scene: int, notes) -> str:
    """The ``about`` document of an analysis recording: time line, entities, notes."""
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
