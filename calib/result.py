"""A calibration result: 21 values with 1-sigma, the initial attitude and the fit's health.

Saved and loaded as the result TOML of ``files.md`` (values in spec units).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import params as P
from .errormodel import ErrorModel
from .errors import CalibError
from .extras import NONE as NO_EXTRAS, Extras, parse_groups
from .fileio import load_toml, toml_number


@dataclass(frozen=True)
class CalibrationResult:
    """Estimated parameters (SI inside) and how far to trust them.

    Attributes
    ----------
    values, sigma : ndarray, shape (21,)
        Estimates and 1-sigma, SI.
    C_b_n0 : ndarray, shape (3, 3)
        Attitude at the first sample.
    converged : bool
    iterations : int
    residual_rms_mps : float
    profile : str
    chi2_per_dof : float
        Whitened residual power per degree of freedom: ~1 when the noise
        profile describes the run.
    correlation : ndarray, shape (21, 21) or None
    provenance : dict
    extras : Extras
        Optional terms fitted with the 21 (:mod:`calib.extras`); saved after
        the 21 in ``[parameters]`` and named in ``[fit] extras``.
    extra_values, extra_sigma : ndarray, shape (extras.n,)
        SI.
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
    extras: Extras = NO_EXTRAS
    extra_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    extra_sigma: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def error_model(self) -> ErrorModel:
        return ErrorModel(self.values)

    def to_dict(self) -> dict:
        vals, sig = P.from_si(self.values), P.from_si(self.sigma)
        doc = {"parameters": {p.name: {"value": float(vals[p.index]), "sigma": float(sig[p.index]),
                                       "unit": p.unit} for p in P.PARAMETERS}
               | {p.name: {"value": float(v / p.si_per_unit), "sigma": float(e / p.si_per_unit),
                           "unit": p.unit}
                  for p, v, e in zip(self.extras.parameters, self.extra_values, self.extra_sigma)},
               "initial_attitude": {"C_b_n": [[float(x) for x in row] for row in self.C_b_n0]},
               "fit": {"converged": bool(self.converged), "iterations": int(self.iterations),
                       "residual_rms_mps": float(self.residual_rms_mps),
                       "chi2_per_dof": float(self.chi2_per_dof), "profile": self.profile}}
        if self.extras.groups:
            doc["fit"]["extras"] = list(self.extras.groups)
        if self.correlation is not None:
            doc["correlation"] = {"names": list(P.NAMES),
                                  "matrix": [[round(float(x), 6) for x in row]
                                             for row in self.correlation]}
        if self.provenance:
            doc["provenance"] = dict(self.provenance)
        return doc

    def save(self, path: str | Path) -> None:
        import tomli_w

        from .fileio import atomic_write_text
        atomic_write_text(path, tomli_w.dumps(self.to_dict()))

    @classmethod
    def load(cls, path: str | Path) -> "CalibrationResult":
        """Read a result TOML; refuse it, naming the file and table, unless it is complete.

        ``[parameters]`` (all 21 with finite value and non-negative sigma) and
        ``[initial_attitude]`` are required; ``[fit]`` keys, ``[correlation]``
        and ``[provenance]`` are optional, but when present must be well-formed.
        """

        def _matrix(rows, n: int) -> np.ndarray | None:
            """An ``n x n`` float array from a list of lists of TOML numbers, else None."""
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
            if (C is None or np.any(np.abs(C) > 1.0 + 1e-6)
                    or not np.allclose(C @ C.T, np.eye(3), atol=1e-6) or np.linalg.det(C) < 0):
                raise CalibError("initial_attitude.C_b_n must be a 3x3 rotation matrix", where)
            return C

        def _correlation(table, where: str) -> np.ndarray:
            """``[correlation]``: the 21 names in order and a 21x21 matrix within [-1, 1]."""
            fix = "remove the [correlation] table or write the 21x21 matrix of the fit"
            if not isinstance(table, dict):
                raise CalibError("[correlation] must be a table", where, fix)
            names = table.get("names", list(P.NAMES))
            if names != list(P.NAMES):
                raise CalibError("'names' must list the 21 parameters in order", where, fix)
            corr = _matrix(table.get("matrix"), P.N_PARAMS)
            if corr is None or np.any(np.abs(corr) > 1.0 + 1e-6):
                raise CalibError("'matrix' must be a 21x21 matrix of numbers within [-1, 1]",
                                 where, fix)
            return corr

        where = str(path)
        doc = load_toml(path)
        table = doc.get("parameters")
        if not isinstance(table, dict):
            raise CalibError("missing table [parameters]", where, "is this a result file?")
        vals, sig = [], []
        for p in P.PARAMETERS:
            entry = table.get(p.name)
            here = f"{where}: [parameters.{p.name}]"
            if not isinstance(entry, dict):
                raise CalibError("missing", here, "a result carries all 21 parameters")
            for key, out in (("value", vals), ("sigma", sig)):
                v = toml_number(entry.get(key))
                if v is None or not math.isfinite(v):
                    raise CalibError(f"'{key}' must be a finite number, got {entry.get(key)!r}",
                                     here, "a result without uncertainties is not a result")
                out.append(v)
            if sig[-1] < 0:
                raise CalibError(f"sigma {sig[-1]} is negative", here)
        C = _attitude(doc.get("initial_attitude"), f"{where}: [initial_attitude]")
        fit = doc.get("fit", {})
        if not isinstance(fit, dict):
            raise CalibError("[fit] must be a table", where)
        groups = fit.get("extras", [])
        if not isinstance(groups, list) or not all(isinstance(g, str) for g in groups):
            raise CalibError("must be a list of names", f"{where}: [fit] extras")
        extras = Extras(parse_groups(",".join(groups), f"{where}: [fit] extras"))
        xv, xs = [], []
        for p in extras.parameters:
            entry = table.get(p.name)
            here = f"{where}: [parameters.{p.name}]"
            if not isinstance(entry, dict):
                raise CalibError("missing", here, f"[fit] extras names {p.group}")
            for key, out in (("value", xv), ("sigma", xs)):
                v = toml_number(entry.get(key))
                if v is None or not math.isfinite(v) or (key == "sigma" and v < 0):
                    raise CalibError(f"'{key}' must be a finite number, got {entry.get(key)!r}",
                                     here)
                out.append(v * p.si_per_unit)
        converged = fit.get("converged", False)
        if not isinstance(converged, bool):
            raise CalibError(f"must be true or false, got {converged!r}",
                             f"{where}: [fit] converged")
        iterations = fit.get("iterations", 0)
        if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 0:
            raise CalibError(f"must be a non-negative integer, got {iterations!r}",
                             f"{where}: [fit] iterations")
        figures = {}
        for key in ("residual_rms_mps", "chi2_per_dof"):
            # NaN stands for "not computed"; anything else must be a finite number >= 0.
            v = toml_number(fit.get(key, math.nan))
            if v is None or math.isinf(v) or v < 0:
                raise CalibError(f"must be a finite number >= 0 (or nan), got {fit.get(key)!r}",
                                 f"{where}: [fit] {key}")
            figures[key] = v
        profile = fit.get("profile", "")
        if not isinstance(profile, str):
            raise CalibError(f"must be a string, got {profile!r}", f"{where}: [fit] profile")
        corr = None
        if "correlation" in doc:
            corr = _correlation(doc["correlation"], f"{where}: [correlation]")
        provenance = doc.get("provenance", {})
        if not isinstance(provenance, dict):
            raise CalibError("[provenance] must be a table", where)
        return cls(values=P.to_si(vals), sigma=P.to_si(sig), C_b_n0=C,
                   converged=converged, iterations=iterations,
                   residual_rms_mps=figures["residual_rms_mps"], profile=profile,
                   chi2_per_dof=figures["chi2_per_dof"], correlation=corr,
                   provenance=provenance, extras=extras, extra_values=np.array(xv),
                   extra_sigma=np.array(xs))
