"""A calibration result: 21 values with 1-sigma, the initial attitude and the fit's health.

Saved and loaded as the result TOML of ``docs/formats.md`` (values in spec
units). The result knows how to print itself (``to_text``) and how to turn
itself into the ``--json`` document of ``calibrate`` (``to_json``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.hand.summary import HandSummary
from calib.io.fields import FORMAT_VERSION, Fields, check_format_version
from calib.io.files import atomic_write_text, load_toml, toml_number
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.model.optional_terms import GROUPS, NONE as NO_EXTRAS, OptionalTerms, parse_groups
from calib.model.report import extra_entries, format_table, parameter_entries, worst
from calib.model.requirements import PAPER, Requirements, requirements_from_dict
from calib.nav.site import ppm_per_mgal

# The error model is linear in the scale factors and misalignments: an error of 1 % (0.57 deg)
# leaves products of 1e-4 unmodelled, a tenth of a MEMS unit's 1000 ppm requirement. A sigma
# beyond it says the linearisation the estimate and the sigma both come from no longer holds.
LINEAR_LIMIT = 1e-2
# No triad is built this far off (a MEMS part's scale factors and cross-axis terms are within
# 2-3 %): an estimate beyond it is a conversion off by as much, or moves the fit should not have
# trusted (clipped, sampled too seldom: a flight computer's 20 Hz log gave 12-14 deg). The model
# (I + S + M, inverted exactly) describes any linear triad, so the first is corrected as fitted
# (a real BMI160 read 5.3 % high, imu_tk's fit the same): said, for the user to tell which.
VALUE_LIMIT = 5e-2


@dataclass(frozen=True)
class CalibrationResult:
    """Estimated parameters (SI inside) and how far to trust them.

    Attributes
    ----------
    values, sigma : ndarray, shape (21,)
        Estimates and 1-sigma, SI. ``sigma`` already carries the Birge
        inflation (``sigma_scale``); it is inf for a parameter that is not
        estimable (a partial fit).
    C_b_n0 : ndarray, shape (3, 3)
        Attitude at the first sample.
    converged : bool
        Whether the Gauss-Newton corrections fell below 1e-3 sigma.
    iterations : int
        Gauss-Newton iterations used.
    residual_rms_mps : float
        RMS of the velocity-change residuals after the fit.
    profile : str
        The noise profile that weighted the fit.
    chi2_per_dof : float
        Whitened residual power per degree of freedom: ~1 when the noise
        profile describes the run.
    correlation : ndarray, shape (21, 21) or None
        Correlation of the 21 (0 in the rows of parameters not estimable).
    provenance : dict
        Tool version, command and input hashes.
    extras : OptionalTerms
        Optional terms fitted with the 21 (:mod:`calib.model.optional_terms`); saved after
        the 21 in ``[parameters]`` and named in ``[fit] extras``.
    extra_values, extra_sigma : ndarray, shape (extras.n,)
        SI.
    sigma_scale : float
        The Birge ratio ``sqrt(chi2/dof)`` the sigmas were inflated by (1: not).
    not_estimable : tuple of str
        Parameters a partial fit could not estimate on their own.
    null_directions : tuple of str
        The unobserved combinations (in units of each requirement).
    n_observations : int
        Scalar observations in the fit.
    gravity_mps2 : float
        The gravity the fit assumed (nan: not recorded).
    gravity_source : str
        ``measured`` (the log's) or ``normal`` (WGS-84 model); empty if unknown.
    requirements : Requirements
        What the ratios are judged against.
    caveats : tuple of str
        Warnings about the noise model's honesty for this profile (a MEMS gyro's GM bias).
    by_hand : HandSummary or None
        For a run placed by hand, the rests and moves the fit used.
    """

    values: np.ndarray
    sigma: np.ndarray
    C_b_n0: np.ndarray
    converged: bool
    iterations: int
    residual_rms_mps: float
    profile: str
    chi2_per_dof: float = float("nan")
    correlation: np.ndarray | None = None
    provenance: dict = field(default_factory=dict)
    extras: OptionalTerms = NO_EXTRAS
    extra_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    extra_sigma: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sigma_scale: float = 1.0
    not_estimable: tuple = ()
    null_directions: tuple = ()
    n_observations: int = 0
    gravity_mps2: float = float("nan")
    gravity_source: str = ""
    requirements: Requirements = PAPER
    by_hand: HandSummary | None = None  # a run placed by hand: its rests and moves
    caveats: tuple = ()  # what the fit's model does not prove for this run (calib.fit.feedback)

    @property
    def error_model(self) -> ErrorModel:
        return ErrorModel(self.values)

    @property
    def estimable(self) -> np.ndarray:
        """(21,) whether each of the 21 was estimated on its own."""
        return np.array([n not in self.not_estimable for n in P.NAMES])

    @property
    def covariance(self) -> np.ndarray:
        """Covariance of the 21 (SI) from sigma and correlation (diagonal if no correlation)."""
        corr = np.eye(P.N_PARAMS) if self.correlation is None else self.correlation
        s = np.where(np.isfinite(self.sigma), self.sigma, 0.0)
        return corr * np.outer(s, s)

    @property
    def birge_inflated(self) -> bool:
        """Whether the residuals exceeded the profile's noise and the sigmas were inflated."""
        return self.sigma_scale > 1.0

    @property
    def ppm_per_mgal(self) -> float:
        """How far 1 mGal of gravity error moves every accelerometer scale factor, ppm."""
        return ppm_per_mgal(self.gravity_mps2)

    def nees(self, truth_values: np.ndarray) -> float:
        """Normalised estimation error squared of the estimable 21 against a truth (SI)."""
        ok = self.estimable
        e = (self.values - truth_values)[ok]
        return float(e @ np.linalg.solve(self.covariance[np.ix_(ok, ok)], e))

    def entries(self, truth=None) -> dict[str, dict]:
        """Per-parameter report entries (spec names and units), extras after the 21."""
        out = parameter_entries(
            self.sigma, self.values, truth.errors.values if truth is not None else None, self.requirements
        )
        for name in self.not_estimable:
            if name in out:
                out[name]["estimable"] = False
        if self.extras.n:
            true_extra = None
            if truth is not None and truth.extra is not None:
                true_extra = self.extras.pack(truth.extra)
            out |= extra_entries(self.extras, self.extra_sigma, self.extra_values, true_extra)
        return out

    def warnings(self, gravity_option: str = "gravity_mps2") -> list[str]:
        """What a user must know before trusting the numbers.

        ``gravity_option``: how the user gives the surveyed gravity where they are
        (the CLI's ``--gravity``; the API's and the log's ``gravity_mps2``).
        """
        out = []
        if self.birge_inflated:
            out.append(
                f"residuals are {self.chi2_per_dof:.2f}x the profile's noise power; "
                f"sigmas inflated by {self.sigma_scale:.2f}"
            )
        if self.not_estimable:
            out.append(
                "not estimable (the run does not separate them): "
                + ", ".join(self.not_estimable)
                + "; unobserved combinations: "
                + "; ".join(self.null_directions)
            )
        out.extend(self.caveats)
        loose = [
            p.name
            for p, sigma in zip(P.PARAMETERS, self.sigma, strict=True)
            if p.kind != "bias" and np.isfinite(sigma) and sigma > LINEAR_LIMIT
        ]
        if loose:
            out.append(
                f"the run barely determines {', '.join(loose)}: sigma beyond 1 % (0.57 deg), where the "
                "linear error model this fit and its sigmas rest on no longer holds; do not apply these "
                "estimates (add poses: other faces up, turns about other axes)"
            )
        far = [
            f"{p.name} {100 * v:+.3g} %" if p.kind == "scale" else f"{p.name} {np.degrees(v):+.3g} deg"
            for p, v, sigma in zip(P.PARAMETERS, self.values, self.sigma, strict=True)
            if p.kind != "bias" and np.isfinite(sigma) and abs(v) > VALUE_LIMIT
        ]
        if far:
            out.append(
                f"{', '.join(far)}: beyond 5 % (2.9 deg), further than any triad is built: the log's "
                "conversion to units is off by as much, or the moves the fit used cannot be trusted; apply "
                "these estimates only once you know which (check the conversion, the axes' labels and "
                "units, and the moves: clipped or sampled too seldom)"
            )
        req = min(self.requirements.values[P.ACCEL_SCALE])
        if self.gravity_source == "normal" and req <= 5 * self.ppm_per_mgal:
            out.append(
                f"accelerometer scale factors rest on modelled normal gravity: each mGal "
                f"of local anomaly is {self.ppm_per_mgal:.2f} ppm on sax, say and saz "
                f"(requirement {req:g} ppm); give the surveyed gravity ({gravity_option})"
            )
        return out

    def to_json(self, truth=None) -> dict:
        """The ``calibrate --json`` document (``docs/formats.md``), with truth comparisons if given."""
        entries = self.entries(truth)
        doc: dict[str, object] = {
            "parameters": entries,
            "worst": worst(entries),
            "profile": self.profile,
            "requirements": self.requirements.name,
            "fit": {
                "converged": self.converged,
                "iterations": self.iterations,
                "residual_rms_mps": self.residual_rms_mps,
                "chi2_per_dof": self.chi2_per_dof,
                "sigma_scale": self.sigma_scale,
                "extras": list(self.extras.groups),
                "not_estimable": list(self.not_estimable),
                "unobserved_directions": list(self.null_directions),
            },
            "gravity": {
                "value_mps2": self.gravity_mps2,
                "source": self.gravity_source,
                "ppm_per_mgal": self.ppm_per_mgal,
            },
            "warnings": self.warnings(),
        }
        if truth is not None:
            doc["nees"] = self.nees(truth.errors.values)
        if self.by_hand is not None:
            doc["by_hand"] = self.by_hand.to_json()
        return doc

    def to_text(self, truth=None) -> str:
        """The table and summary ``calibrate`` prints (its :meth:`warnings` go to stderr)."""
        entries = self.entries(truth)
        w = worst(entries)
        lines = [
            format_table(entries),
            f"profile {self.profile}; requirements {self.requirements.name}; "
            f"{'converged' if self.converged else 'NOT converged'} "
            f"in {self.iterations} iterations; {self._residual_text()}; "
            f"chi2/dof {self.chi2_per_dof:.3f}; "
            + (
                f"worst 3 sigma/requirement {w['ratio']:.2f} ({w['name']})"
                if w["name"] is not None
                else "no parameter estimable"
            ),
        ]
        if math.isfinite(self.gravity_mps2):
            lines.append(
                f"gravity {self.gravity_mps2:.7f} m/s^2 ({self.gravity_source}); "
                f"1 mGal = {self.ppm_per_mgal:.2f} ppm on each accelerometer scale factor"
            )
        if self.by_hand is not None:
            lines += self.by_hand.lines()
        return "\n".join(lines)

    def _residual_text(self) -> str:
        if self.by_hand is not None:  # a hand fit's residuals are the rests' mean specific force
            return f"rest specific-force residual RMS {self.residual_rms_mps:.3g} m/s^2"
        return f"residual RMS {self.residual_rms_mps:.3g} m/s"

    def to_dict(self) -> dict:
        """The result TOML document."""
        vals, sig = P.from_si(self.values), P.from_si(self.sigma)
        params = {}
        for p in P.PARAMETERS:
            entry = {"value": float(vals[p.index]), "sigma": float(sig[p.index]), "unit": p.unit}
            if p.name in self.not_estimable:
                entry["estimable"] = False
            params[p.name] = entry
        for xp, v, e in zip(self.extras.parameters, self.extra_values, self.extra_sigma, strict=True):
            params[xp.name] = {
                "value": float(v / xp.si_per_unit),
                "sigma": float(e / xp.si_per_unit),
                "unit": xp.unit,
            }
            if xp.name in self.not_estimable:
                params[xp.name]["estimable"] = False
        fit = {
            "converged": bool(self.converged),
            "iterations": int(self.iterations),
            "residual_rms_mps": float(self.residual_rms_mps),
            "chi2_per_dof": float(self.chi2_per_dof),
            "profile": self.profile,
            "sigma_scale": float(self.sigma_scale),
        }
        if self.extras.groups:
            fit["extras"] = list(self.extras.groups)
        if self.null_directions:
            fit["unobserved_directions"] = list(self.null_directions)
        if math.isfinite(self.gravity_mps2):
            fit["gravity_mps2"] = float(self.gravity_mps2)
            fit["gravity_source"] = self.gravity_source
        doc = {
            "format_version": FORMAT_VERSION,
            "parameters": params,
            "initial_attitude": {"C_b_n": [[float(x) for x in row] for row in self.C_b_n0]},
            "fit": fit,
        }
        if not self.requirements.is_paper:
            fit["requirements"] = self.requirements.name
            doc["requirements"] = {p.name: self.requirements.values[p.index] for p in P.PARAMETERS}
        if self.correlation is not None:
            corr = np.where(np.isfinite(self.correlation), self.correlation, 0.0)
            doc["correlation"] = {
                "names": list(P.NAMES),
                "matrix": [[round(float(x), 6) for x in row] for row in corr],
            }
        if self.provenance:
            doc["provenance"] = dict(self.provenance)
        return doc

    def save(self, path: str | Path) -> None:
        import tomli_w

        atomic_write_text(path, tomli_w.dumps(self.to_dict()))

    @classmethod
    def load(cls, path: str | Path) -> CalibrationResult:
        """Read a result TOML; refuse it, naming the file and table, unless it is complete.

        ``[parameters]`` (all 21 with finite value and non-negative sigma; an
        infinite sigma only where ``estimable = false``) and
        ``[initial_attitude]`` are required; ``[fit]`` keys, ``[correlation]``
        and ``[provenance]`` are optional, but when present must be well-formed.
        """
        where = str(path)
        doc = load_toml(path)
        if not isinstance(doc.get("parameters"), dict):
            raise CalibError("missing table [parameters]", where, _kind_hint(doc))
        check_format_version(doc, "result", where)
        table = doc["parameters"]
        vals, sig, not_est = _read_parameters(
            table, P.PARAMETERS, where, "a result carries all 21 parameters"
        )
        C = _attitude(doc.get("initial_attitude"), f"{where}: [initial_attitude]")
        fit = Fields(doc.get("fit", {}), f"{where}: [fit]")
        extras = _read_extras(fit, where)
        xv, xs, x_not = _read_parameters(table, extras.parameters, where, "[fit] extras names it", si=True)
        corr = None
        if "correlation" in doc:
            corr = _correlation(doc["correlation"], f"{where}: [correlation]")
        provenance = doc.get("provenance", {})
        if not isinstance(provenance, dict):
            raise CalibError("[provenance] must be a table", where)
        return cls(
            values=P.to_si(vals),
            sigma=P.to_si(sig),
            C_b_n0=C,
            converged=fit.boolean("converged", False),
            iterations=fit.integer("iterations", 0, low=0),
            residual_rms_mps=_figure(fit, "residual_rms_mps"),
            profile=fit.string("profile", ""),
            chi2_per_dof=_figure(fit, "chi2_per_dof"),
            correlation=corr,
            provenance=provenance,
            extras=extras,
            extra_values=np.array(xv),
            extra_sigma=np.array(xs),
            sigma_scale=fit.number("sigma_scale", 1.0, low=1.0),
            not_estimable=tuple(not_est + x_not),
            null_directions=tuple(_strings(fit, "unobserved_directions")),
            gravity_mps2=fit.number("gravity_mps2", float("nan"), low=9.7, high=9.9),
            gravity_source=fit.string("gravity_source", ""),
            requirements=_read_requirements(doc, fit, where),
        )


