"""Design sequences for one or several time budgets: the library call behind ``seqdesign design``.

:func:`design_budgets` runs the search of :mod:`seqdesign.search.design` for each
budget and returns a :class:`DesignReport` that knows its ``--json``
document, its text table, how to save each design with its provenance and
how to write the Pareto front (CSV, and a PNG drawn with matplotlib).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from pathlib import Path

from calib.analysis.bounds import accel_scale_bound
from calib.analysis.worst_case import analyze_tolerance
from calib.errors import CalibError
from calib.gimbal.description import Gimbal
from calib.io.files import atomic_write_text, sha256_file
from calib.model.optional_terms import NONE as NO_EXTRAS, OptionalTerms
from calib.model.requirements import PAPER, Requirements
from calib.nav import earth
from calib.nav.site import Site
from calib.noise.profiles import NoiseProfile, load_profile
from calib.sequence.definition import load_sequence, save_sequence

from ..plots import pareto_png
from .constraints import Constraints, DesignOptions, check_constraints
from .design import DesignResult, design


@dataclass(frozen=True)
class DesignRow:
    """One budget's design and the bound it is judged against."""

    budget_min: float
    result: DesignResult
    bound_ratio: float  # white-noise bound of the conventions
    rate_bound_ratio: float  # with the profile's Gauss-Markov bias at the gimbal's rate


@dataclass(frozen=True)
class DesignReport:
    """Designs for a set of budgets, with the paper's point for scale."""

    rows: list[DesignRow]
    profile: NoiseProfile
    objective: str
    tolerance_deg: float
    latitude_deg: float
    paper_duration_s: float
    paper_worst_ratio: float
    requirements: Requirements = PAPER
    extras: OptionalTerms = NO_EXTRAS
    gimbal: Gimbal | None = None  # the moves were planned on (design --gimbal)

    def to_json(self) -> dict:
        """The ``design --json`` document."""
        return {
            "profile": self.profile.name,
            "requirements": self.requirements.name,
            "objective": self.objective,
            "tolerance_deg": self.tolerance_deg,
            "with": list(self.extras.groups),
            "gimbal": None if self.gimbal is None else self.gimbal.name,
            "designs": [_row_doc(r) for r in self.rows],
            "paper_9pos": {"duration_s": self.paper_duration_s, "worst_ratio": self.paper_worst_ratio},
        }

    def to_text(self) -> str:
        coloured = self.profile.accel_gm_sigma > 0  # then the bound at the gimbal's rate too
        lines = [
            f"{'budget':>7} {'time':>7} {'worst ratio':>16} {'uniform':>8} {'bound':>6} "
            + ("rate-bound  " if coloured else " ")
            + "moves"
        ]
        for row in self.rows:
            r = row.result
            moves = " ".join(f"{s.angle_deg:+.0f}{s.axis}" for s in r.sequence.steps)
            lines.append(
                f"{row.budget_min:6g}m {r.sequence.duration_s / 60:6.1f}m "
                f"{r.worst_name:>5} {r.worst_ratio:9.3f} {r.uniform_worst_ratio:8.3f} "
                f"{row.bound_ratio:6.3f} " + (f"{row.rate_bound_ratio:10.3f}  " if coloured else " ") + moves
            )
            lines.extend(extras_lines(r))
        lines.append(
            f"paper-9pos: {self.paper_duration_s / 60:.1f} min, worst ratio "
            f"{self.paper_worst_ratio:.2f}. Ratios are 3 sigma/requirement, worst over "
            f"+-{self.tolerance_deg:g} deg, profile {self.profile.name}; bound = best "
            "possible for the accelerometer scale factors at that time"
            + (
                "; rate-bound = the same with the Gauss-Markov bias, turning at the "
                "design's rate (docs/design.md)."
                if coloured
                else "."
            )
        )
        return "\n".join(lines)

    def save_design(self, row: DesignRow, path: str | Path, provenance: dict) -> None:
        """Write one design as a sequence file whose provenance says how it was found."""
        r = row.result
        prov = dict(provenance) | {
            "objective": self.objective,
            "profile": self.profile.name,
            "requirements": self.requirements.name,
            "score": r.worst_ratio,
            "score_parameter": r.worst_name,
            "tolerance_deg": self.tolerance_deg,
            "latitude_deg": self.latitude_deg,
            "budget_min": row.budget_min,
            "uniform_dwell_score": r.uniform_worst_ratio,
            "candidates_evaluated": r.evaluated,
            "with": ",".join(self.extras.groups) or "none",
            "motif_repeats": r.repeats,
        }
        prov |= gimbal_provenance(self.gimbal)
        save_sequence(replace(r.sequence, provenance=prov), path)

    def write_pareto(self, stem: str | Path) -> list[str]:
        """The front as ``stem.csv`` and ``stem.png`` (matplotlib); returns the files written."""
        stem = str(stem).removesuffix(".toml")
        g = earth.gravity(math.radians(self.latitude_deg))
        lines = ["budget_min,duration_s,worst_ratio,worst_parameter,bound_ratio,rate_bound_ratio"]
        for row in self.rows:
            r = row.result
            lines.append(
                f"{row.budget_min},{r.sequence.duration_s:.1f},{r.worst_ratio:.4f},"
                f"{r.worst_name},{row.bound_ratio:.4f},{row.rate_bound_ratio:.4f}"
            )
        paper = [
            accel_scale_bound(self.paper_duration_s, self.profile, g, self.requirements, rate)
            for rate in (None, design_rate_dps(load_sequence("paper-9pos")))
        ]
        lines.append(
            f"paper-9pos,{self.paper_duration_s:.1f},{self.paper_worst_ratio:.4f},,"
            f"{paper[0]:.4f},{paper[1]:.4f}"
        )
        atomic_write_text(stem + ".csv", "\n".join(lines) + "\n")

        fastest = max((design_rate_dps(r.result.sequence) for r in self.rows), default=None)
        pareto_png(self, g, stem + ".png", fastest)
        return [stem + ".csv", stem + ".png"]


