"""Pictures drawn with matplotlib (the optional ``plot`` extra), imported only when asked for."""

from __future__ import annotations

import numpy as np

from calib.analysis.bounds import accel_scale_bound
from calib.errors import CalibError
from calib.io.files import atomic_write_bytes


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


def verify_png(verification, path) -> None:
    """Per parameter, RMS error over the reported and over the predicted sigma; the mean NEES.

    ``verification`` is a :class:`seqdesign.verify.Verification` (read, not imported).
    The band drawn, [0.67, 1.36], is where the RMS of 50 honest runs' z-scores falls for
    each parameter with high probability (chi-square of 50 dof: sqrt(28/50) .. sqrt(92/50)).
    """
    plt = pyplot()
    names = list(verification.to_json().get("parameters", {}))
    fig, ax = plt.subplots(figsize=(11, 4.2))
    if names:
        x = np.arange(len(names))
        ax.axhspan(0.67, 1.36, color="0.9", label="[0.67, 1.36]")
        ax.bar(x - 0.2, verification.rms_over_reported(), 0.4, label="RMS error / sigma each run reported")
        ax.bar(x + 0.2, verification.rms_over_predicted(), 0.4, label="RMS error / analyze's sigma")
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xticks(x, names, rotation=60)
        doc = verification.to_json()["nees"]
        ax.set_title(
            f"{verification.sequence.name}, {len(verification.fitted)} runs: mean NEES {doc['mean']:.2f} "
            f"(99 % band {doc['band_99'][0]:.2f}-{doc['band_99'][1]:.2f})"
        )
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3, fontsize=8)
    ax.set_ylabel("ratio")
    save_png(fig, path)
