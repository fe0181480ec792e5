"""Per-parameter reports (table and ``--json``) shared by calibrate and analyze."""
from __future__ import annotations

import numpy as np

from calib import params as P


def parameter_entries(sigma_si: np.ndarray, values_si: np.ndarray | None = None,
                      truth_si: np.ndarray | None = None) -> dict[str, dict]:
    """``files.md`` JSON entries keyed by spec name, in spec units."""
    sig = P.from_si(sigma_si)
    ratios = P.ratio(sigma_si)
    out = {}
    for p in P.PARAMETERS:
        e = {"sigma": float(sig[p.index]), "ratio": float(ratios[p.index]),
             "requirement": p.requirement, "unit": p.unit}
        if values_si is not None:
            e["value"] = float(P.from_si(values_si)[p.index])
        if truth_si is not None:
            t = float(P.from_si(truth_si)[p.index])
            e["truth"] = t
            e["error"] = e["value"] - t
            e["error_over_sigma"] = e["error"] / e["sigma"] if e["sigma"] > 0 else None
        out[p.name] = e
    return out


def worst(entries: dict[str, dict]) -> dict:
    name = max(entries, key=lambda n: entries[n]["ratio"])
    return {"name": name, "ratio": entries[name]["ratio"]}


def format_table(entries: dict[str, dict]) -> str:
    """A readable table: estimate (if any), sigma, requirement, ratio, flag (and truth)."""
    first = next(iter(entries.values()))
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
        flag = "ok" if e["ratio"] <= 1.0 else "MISS"
        row += f"{e['sigma']:11.4g}{e['requirement']:9.4g}{e['ratio']:8.2f}  {flag:<5}"
        if has_truth:
            eos = e["error_over_sigma"]
            row += f"{e['truth']:11.5g}{e['error']:11.3g}{(eos if eos is not None else float('nan')):8.2f}"
        lines.append(row)
    return "\n".join(lines)
