"""Analyse a sequence: the library call behind ``seqdesign analyze`` and ``compare``.

:func:`analyze` returns an :class:`Analysis` that knows how to turn itself
into the ``--json`` document and the text the CLI prints: predicted sigma
and 3 sigma / requirement per parameter (worst over the mounting box),
which parameters are estimable and which combinations are not, correlated
pairs, the D/A/E criteria, the accelerometer scale-factor bound and,
optionally, what fitting a real unit's extra terms costs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.analysis.bounds import Unreachable, accel_scale_bound, unreachable
from calib.analysis.worst_case import OptionalTermsCost, Robustness, analyze_extras, analyze_tolerance
from calib.errors import CalibError
from calib.model import params as P
from calib.model.optional_terms import OptionalTerms, load_optional_terms
from calib.model.report import format_table, parameter_entries, worst
from calib.model.requirements import PAPER, Requirements, load_requirements
from calib.nav import earth
from calib.nav.site import Site
from calib.noise.profiles import NoiseProfile, load_profile
from calib.noise.wander import check_wander
from calib.sequence.definition import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG, Sequence, load_sequence

from .separability import involvement, motion_hint, separable_combinations


def resolve_site(
    seq: Sequence, latitude_deg: float | None = None, height_m: float | None = None
) -> tuple[float, float]:
    """The site: the given values, else the sequence's, else the conventions' defaults."""
    lat = (
        latitude_deg
        if latitude_deg is not None
        else (seq.latitude_deg if seq.latitude_deg is not None else DEFAULT_LATITUDE_DEG)
    )
    h = height_m if height_m is not None else (seq.height_m if seq.height_m is not None else DEFAULT_HEIGHT_M)
    earth.check_site(lat, h)
    return lat, h


@dataclass(frozen=True)
class Analysis:
    """Observability of one sequence under one profile, worst over the mounting box."""

    sequence: Sequence
    profile: NoiseProfile
    latitude_deg: float
    height_m: float
    robustness: Robustness
    bound: float
    extras_cost: OptionalTermsCost | None = None
    requirements: Requirements = PAPER

    @property
    def estimable(self) -> np.ndarray:
        return self.robustness.nominal.estimable

    def entries(self) -> dict[str, dict]:
        """Per-parameter entries: sigma and ratio worst over the box, estimability."""
        rob = self.robustness
        entries = parameter_entries(rob.per_parameter_worst_sigma, requirements=self.requirements)
        takes_part = involvement(rob.nominal.null_basis)
        for p in P.PARAMETERS:
            e = entries[p.name]
            e["ratio_nominal"] = float(rob.nominal.ratio[p.index])
            e["estimable"] = bool(self.estimable[p.index])
            if not e["estimable"]:
                e["unobserved_directions"] = takes_part[p.index]
                e["needs"] = motion_hint(p.index)
        return entries

    def to_json(self) -> dict:
        """The ``analyze --json`` document."""
        rob, seq = self.robustness, self.sequence
        w = rob.worst
        entries = self.entries()
        ratios = [entries[n]["ratio"] for n in ("sax", "say", "saz")]
        doc = {
            "sequence": seq.name,
            "duration_s": seq.duration_s,
            "profile": self.profile.name,
            "requirements": self.requirements.name,
            "latitude_deg": self.latitude_deg,
            "tolerance_deg": rob.tolerance_deg,
            "setups_evaluated": rob.points,
            "ipopt_search": rob.searched,
            "parameters": entries,
            "worst": worst(entries),
            "worst_setup_deg": [float(x) for x in np.degrees(w.setup_rotvec)],
            "rank": rob.nominal.rank,
            "estimable": [n for n in P.NAMES if entries[n]["estimable"]],
            "not_estimable": [n for n in P.NAMES if not entries[n]["estimable"]],
            "unobservable": rob.nominal.unobservable,
            "separable_combinations": separable_combinations(
                rob.nominal.null_basis, self.estimable, scales=self.requirements.values
            ),
            "correlated_pairs": [{"a": a, "b": b, "rho": r} for a, b, r in w.correlated_pairs()],
            "criteria": w.criteria(),
            "accel_scale_bound": {"best_possible_ratio": self.bound, "achieved_ratio": float(max(ratios))},
            "unreachable": [
                {
                    "parameters": list(u.names),
                    "best_possible_ratio": u.ratio,
                    "needed_s": u.needed_s,
                    "why": u.why,
                }
                for u in self.unreachable()
            ],
        }
        if self.extras_cost is not None:
            doc["extras"] = _extras_doc(self.extras_cost, self.requirements)
        return doc

    def unreachable(self) -> list[Unreachable]:
        """The requirements no sequence this long meets under this noise (:mod:`~calib.analysis.bounds`)."""
        site = Site.at(math.radians(self.latitude_deg), self.height_m)
        return unreachable(self.sequence.duration_s, self.profile, site.gravity_mps2, self.requirements)

    def to_text(self) -> str:
        """What ``analyze`` prints."""
        rob, seq = self.robustness, self.sequence
        doc = self.to_json()
        lines = [
            f"{seq.name}: {seq.duration_s:.0f} s ({seq.duration_s / 60:.1f} min), profile "
            f"{self.profile.name}, requirements {self.requirements.name}, latitude "
            f"{self.latitude_deg:g} deg, worst case over "
            f"+-{rob.tolerance_deg:g} deg ({rob.points} mountings"
            f"{' + IPOPT search' if rob.searched else ''})",
            format_table(doc["parameters"]),
        ] + _verdict(doc)
        lines += self._why_missed(doc)
        if self.extras_cost is not None:
            lines += _extras_text(doc["extras"])
        return "\n".join(lines)

    def _why_missed(self, doc: dict) -> list[str]:
        """Why the misses miss, where the verdict is printed: a bound of the noise, or the moves."""
        misses = [n for n in doc["estimable"] if doc["parameters"][n]["ratio"] > 1.0]
        if not misses:
            return []
        p = self.profile
        lines = [
            f"why: judged by requirements {self.requirements.name} under profile {p.name} (gyro ARW "
            f"{p.gyro_arw_dph:.3g} deg/sqrt(h), accel VRW {p.accel_vrw_ug:.3g} ug/sqrt(Hz)"
            + (", Gauss-Markov biases" if p.has_gauss_markov else "")
            + ")"
        ]
        bounded: set[str] = set()
        for u in self.unreachable():
            if set(u.names) & set(misses):
                lines.append("  " + u.text(self.sequence.duration_s))
                bounded.update(u.names)
        rest = [n for n in misses if n not in bounded]
        if rest:
            lines.append(
                f"  {', '.join(rest)}: no bound of the noise forbids them at this length; other moves "
                f"may meet them (seqdesign design --budget-min {self.sequence.duration_s / 60:.0f})"
            )
        return lines


def analyze(
    sequence: Sequence | str,
    profile: NoiseProfile | str = "navigation",
    *,
    latitude_deg: float | None = None,
    height_m: float | None = None,
    tolerance_deg: float = 3.0,
    extras: OptionalTerms | str | None = None,
    requirements: Requirements | str | None = None,
) -> Analysis:
    """Predict how well a sequence calibrates the 21 parameters.

    Parameters
    ----------
    sequence : Sequence or str
        A sequence, a shipped name (``paper-9pos``) or a file.
    profile : NoiseProfile or str
        The IMU's noise.
    latitude_deg, height_m : float, optional
        The site (default: the sequence's, else 40 deg and 0 m).
    tolerance_deg : float
        Half-width of the mounting box; figures are the worst over it.
    extras : OptionalTerms or str, optional
        Also report what fitting these optional terms costs.
    requirements : Requirements or str, optional
        What the ratios are judged against (default: the paper's).

    Returns
    -------
    Analysis
    """
    seq = sequence if isinstance(sequence, Sequence) else load_sequence(sequence)
    prof, extras = load_profile(profile), load_optional_terms(extras)
    req = load_requirements(requirements)
    if not 0.0 <= tolerance_deg <= 10.0:
        raise CalibError(f"tolerance {tolerance_deg} deg outside [0, 10]", "tolerance_deg")
    # Beyond the wander the linearised fit follows, no calibration achieves these sigmas.
    check_wander(prof, seq.duration_s, seq.name)
    lat, h = resolve_site(seq, latitude_deg, height_m)
    site = Site.at(math.radians(lat), h)
    rob = analyze_tolerance(seq, prof, site, tolerance_deg, requirements=req, extras=extras)
    bound = accel_scale_bound(seq.duration_s, prof, site.gravity_mps2, req)
    cost = analyze_extras(seq, prof, site, extras, tolerance_deg, req, search=True) if extras.n else None
    return Analysis(seq, prof, lat, h, rob, bound, cost, req)


def site_warnings(analyses: list[Analysis]) -> list[str]:
    """A warning when the analyses were made at different sites (each sequence's own).

    Gravity and Earth rate differ with latitude and height, so the ratios of sequences
    analysed at different sites are not comparable; the fix is one site for all.
    """
    sites = {(a.latitude_deg, a.height_m) for a in analyses}
    if len(sites) < 2:
        return []
    each = "; ".join(f"{a.sequence.name} at {a.latitude_deg:g} deg, {a.height_m:g} m" for a in analyses)
    give = " and ".join(
        opt
        for opt, values in (
            ("--latitude DEG", {a.latitude_deg for a in analyses}),
            ("--height M", {a.height_m for a in analyses}),
        )
        if len(values) > 1
    )
    return [
        f"the sequences are analysed at different sites, each at its own ({each}): their ratios "
        f"are not comparable; give {give} to compare them at one site"
    ]


def compare_text(analyses: list[Analysis]) -> str:
    """Several analyses side by side: time, worst ratio, each parameter's ratio."""
    docs = [a.to_json() for a in analyses]
    names = [d["sequence"] for d in docs]
    width = max(10, *(len(n) + 2 for n in names))
    lines = [
        f"{'':<12}" + "".join(f"{n:>{width}}" for n in names),
        f"{'time min':<12}" + "".join(f"{d['duration_s'] / 60:>{width}.1f}" for d in docs),
        f"{'worst':<12}" + "".join(f"{_worst_cell(d):>{width}}" for d in docs),
    ]
    for p in P.PARAMETERS:
        cells = [d["parameters"][p.name] for d in docs]
        lines.append(
            f"{p.name:<12}"
            + "".join(f"{e['ratio']:>{width}.2f}" if e["estimable"] else f"{'n/e':>{width}}" for e in cells)
        )
    a = analyses[0]
    lines.append(
        f"ratios are 3 sigma / requirement, worst over +-{a.robustness.tolerance_deg:g} "
        f"deg, profile {a.profile.name}, requirements {a.requirements.name}; n/e: not "
        "estimable on its own"
    )
    return "\n".join(lines)


def _worst_cell(doc: dict) -> str:
    w = doc["worst"]
    return "none" if w["name"] is None else f"{w['name']} {w['ratio']:.2f}"


def _verdict(doc: dict) -> list[str]:
    lines = []
    if doc["not_estimable"]:
        lines.append("NOT ESTIMABLE on their own: " + ", ".join(doc["not_estimable"]))
        lines.append(
            "unobserved directions (in units of each requirement): " + "; ".join(doc["unobservable"])
        )
        if doc["separable_combinations"]:
            lines.append(
                "what the sequence does determine of them (each in its own unit): "
                + "; ".join(doc["separable_combinations"])
            )
        lines.append("what would add the missing information:")
        lines += [f"  {n}: {doc['parameters'][n]['needs']}" for n in doc["not_estimable"]]
    if doc["correlated_pairs"]:
        lines.append(
            "correlated pairs (|rho| > 0.9): "
            + ", ".join(f"{p['a']}/{p['b']} {p['rho']:+.3f}" for p in doc["correlated_pairs"])
        )
    b = doc["accel_scale_bound"]
    lines.append(
        f"accel scale-factor bound for {doc['duration_s']:.0f} s: best possible ratio "
        f"{b['best_possible_ratio']:.2f}, this sequence {b['achieved_ratio']:.2f}"
    )
    lines.append(_verdict_line(doc))
    return lines


def _verdict_line(doc: dict) -> str:
    w = doc["worst"]
    where = "worst case over the mounting box" if doc["tolerance_deg"] > 0 else "at the nominal mounting"
    misses = [n for n in doc["estimable"] if doc["parameters"][n]["ratio"] > 1.0]
    if doc["not_estimable"]:
        est = len(doc["estimable"])
        tail = f"; of the {est} estimable, the worst is {w['name']} at {w['ratio']:.2f}" if w["name"] else ""
        return (
            f"Verdict: this sequence cannot separate {len(doc['not_estimable'])} of 21 "
            f"parameters ({', '.join(doc['not_estimable'])}; rank {doc['rank']} of 21){tail}, "
            f"under profile {doc['profile']}, {where}."
        )
    if not misses:
        return (
            f"Verdict: all 21 parameters meet their requirements (worst ratio "
            f"{w['ratio']:.2f}, {w['name']}) under profile {doc['profile']}, {where}."
        )
    return (
        f"Verdict: {len(misses)} of 21 parameters miss their requirement ("
        + ", ".join(misses)
        + f"); the worst is {w['name']} at {w['ratio']:.2f} x the "
        f"requirement (3 sigma), under profile {doc['profile']}, {where}."
    )


def _extras_doc(cost: OptionalTermsCost, requirements: Requirements) -> dict:
    """``analyze --with``: the cost of the optional terms to each of the 21, and their sigma."""
    r0, r1 = requirements.ratio(cost.sigma_without), requirements.ratio(cost.sigma_with)
    params = {
        p.name: {
            "unit": p.unit,
            "sigma_without": float(cost.sigma_without[p.index] / p.si_per_unit),
            "sigma_with": float(cost.sigma_with[p.index] / p.si_per_unit),
            "ratio_without": float(r0[p.index]),
            "ratio_with": float(r1[p.index]),
            "sigma_increase": float(cost.sigma_with[p.index] / cost.sigma_without[p.index]),
        }
        for p in P.PARAMETERS
    }
    extra = {
        p.name: {
            "unit": p.unit,
            "sigma": float(s / p.si_per_unit),
            "typical_size": p.scale,
            "verdict": v,
            "meaning": p.meaning,
        }
        for p, s, v in zip(cost.extras.parameters, cost.extra_sigma, cost.verdicts(), strict=True)
    }
    finite = np.where(np.isfinite(r1), r1, -np.inf)
    w = int(np.argmax(finite))
    return {
        "terms": list(cost.extras.groups),
        "setups_evaluated": cost.points,
        "ipopt_search": cost.searched,
        "tolerance_deg": cost.tolerance_deg,
        "parameters": params,
        "extra_parameters": extra,
        "worst_with": {"name": P.NAMES[w], "ratio": float(r1[w])},
        "unobservable": cost.unobservable,
    }


def _extras_text(d: dict) -> list[str]:
    search = " + IPOPT search" if d["ipopt_search"] else ""
    lines = [
        "",
        f"with {', '.join(d['terms'])} also fitted (worst over {d['setups_evaluated']} "
        f"mountings{search} within +-{d['tolerance_deg']:g} deg, direct evaluation):",
        f"{'param':<6}{'unit':<8}{'sigma w/o':>11}{'sigma with':>11}{'x':>7}"
        f"{'3s/req w/o':>11}{'3s/req with':>12}",
    ]
    for name, e in d["parameters"].items():
        lines.append(
            f"{name:<6}{e['unit']:<8}{e['sigma_without']:11.4g}{e['sigma_with']:11.4g}"
            f"{e['sigma_increase']:7.2f}{e['ratio_without']:11.2f}{e['ratio_with']:12.2f}"
        )
    lines.append(f"{'param':<6}{'unit':<8}{'sigma':>11}{'typical':>9}  verdict")
    for name, e in d["extra_parameters"].items():
        lines.append(f"{name:<6}{e['unit']:<8}{e['sigma']:11.4g}{e['typical_size']:9.4g}  {e['verdict']}")
    if d["unobservable"]:
        lines.append("UNOBSERVABLE with the extra terms: " + "; ".join(d["unobservable"]))
    finite = {k: v for k, v in d["parameters"].items() if np.isfinite(v["sigma_increase"])}
    if finite:
        name, e = max(finite.items(), key=lambda kv: kv[1]["sigma_increase"])
        lines.append(
            f"Fitting them costs most on {name} (sigma x{e['sigma_increase']:.2f}); "
            f"worst ratio with them {d['worst_with']['ratio']:.2f} "
            f"({d['worst_with']['name']}). 'weak': 3 sigma exceeds the typical size; "
            "'unobservable': no information."
        )
    return lines
