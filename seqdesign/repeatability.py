"""Two calibrations of the same unit side by side: the repeatability check of the paper's Table 3.

Each parameter's difference is judged against the combined sigma
``sqrt(sigma_a^2 + sigma_b^2)`` of two independent runs. The sum of the
squared normalised differences over the parameters both runs estimate has
the mean of their number when the unit did not change and both sigmas are
honest, but the estimates are correlated: the sum is then distributed as
``sum_j lambda_j chi2_1``, the ``lambda_j`` the eigenvalues of the correlation
matrix of the difference (covariance ``C_a + C_b``), which is chi-square with
that many degrees of freedom only when the correlations vanish. Its p-value
is taken from that distribution (Imhof's formula) when both results carry
their correlations. For two navigation-grade fits of paper-9pos the eigenvalues
run from 0.02 to 3.0: the sum spreads by 8.0 where chi-square(21) spreads by
6.5, and a sum of 42.5 has p = 1.6 %, not the 0.4 % of chi-square(21).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad
from scipy.stats import chi2

from calib.calibration.result import CalibrationResult
from calib.model import params as P

LIMIT_SIGMA = 3.0  # a difference beyond 3 combined sigmas is flagged
SATTERTHWAITE_TAIL = 1e-7  # below: the Imhof integral's error (1e-10 absolute) is over 0.1 % of p


def weighted_chi2_sf(x: float, weights) -> float:
    """P(sum_j w_j z_j^2 > x) for independent standard normal z_j and weights w_j >= 0 (Imhof 1961).

    ``1/2 + 1/pi int_0^inf sin(theta(u)) / (u rho(u)) du`` with
    ``theta(u) = sum_j atan(w_j u) / 2 - x u / 2`` and ``rho(u) = prod_j (1 + w_j^2 u^2)^(1/4)``.
    """
    w = np.asarray(weights, dtype=float)
    w = w[w > 1e-12 * max(float(w.max(initial=0.0)), 1e-300)]
    if len(w) == 0:
        return float(x < 0.0)

    def integrand(u: float) -> float:
        if u == 0.0:  # the limit: (sum w - x) / 2
            return 0.5 * (float(w.sum()) - x)
        theta = 0.5 * float(np.sum(np.arctan(w * u))) - 0.5 * x * u
        log_rho = 0.25 * float(np.sum(np.log1p((w * u) ** 2)))
        return math.sin(theta) / (u * math.exp(log_rho))

    a, nu = float(np.sum(w**2) / np.sum(w)), float(np.sum(w) ** 2 / np.sum(w**2))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        total, _ = quad(integrand, 0.0, np.inf, limit=500, epsabs=1e-10)
    p = 0.5 + total / math.pi
    # Few weights: the integrand decays slowly. Far in the tail: the integral's absolute error
    # (1e-10) is the answer's size, and it came out 9e-12 for a chi2 of 561 on 21 while 665 gave
    # 0. Satterthwaite's chi2(nu) instead: exact for equal weights, monotone in x.
    if caught or p < SATTERTHWAITE_TAIL:
        return float(chi2.sf(x / a, nu))
    return float(min(p, 1.0))


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

    def difference_weights(self, used: np.ndarray) -> np.ndarray | None:
        """Eigenvalues of the correlation of B - A over ``used`` (None without both correlations)."""
        if self.a.correlation is None or self.b.correlation is None:
            return None
        C = (self.a.covariance + self.b.covariance)[np.ix_(used, used)]
        s = np.sqrt(np.diag(C))
        return np.clip(np.linalg.eigvalsh(C / np.outer(s, s)), 0.0, None)

    def chi2(self) -> tuple[float, int, float]:
        """Sum of squared normalised differences, its degrees of freedom, and its p-value.

        The p-value is that of the sum's own distribution for honest, independent runs, the
        correlations of both results included (:func:`weighted_chi2_sf`); chi-square with
        ``dof`` degrees of freedom when a result carries no correlation.
        """
        z = [e["difference_over_sigma"] for e in self.entries().values()]
        used = np.array([v is not None for v in z])
        s = float(np.sum(np.square([v for v in z if v is not None])))
        dof = int(used.sum())
        if dof == 0:
            return s, 0, float("nan")
        weights = self.difference_weights(used)
        p = chi2.sf(s, dof) if weights is None else weighted_chi2_sf(s, weights)
        return s, dof, float(p)

    def to_json(self) -> dict:
        s, dof, p = self.chi2()
        return {
            "results": list(self.names),
            "parameters": self.entries(),
            "chi2": s,
            "dof": dof,
            "p_value": p,
            "flagged": [n for n, e in self.entries().items() if e["flag"]],
            "same_samples": self.same_samples,
        }

    @property
    def same_samples(self) -> bool:
        """Whether both results were fitted on the same samples (their fingerprints agree)."""
        a, b = self.a.provenance.get("samples"), self.b.provenance.get("samples")
        return a is not None and a == b

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
        if self.a.correlation is not None and self.b.correlation is not None:
            lines.append("p from the sum's distribution with both results' correlations (docs/formats.md)")
        if self.same_samples:
            lines.append(
                f"chi2 = {s:.1f} over {dof} parameters: both are fits of the same samples "
                f"({self.a.provenance['samples'].split(' ')[0]}): their difference says how the two fits "
                "differ, nothing of the unit's repeatability"
            )
            return "\n".join(lines)
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
