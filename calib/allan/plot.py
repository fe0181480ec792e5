"""The PNG of ``profile fit``: each axis' Allan deviation, its fit, and the profile's model."""

from __future__ import annotations

import io

import numpy as np

from calib.errors import CalibError
from calib.io.files import atomic_write_bytes
from calib.model.params import DEG_PER_HOUR, MICRO_G

from .noise_terms import model_avar

AXES = ("x", "y", "z")


def plot_allan(fit, path) -> None:
    """PNG of the six Allan deviations with their fits and the profile's white noise and GM.

    Parameters
    ----------
    fit : calib.allan.profile_fit.ProfileFit
    path : str or Path
        The PNG to write.

    Each axis: the measured deviation and its 68 % interval (dots, band), the fitted
    terms (solid over the fitted range, dotted beyond it); the profile's white
    noise and one GM (black, dashed over the range it was fitted to).
    """
    try:
        import matplotlib
    except ImportError:
        raise CalibError(
            "matplotlib is not installed",
            str(path),
            "pip install '.[plot]', or write no plot (the CLI's --plot)",
        ) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5), constrained_layout=True)
    panels = (
        ("gyro", fit.gyro_curves, fit.gyro, fit.gyro_profile, DEG_PER_HOUR, "deg/h"),
        ("accelerometer", fit.accel_curves, fit.accel, fit.accel_profile, MICRO_G, "ug"),
    )
    for ax, (title, curves, fits, prof, unit, label) in zip(axes, panels, strict=True):
        for j, (c, f, colour) in enumerate(zip(curves, fits, ("C0", "C1", "C2"), strict=True)):
            ax.fill_between(c.tau_s, c.ci_low / unit, c.ci_high / unit, color=colour, alpha=0.2)
            ax.loglog(c.tau_s, c.adev / unit, "o", ms=3, color=colour, label=f"{AXES[j]} measured")
            inside = (c.tau_s >= f.fit_tau_s[0]) & (c.tau_s <= f.fit_tau_s[1])
            model = f.model_adev(c.tau_s) / unit
            ax.loglog(c.tau_s, np.where(inside, np.nan, model), ":", color=colour, lw=1)
            lo, hi = f.fit_ratio
            ax.loglog(
                c.tau_s[inside],
                model[inside],
                "-",
                color=colour,
                lw=1.2,
                label=f"{AXES[j]} fit ({lo:.2f}-{hi:.2f})",
            )
        if prof.sigma > 0 or prof.tau_s[1] > 0:
            tau = np.geomspace(prof.tau_s[0], prof.tau_s[1], 50)
            terms = {
                "N": (prof.white,),
                **({"GM": (prof.sigma, prof.correlation_s)} if prof.sigma > 0 else {}),
            }
            ax.loglog(
                tau,
                np.sqrt(model_avar(tau, terms)) / unit,
                "--",
                color="k",
                lw=1.5,
                label=f"profile: white + one GM ({prof.ratio[0]:.2f}-{prof.ratio[1]:.2f} of the worst axis)",
            )
        ax.set(
            title=f"{title}: Allan deviation, {fit.name}", xlabel="tau, s", ylabel=f"Allan deviation, {label}"
        )
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(
            fontsize=7,
            ncol=2,
            title="band: 68 % interval; fit solid over its range (fit/measured), dotted beyond",
            title_fontsize=7,
        )
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buffer.getvalue())
