"""A calibration in a run recording: the velocity residuals before and after it, and its
estimates against the requirements the result carries (and against the truth).
"""

from __future__ import annotations

import numpy as np

from calib.model import params as P

from .charts import labelled_bars, labelled_matrix
from .rrd import Writer
from .scene import AXIS_COLORS, ENVELOPE_COLORS


def log_residuals(w: Writer, t_rel: np.ndarray, review) -> None:
    """Velocity errors before and after calibration (every sample) and the predicted envelope."""
    if review.before is not None:
        w.series("residuals/before/velocity_mps", t_rel, review.before.v_n[1:], "ENU", AXIS_COLORS)
    if review.after is not None:
        w.series("residuals/after/velocity_mps", t_rel, review.after.v_n[1:], "ENU", AXIS_COLORS)
    if review.noise_sigma_v is not None:
        s3 = 3.0 * review.noise_sigma_v
        w.series(
            "residuals/after/noise_3sigma_mps",
            review.noise_time,
            np.c_[s3, -s3],
            [f"{sign}3σ {a}" for sign in "+-" for a in "ENU"],
            ENVELOPE_COLORS * 2,
        )


def _results_table(result, truth) -> str:
    vals, sig = P.from_si(result.values), P.from_si(result.sigma)
    req = result.requirements
    ratio = req.ratio(result.sigma)
    head = "| # | name | unit | estimate | sigma | 3 sigma / req |"
    rule = "|---|---|---|---|---|---|"
    if truth is not None:
        tv = truth.errors.in_units()
        head += " truth | error | error / req | error / sigma |"
        rule += "---|---|---|---|"
    lines = [
        f"# Calibration result (profile {result.profile or '?'}, requirements {req.name})",
        "",
        f"converged: {result.converged}, iterations {result.iterations}, residual RMS "
        f"{result.residual_rms_mps:.3g} m/s, chi2/dof {result.chi2_per_dof:.3f}",
        "",
        "Bars in results/* are named and follow the # column (spec order).",
        "",
        head,
        rule,
    ]
    for p in P.PARAMETERS:
        i = p.index
        row = (
            f"| {i} | {p.name} | {p.unit} | {vals[i]:.5g} | {sig[i]:.3g} | "
            f"{ratio[i]:.2f}{' MISS' if ratio[i] > 1 else ''} |"
        )
        if truth is not None:
            e = vals[i] - tv[i]
            row += (
                f" {tv[i]:.5g} | {e:+.3g} | {abs(e) / req.values[i]:.2f} | "
                f"{e / sig[i] if sig[i] > 0 else float('nan'):+.2f} |"
            )
        lines.append(row)
    i = int(np.argmax(ratio))
    lines += ["", f"worst 3 sigma / requirement: {ratio[i]:.2f} ({P.NAMES[i]})"]
    return "\n".join(lines)


def log_results(w: Writer, result, truth) -> None:
    """The result's bars (and against the truth), its correlation matrix and its table."""
    rr = w.rr
    # The result carries the requirements it was judged against (--requirements): draw those.
    req = result.requirements
    labelled_bars(w, "results/ratio", req.ratio(result.sigma), (90, 170, 230), "1 = requirement")
    if truth is not None:
        err = result.values - truth.errors.values
        labelled_bars(
            w,
            "results/error_over_requirement",
            np.abs(err) / req.si,
            (230, 150, 60),
            "1 = requirement",
        )
        with np.errstate(divide="ignore", invalid="ignore"):
            labelled_bars(w, "results/error_over_sigma", err / result.sigma, (160, 110, 220), "1 sigma")
    if result.correlation is not None:
        labelled_matrix(w, "results/correlation", result.correlation)
    w.static("results/table", rr.TextDocument(_results_table(result, truth), media_type="text/markdown"))
