"""Pictures drawn with matplotlib (the optional ``plot`` extra), imported only when asked for."""

from __future__ import annotations

import numpy as np

from calib.bounds import accel_scale_bound
from calib.errors import CalibError
from calib.fileio import atomic_write_bytes


def pyplot():
    """Matplotlib's pyplot on the file-only Agg backend, or a clear refusal if it is missing."""
    try:
        import matplotlib
    except ImportError:
        raise CalibError(
            "matplotlib is not installed", None, "pip install 'seqdesign[plot]' (or pip install matplotlib)"
        ) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_png(fig, path) -> None:
    """Write a figure atomically (complete or untouched) and close it."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    pyplot().close(fig)
    atomic_write_bytes(path, buf.getvalue())


def pareto_png(report, gravity_mps2: float, path, rate_dps: float | None) -> None:
    """Worst ratio against total time for each design, the paper's point and the bound curve.

    ``report`` is a :class:`seqdesign.search.DesignReport` (read, not imported: the
    pictures sit below the search); ``rate_dps`` the designs' fastest turn, where the
    coloured-noise bound is drawn for a Gauss-Markov profile.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    rows = sorted(report.rows, key=lambda r: r.result.sequence.duration_s)
    t = [r.result.sequence.duration_s / 60 for r in rows]
    ax.plot(
        t,
        [r.result.worst_ratio for r in rows],
        "o-",
        color="#1f77b4",
        label=f"designs ({report.profile.name})",
    )
    for r, x in zip(rows, t, strict=True):
        ax.annotate(
            f"{r.result.worst_ratio:.2f}",
            (x, r.result.worst_ratio),
            textcoords="offset points",
            xytext=(4, 6),
            fontsize=8,
        )
    tmax = max(t + [report.paper_duration_s / 60]) * 1.1
    grid = np.linspace(max(1.0, tmax / 40), tmax, 80)
    ax.plot(
        grid,
        [accel_scale_bound(x * 60, report.profile, gravity_mps2, report.requirements) for x in grid],
        "--",
        color="#d62728",
        label="accelerometer scale-factor bound (white noise)",
    )
    if report.profile.accel_gm_sigma > 0:  # the coloured-noise bound at the gimbal's rate
        ax.plot(
            grid,
            [
                accel_scale_bound(x * 60, report.profile, gravity_mps2, report.requirements, rate_dps)
                for x in grid
            ],
            ":",
            color="#9467bd",
            label=f"same with Gauss-Markov bias, turning at {rate_dps:g} deg/s",
        )
    ax.plot(
        [report.paper_duration_s / 60], [report.paper_worst_ratio], "s", color="#ff7f0e", label="paper-9pos"
    )
    ax.set_yscale("log")
    ax.set_xlabel("total time, min")
    ax.set_ylabel(f"worst 3 sigma / requirement (+-{report.tolerance_deg:g} deg)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    save_png(fig, path)