def design_rate_dps(seq) -> float:
    """The fastest turn of a sequence: what its gimbal can do, for the coloured-noise bound."""
    return max(s.rate_dps for s in seq.steps)


def gimbal_provenance(gimbal) -> dict:
    """What a designed file records of the gimbal its moves were planned on."""
    if gimbal is None:
        return {"gimbal": "none (default: slip rings, no limits)"}

    out = {"gimbal": gimbal.name}
    if gimbal.path:
        out |= {"gimbal_file": str(gimbal.path), "gimbal_sha256": sha256_file(gimbal.path)}
    return out


def _row_doc(row: DesignRow) -> dict:
    r = row.result
    return {
        "budget_min": row.budget_min,
        "duration_s": r.sequence.duration_s,
        "worst": {"name": r.worst_name, "ratio": r.worst_ratio},
        "uniform_dwell_worst_ratio": r.uniform_worst_ratio,
        "accel_scale_bound_ratio": row.bound_ratio,
        "accel_scale_rate_bound_ratio": row.rate_bound_ratio,
        "steps": [{"axis": s.axis, "angle_deg": s.angle_deg, "dwell_s": s.dwell_s} for s in r.sequence.steps],
        "initial_dwell_s": r.sequence.initial_dwell_s,
        "candidates_evaluated": r.evaluated,
        "search_seconds": r.search_seconds,
        "motif_repeats": r.repeats,
        "extras": extras_doc(r),
    }


def extras_doc(r: DesignResult) -> list[dict]:
    """Each fitted extra term's worst sigma against its typical size, in its own unit."""
    cost = r.extras_cost
    if cost is None:
        return []
    return [
        {"name": p.name, "unit": p.unit, "sigma": float(s / p.si_per_unit), "typical": p.scale, "verdict": v}
        for p, s, v in zip(cost.extras.parameters, cost.extra_sigma, cost.verdicts(), strict=True)
    ]


def extras_lines(r: DesignResult) -> list[str]:
    """Text lines for :func:`extras_doc`; flags a term left weak or unobservable."""
    docs = extras_doc(r)
    if not docs:
        return []
    out = ["        " + "  ".join(f"{d['name']} {d['sigma']:.3g}/{d['typical']:g} {d['unit']}" for d in docs)]
    bad = [f"{d['name']} ({d['verdict']})" for d in docs if d["verdict"] != "observable"]
    out.append(
        "        extra terms: "
        + ("all observable (3 sigma within the typical size)" if not bad else "WARNING " + ", ".join(bad))
    )
    return out