def _read_requirements(doc: dict, fit: Fields, where: str) -> Requirements:
    """The requirements a result was judged against (the paper's when it names none)."""
    if "requirements" not in doc:
        return PAPER
    named = {"name": fit.string("requirements", "custom"), "requirements": doc["requirements"]}
    return requirements_from_dict(named, where)


def _kind_hint(doc: dict) -> str:
    """What a file given as a result looks like instead (a truth, a sequence, a profile)."""
    if "errors" in doc:
        return "this looks like a truth file (it has [errors]); give the result that calibrate wrote"
    if "step" in doc:
        return "this looks like a sequence file; give the result that calibrate wrote"
    if "gyro_arw_dph" in doc:
        return "this looks like a noise profile; give the result that calibrate wrote"
    return "is this a result file?"


def _read_parameters(table: dict, parameters, where: str, missing_fix: str, si: bool = False):
    """Values, sigmas and not-estimable names of ``parameters`` from ``[parameters]``."""
    vals, sig, not_est = [], [], []
    for p in parameters:
        here = f"{where}: [parameters.{p.name}]"
        entry = table.get(p.name)
        if not isinstance(entry, dict):
            raise CalibError("missing", here, missing_fix)
        f = Fields(entry, here)
        estimable = f.boolean("estimable", True)
        value = _finite(entry, "value", here)
        raw = toml_number(entry.get("sigma"))
        if estimable or raw is None or raw != math.inf:
            sigma = _finite(entry, "sigma", here)
            if sigma < 0:
                raise CalibError(f"sigma {sigma} is negative", here)
        else:
            sigma = math.inf
        if not estimable:
            not_est.append(p.name)
        k = p.si_per_unit if si else 1.0
        vals.append(value * k)
        sig.append(sigma * k)
    return vals, sig, not_est


