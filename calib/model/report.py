"""Per-parameter reports (table and ``--json``) shared by calibrate and analyze."""

from __future__ import annotations

import numpy as np

from . import params as P
from .requirements import PAPER, Requirements


def parameter_entries(
    sigma_si: np.ndarray,
    values_si: np.ndarray | None = None,
    truth_si: np.ndarray | None = None,
    requirements: Requirements = PAPER,
) -> dict[str, dict]:
    """``docs/formats.md`` JSON entries keyed by spec name, in spec units."""
    sig = P.from_si(sigma_si)
    ratios = requirements.ratio(sigma_si)
    out = {}
    for p in P.PARAMETERS:
        e = {
            "sigma": float(sig[p.index]),
            "ratio": float(ratios[p.index]),
            "requirement": requirements.values[p.index],
            "unit": p.unit,
        }
        if values_si is not None:
            e["value"] = float(P.from_si(values_si)[p.index])
        if truth_si is not None:
            t = float(P.from_si(truth_si)[p.index])
            e["truth"] = t
            e["error"] = e["value"] - t
            e["error_over_sigma"] = e["error"] / e["sigma"] if e["sigma"] > 0 else None
        out[p.name] = e
    return out


def extra_entries(
    extras, sigma_si: np.ndarray, values_si: np.ndarray | None = None, truth_si: np.ndarray | None = None
) -> dict[str, dict]:
    """Entries of the optional terms (:mod:`calib.model.optional_terms`), listed after the 21.

    They have no requirement, so no ratio; ``meaning`` says what each is.
    """
    out = {}
    for k, p in enumerate(extras.parameters):
        e = {"sigma": float(sigma_si[k] / p.si_per_unit), "unit": p.unit, "meaning": p.meaning}
        if values_si is not None:
            e["value"] = float(values_si[k] / p.si_per_unit)
        if truth_si is not None:
            e["truth"] = float(truth_si[k] / p.si_per_unit)
            e["error"] = e["value"] - e["truth"]
            e["error_over_sigma"] = e["error"] / e["sigma"] if e["sigma"] > 0 else None
        out[p.name] = e
    return out


def worst(entries: dict[str, dict]) -> dict:
    """The parameter with the largest finite ratio (those not estimable have none)."""
    rated = [n for n, e in entries.items() if "ratio" in e and np.isfinite(e["ratio"])]
    if not rated:
        return {"name": None, "ratio": None}
    name = max(rated, key=lambda n: entries[n]["ratio"])
    return {"name": name, "ratio": entries[name]["ratio"]}


def format_table(entries: dict[str, dict]) -> str:
    """A readable table: estimate (if any), sigma, requirement, ratio, flag (and truth)."""
    first = next(iter(entries.values()))  # the 21 (and any extras after them) share the columns
    has_value, has_truth = "value" in first, "truth" in first
    head = f"{'param':<6}{'unit':<8}"
    if has_value:
        head += f"{'estimate':>12}"
    head += f"{'sigma':>11}{'require':>9}{'3s/req':>8}  {'flag':<5}"
    if has_truth:
        head += f"{'truth':>11}{'error':>11}{'err/sig':>8}"
    lines = [head]
    for name, e in entries.items():
        row = f"{name:<6}{e['unit']:<8}"
        if has_value:
            row += f"{e['value']:12.5g}"
        if "ratio" in e and not np.isfinite(e["ratio"]):
            row += f"{'-':>11}{e['requirement']:9.4g}{'-':>8}  {'n/e':<5}"
        elif "ratio" in e:
            flag = "ok" if e["ratio"] <= 1.0 else "MISS"
            row += f"{e['sigma']:11.4g}{e['requirement']:9.4g}{e['ratio']:8.2f}  {flag:<5}"
        else:  # an optional term: no requirement
            row += f"{e['sigma']:11.4g}{'-':>9}{'-':>8}  {'':<5}"
        if has_truth:
            eos = e["error_over_sigma"]
            row += f"{e['truth']:11.5g}{e['error']:11.3g}{(eos if eos is not None else float('nan')):8.2f}"
        lines.append(row)
    return "\n".join(lines)