def design_names(budgets_min, name: str | None = None) -> dict[float, str]:
    """Each budget's sequence name: ``name`` for one budget, ``<name>-<budget>min`` for several,
    ``designed-<budget>min`` without a name (so that several designs never share a name).
    """
    budgets_min = list(budgets_min)
    if name is not None and not name.strip():
        raise CalibError("the design's name is empty", "name (the CLI's --name)", "give a name, e.g. mine")
    if name is None:
        return {b: f"designed-{b:g}min" for b in budgets_min}
    if len(budgets_min) == 1:
        return {budgets_min[0]: name}
    return {b: f"{name}-{b:g}min" for b in budgets_min}


def paper_point(profile: NoiseProfile, site: Site, tolerance_deg: float, requirements: Requirements = PAPER):
    """The paper's sequence at ``site``: duration and worst ratio over the 27 box points."""
    seq = load_sequence("paper-9pos")
    rob = analyze_tolerance(seq, profile, site, tolerance_deg, search=False, requirements=requirements)
    return seq.duration_s, float(rob.per_parameter_worst_ratio.max())


def design_budgets(
    budgets_min,
    constraints: Constraints | dict | None = None,
    profile: NoiseProfile | str = "navigation",
    options: DesignOptions | None = None,
    *,
    progress=None,
    name: str | None = None,
) -> DesignReport:
    """Design one sequence per budget.

    Parameters
    ----------
    budgets_min : iterable of float
        Total time budgets, minutes.
    constraints : Constraints or dict, optional
        A :class:`seqdesign.search.Constraints` (its ``budget_s`` is replaced by each
        budget), or a dict of its fields other than the budget (start, end, max_flips,
        axes, max_quarters, rate_dps, min/max dwell; a gimbal and its move limits from
        :func:`seqdesign.search.gimbal.gimbal_constraints`). Default: ``Constraints()``'s.
        ``seqdesign.api.design`` also takes them as a dict of names and resolves a gimbal's name.
    profile : NoiseProfile or str
        The noise the design is optimised for.
    options : DesignOptions, optional
        Site latitude, objective, tolerance, beam width, refinement, workers or scheduler,
        requirements and extra terms (:class:`seqdesign.search.DesignOptions`; default: its
        defaults, the CLI's).
    progress : callable, optional
        ``progress(budget_min, report)`` as the search advances, ``report`` a
        :class:`seqdesign.search.Progress` (phase, work done of the phase's total,
        candidates scored, best figure so far).
    name : str, optional
        The designs' sequence name (:func:`design_names`: ``<name>-<budget>min`` each
        when there are several budgets; default ``designed-<budget>min``).

    Returns
    -------
    DesignReport
    """
    if isinstance(constraints, Constraints):
        constraints = {
            f.name: getattr(constraints, f.name) for f in fields(Constraints) if f.name != "budget_s"
        }
    constraints = dict(constraints or {})
    prof = load_profile(profile)
    options = options or DesignOptions()
    req, ext = options.judged_by()
    options = replace(options, requirements=req, extras=ext)
    latitude_deg, tolerance_deg = options.latitude_deg, options.tolerance_deg
    earth.check_site(latitude_deg, 0.0)
    site = Site.at(math.radians(latitude_deg))  # the designs' too: DesignOptions carry no height
    g = site.gravity_mps2
    budgets_min = list(budgets_min)
    names = design_names(budgets_min, name)
    rows = []
    for b in budgets_min:
        c = Constraints(budget_s=b * 60.0, **constraints)
        check_constraints(c)
        res = design(
            c,
            prof,
            options,
            keep=4,
            name=names[b],
            progress=None if progress is None else (lambda r, b=b: progress(b, r)),
        )
        T = res.sequence.duration_s
        rows.append(
            DesignRow(
                b,
                res,
                accel_scale_bound(T, prof, g, req),
                accel_scale_bound(T, prof, g, req, design_rate_dps(res.sequence)),
            )
        )
    paper_T, paper_worst = paper_point(prof, site, tolerance_deg, req)
    return DesignReport(
        rows,
        prof,
        options.objective,
        tolerance_deg,
        latitude_deg,
        paper_T,
        paper_worst,
        req,
        ext,
        constraints.get("gimbal"),
    )
