"""Labelled charts: rr.BarChart and rr.Tensor carry no category names, so the bars and the
correlation matrix are also drawn in 2D with the parameter names beside them.
"""

from __future__ import annotations

import numpy as np

from calib.model import params as P

from .rrd import Writer

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


def labelled_bars(w: Writer, entity: str, values: np.ndarray, color, guide: str) -> None:
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


def labelled_matrix(w: Writer, entity: str, corr: np.ndarray) -> None:
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
            labels=[
                f"{names[a]} / {names[b]}: {corr[a, b]:+.3f}"
                for a, b in zip(i.ravel(), j.ravel(), strict=True)
            ],
        ),
    )
