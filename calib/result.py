"""A calibration result: 21 values with 1-sigma, the initial attitude and the fit's health.

Saved and loaded as the result TOML of ``files.md`` (values in spec units).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import params as P
from .errormodel import ErrorModel
from .errors import CalibError


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

    @property
    def error_model(self) -> ErrorModel:
        return ErrorModel(self.values)

    def to_dict(self) -> dict:
        vals, sig = P.from_si(self.values), P.from_si(self.sigma)
        doc = {"parameters": {p.name: {"value": float(vals[p.index]), "sigma": float(sig[p.index]),
                                       "unit": p.unit} for p in P.PARAMETERS},
               "initial_attitude": {"C_b_n": [[float(x) for x in row] for row in self.C_b_n0]},
               "fit": {"converged": bool(self.converged), "iterations": int(self.iterations),
                       "residual_rms_mps": float(self.residual_rms_mps),
                       "chi2_per_dof": float(self.chi2_per_dof), "profile": self.profile}}
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
        where = str(path)
        try:
            doc = tomllib.loads(Path(path).read_bytes().decode("utf-8"))
        except UnicodeDecodeError as exc:
            raise CalibError(f"not UTF-8 text (byte {exc.start})", where) from None
        except tomllib.TOMLDecodeError as exc:
            raise CalibError(f"not valid TOML: {exc}", where) from None
        except OSError as exc:
            raise CalibError(f"cannot read: {exc.strerror}", where) from None
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
                v = entry.get(key)
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                    raise CalibError(f"'{key}' must be a finite number, got {v!r}", here,
                                     "a result without uncertainties is not a result")
                out.append(float(v))
            if sig[-1] < 0:
                raise CalibError(f"sigma {sig[-1]} is negative", here)
        att = doc.get("initial_attitude", {}).get("C_b_n") if isinstance(
            doc.get("initial_attitude"), dict) else None
        try:
            C = np.array(att, dtype=float)
            if C.shape != (3, 3) or not np.allclose(C @ C.T, np.eye(3), atol=1e-6):
                raise ValueError
        except (TypeError, ValueError):
            raise CalibError("initial_attitude.C_b_n must be a 3x3 rotation matrix",
                             f"{where}: [initial_attitude]") from None
        fit = doc.get("fit", {}) if isinstance(doc.get("fit"), dict) else {}
        corr = None
        if isinstance(doc.get("correlation"), dict):
            try:
                corr = np.array(doc["correlation"]["matrix"], dtype=float)
                if corr.shape != (P.N_PARAMS, P.N_PARAMS):
                    corr = None
            except (KeyError, TypeError, ValueError):
                corr = None
        return cls(values=P.to_si(vals), sigma=P.to_si(sig), C_b_n0=C,
                   converged=bool(fit.get("converged", False)),
                   iterations=int(fit.get("iterations", 0)),
                   residual_rms_mps=float(fit.get("residual_rms_mps", float("nan"))),
                   profile=str(fit.get("profile", "")),
                   chi2_per_dof=float(fit.get("chi2_per_dof", float("nan"))),
                   correlation=corr,
                   provenance=doc.get("provenance", {}) if isinstance(doc.get("provenance"), dict) else {})