def _finite(entry: dict, key: str, here: str) -> float:
    v = toml_number(entry.get(key))
    if v is None or not math.isfinite(v):
        raise CalibError(
            f"'{key}' must be a finite number, got {entry.get(key)!r}",
            here,
            "a result without uncertainties is not a result",
        )
    return v


def _figure(fit: Fields, key: str) -> float:
    """NaN stands for "not computed"; anything else must be a finite number >= 0."""
    v = fit.number(key, math.nan, finite=False)
    if math.isinf(v) or v < 0:
        raise CalibError(
            f"must be a finite number >= 0 (or nan), got {fit.table.get(key)!r}", f"{fit.where} {key}"
        )
    return v


def _strings(fit: Fields, key: str) -> list[str]:
    raw = fit.table.get(key, [])
    if not isinstance(raw, list) or not all(isinstance(x, str) for x in raw):
        raise CalibError("must be a list of strings", f"{fit.where} {key}")
    return raw


def _read_extras(fit: Fields, where: str) -> OptionalTerms:
    groups = fit.table.get("extras", [])
    if not isinstance(groups, list) or not all(isinstance(g, str) for g in groups):
        raise CalibError("must be a list of names", f"{where}: [fit] extras")
    return OptionalTerms(parse_groups(",".join(groups), f"{where}: [fit] extras", allowed=tuple(GROUPS)))


