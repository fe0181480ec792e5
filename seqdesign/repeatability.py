"""Two calibrations of the same unit side by side: the repeatability check of the paper's Table 3.

Each parameter's difference is judged against the combined sigma
``sqrt(sigma_a^2 + sigma_b^2)`` of two independent runs; the sum of the
squared normalised differences over the parameters both runs estimate is
chi-square with that many degrees of freedom when the unit did not change
and both sigmas are honest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from calib import params as P
from calib.result import CalibrationResult

LIMIT_SIGMA = 3.0  # a difference beyond 3 combined sigmas is flagged


@dataclass(frozen=True)
class Repeatability:
    """Two results of one unit and what their differences say."""

    a: CalibrationResult
    b: CalibrationResult
    names: tuple  # what each was loaded from

    def entries(self) -> dict[str, dict]:
        va, vb = P.from_si(self.a.values), P.from_si(self.b.values)
        sa, sb = P.from_si(self.a.sigma), P.from_si(self.b.sigma)
        out = {}
        for p in P.PARAMETERS:
            i = p.index
            combined = math.hypot(sa[i], sb[i])
            diff = vb[i] - va[i]
            z = float(diff / combined) if np.isfinite(combined) and combined > 0 else None
            out[p.name] = {
                "unit": p.unit,
                "a": float(va[i]),
                "b": float(vb[i]),
                "difference": float(diff),
                "combined_sigma": float(combined),
                "difference_over_sigma": z,
                "flag": bool(z is not None and abs(z) > LIMIT_SIGMA),
            }
        return out

    def chi2(self) -> tuple[float, int, float]:
        """Sum of squared normalised differences, its degrees of freedom, and its p-value."""
        z = [
            e["difference_over_sigma"]
            for e in self.entries().values()
            if e["difference_over_sigma"] is not None
        ]
        s = float(np.sum(np.square(z)))
        return s, len(z), float(chi2.sf(s, len(z))) if z else float("nan")

    def to_json(self) -> dict:
        s, dof, p = self.chi2()
        return {
            "results": list(self.names),
            "parameters": self.entries(),
            "chi2": s,
            "dof": dof,
            "p_value": p,
            "flagged": [n for n, e in self.entries().items() if e["flag"]],
        }

    def to_text(self) -> str:
        lines = [f"{'param':<6}{'unit':<8}{'A':>12}{'B':>12}{'B - A':>11}{'sigma A+B':>11}{'diff/sig':>9}"]
        for name, e in self.entries().items():
            z = e["difference_over_sigma"]
            lines.append(
                f"{name:<6}{e['unit']:<8}{e['a']:12.5g}{e['b']:12.5g}"
                f"{e['difference']:11.3g}{e['combined_sigma']:11.3g}"
                f"{(z if z is not None else float('nan')):9.2f}"
                f"{'  DIFFERS' if e['flag'] else ''}"
            )
        s, dof, p = self.chi2()
        flagged = [n for n, e in self.entries().items() if e["flag"]]
        lines.append(f"A = {self.names[0]}, B = {self.names[1]}; sigma A+B = sqrt(sA^2 + sB^2)")
        lines.append(
            f"chi2 = {s:.1f} over {dof} parameters (p = {p:.3g}): "
            + (
                "the two calibrations agree within their sigmas"
                if p > 0.01 and not flagged
                else "they differ by more than their sigmas allow"
                + (f" ({', '.join(flagged)} beyond {LIMIT_SIGMA:g} sigma)" if flagged else "")
            )
        )
        return "\n".join(lines)


def compare_results(paths) -> Repeatability:
    """Load two result files and compare them."""
    a, b = (CalibrationResult.load(p) for p in paths)
    return Repeatability(a, b, tuple(str(p) for p in paths))
