"""A sequence's observability analysis in a recording: the figures ``seqdesign analyze``
prints, the mounting drawn, the table and the rest positions' gallery.

Over a mounting box, ``analyze`` prints each parameter's worst sigma and ratio
over the box; a picture (the scene, the gallery, the correlation matrix) is
at one mounting, the one with the largest worst ratio. :class:`AnalysisFigures`
holds both, so the recording shows the printed figures and says which
mounting it draws.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from calib.model import params as P
from calib.model.report import worst

from .rrd import Writer
from .scene import AXIS_COLORS, GALLERY_STEP, IMU_HALF_SIZE, SCENE_RATE_HZ, SCENE_STEP_DEG

if TYPE_CHECKING:
    from calib.analysis.observability import Observability
    from calib.sequence.definition import Sequence


@dataclass(frozen=True)
class AnalysisFigures:
    """What ``seqdesign analyze`` prints, per parameter in spec order, and the mounting drawn.

    Attributes
    ----------
    sequence : calib.sequence.definition.Sequence
    profile, requirements : str
        Names of the noise profile and of the requirement set.
    sigma, requirement, ratio : ndarray, shape (21,)
        Spec units: each parameter's worst sigma over the mounting box (inf:
        unobservable), its requirement, and ``3 sigma / requirement``.
    worst : dict
        ``{"name", "ratio"}``: the largest finite ratio (:func:`calib.model.report.worst`).
    rank : int
        Rank of the information at the nominal mounting.
    unobservable : list of str
        The unobserved directions at the nominal mounting.
    tolerance_deg : float
        Half-width of the mounting box (0: the nominal mounting only).
    mountings : int
        Mountings evaluated over the box.
    searched : bool
        Whether IPOPT refined the worst parameter beyond those mountings.
    drawn : calib.analysis.observability.Observability
        The mounting the scene, the gallery and the correlation matrix show:
        the one with the largest worst ratio.
    """

    sequence: Sequence
    profile: str
    requirements: str
    sigma: np.ndarray
    requirement: np.ndarray
    ratio: np.ndarray
    worst: dict
    rank: int
    unobservable: list
    tolerance_deg: float
    mountings: int
    searched: bool
    drawn: Observability

    @property
    def over(self) -> str:
        """Where the printed figures come from."""
        if self.tolerance_deg == 0:
            return "at the nominal mounting"
        search = " + IPOPT search" if self.searched else ""
        return (
            f"each parameter's worst over +-{self.tolerance_deg:g} deg ({self.mountings} mountings{search})"
        )

    @property
    def drawn_name(self) -> str:
        """The mounting drawn, in two words."""
        return "nominal mounting" if self.tolerance_deg == 0 else "worst mounting"

    @property
    def mounting(self) -> str:
        """The mounting drawn, in words, with its rotation vector in degrees."""
        deg = np.degrees(self.drawn.setup_rotvec).round(3).tolist()
        if self.tolerance_deg == 0:
            return f"the nominal mounting, {deg} deg"
        return f"the worst mounting (largest ratio over the box), {deg} deg"


def analysis_figures(analysis) -> AnalysisFigures:
    """The figures of a ``seqdesign.analysis.Analysis``: its own entries (what it prints) and
    requirements, and its worst mounting to draw.
    """
    entries = analysis.entries()
    rob = analysis.robustness

    def column(key: str) -> np.ndarray:
        return np.array([entries[n][key] for n in P.NAMES], dtype=float)

    return AnalysisFigures(
        sequence=analysis.sequence,
        profile=analysis.profile.name,
        requirements=analysis.requirements.name,
        sigma=column("sigma"),
        requirement=column("requirement"),
        ratio=column("ratio"),
        worst=worst(entries),
        rank=rob.nominal.rank,
        unobservable=list(rob.nominal.unobservable),
        tolerance_deg=rob.tolerance_deg,
        mountings=rob.points,
        searched=rob.searched,
        drawn=rob.worst,
    )


def analysis_table(fig: AnalysisFigures) -> str:
    """The analysis as a markdown table: sigma, requirement and ratio per parameter, then the verdict."""
    seq, sig, ratio = fig.sequence, fig.sigma, fig.ratio
    lines = [
        f"# Observability of {seq.name}",
        "",
        f"duration {seq.duration_s:.0f} s ({seq.duration_s / 60:.1f} min), profile {fig.profile}, "
        f"requirements {fig.requirements}, rank {fig.rank} of {P.N_PARAMS}",
        "",
        f"sigma and 3 sigma / requirement: {fig.over}, as `seqdesign analyze` prints them. "
        f"Drawn (scene, rest positions, correlation): {fig.mounting}.",
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
        lines.append(f"| {i} | {p.name} | {p.unit} | {sig[i]:.3g} | {fig.requirement[i]:g} | {r} |")
    if fig.rank == P.N_PARAMS:
        lines += ["", f"worst 3 sigma / requirement: {fig.worst['ratio']:.2f} ({fig.worst['name']})"]
        pairs = fig.drawn.correlated_pairs()
        if pairs:
            lines += [
                "",
                "correlated pairs (|rho| > 0.9) at the mounting drawn: "
                + ", ".join(f"{a}/{b} {r:+.3f}" for a, b, r in pairs),
            ]
    else:
        lines += ["", "UNOBSERVABLE directions:"] + [f"- {u}" for u in fig.unobservable]
    return "\n".join(lines)


def nominal_scene_times(tl) -> np.ndarray:
    """Nominal time line: SCENE_RATE_HZ, plus every SCENE_STEP_DEG during flips."""
    times: list[np.ndarray | list[float]] = [
        np.arange(0.0, tl.duration_s, 1.0 / SCENE_RATE_HZ),
        [tl.duration_s],
    ]
    for a, b, rate in zip(tl.t0, tl.t1, tl.rate, strict=True):
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


def about_analysis(fig: AnalysisFigures, n_scene: int, notes) -> str:
    """The ``about`` document of an analysis recording: time line, entities, notes."""
    return "\n".join(
        [
            f"# Analysis of {fig.sequence.name}",
            "",
            "`time` = seconds along the sequence's nominal time line.",
            f"- world/... transforms: {n_scene} rows, {SCENE_RATE_HZ:g} Hz and every "
            f"{SCENE_STEP_DEG:g} deg during flips.",
            "- positions/p<k>: the IMU at rest position k (gallery, static).",
            f"- world/base, positions/p<k>, analysis/correlation: drawn at {fig.mounting}.",
            f"- analysis/ratio: 3 sigma / requirement, {fig.over}; bars named, in spec order "
            "(the table's #).",
            "- analysis/correlation: 21 x 21, rows and columns named, in spec order; blue -1, red +1.",
        ]
        + [f"- note: {x}" for x in notes]
    )