def _matrix(rows, n: int) -> np.ndarray | None:
    """An ``n x n`` float array from a list of lists of finite TOML numbers, else None."""
    if not isinstance(rows, list) or len(rows) != n:
        return None
    out = np.empty((n, n))
    for i, row in enumerate(rows):
        if not isinstance(row, list) or len(row) != n:
            return None
        for j, x in enumerate(row):
            v = toml_number(x)
            if v is None or not math.isfinite(v):
                return None
            out[i, j] = v
    return out


def _attitude(table, where: str) -> np.ndarray:
    """``[initial_attitude] C_b_n``: a 3x3 rotation matrix."""
    C = _matrix(table.get("C_b_n") if isinstance(table, dict) else None, 3)
    if (
        C is None
        or np.any(np.abs(C) > 1.0 + 1e-6)
        or not np.allclose(C @ C.T, np.eye(3), atol=1e-6)
        or np.linalg.det(C) < 0
    ):
        raise CalibError("initial_attitude.C_b_n must be a 3x3 rotation matrix", where)
    return C


def _correlation(table, where: str) -> np.ndarray:
    """``[correlation]``: the 21 names in order and a 21x21 matrix within [-1, 1]."""
    fix = "remove the [correlation] table or write the 21x21 matrix of the fit"
    if not isinstance(table, dict):
        raise CalibError("[correlation] must be a table", where, fix)
    if table.get("names", list(P.NAMES)) != list(P.NAMES):
        raise CalibError("'names' must list the 21 parameters in order", where, fix)
    corr = _matrix(table.get("matrix"), P.N_PARAMS)
    if corr is None or np.any(np.abs(corr) > 1.0 + 1e-6):
        raise CalibError("'matrix' must be a 21x21 matrix of numbers within [-1, 1]", where, fix)
    return corr
