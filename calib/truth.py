"""Truth files of simulated runs (``run.truth.toml``) and error files (``--errors``)."""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np

from . import params as P
from .errormodel import ErrorModel
from .errors import CalibError
from .sim import Truth


def truth_path_for(run_path: str | Path) -> Path:
    """``run.csv`` / ``run.npz`` -> ``run.truth.toml`` beside it."""
    p = Path(run_path)
    return p.with_name(p.stem + ".truth.toml")


def _load_toml(path: Path) -> dict:
    try:
        return tomllib.loads(Path(path).read_bytes().decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise CalibError(f"not UTF-8 text (byte {exc.start})", str(path)) from None
    except tomllib.TOMLDecodeError as exc:
        raise CalibError(f"not valid TOML: {exc}", str(path)) from None
    except OSError as exc:
        raise CalibError(f"cannot read: {exc.strerror}", str(path)) from None


def _finite(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise CalibError(f"must be a finite number, got {value!r}", where)
    return float(value)


def errors_from_table(table, where: str) -> ErrorModel:
    """An :class:`ErrorModel` from an ``[errors]`` table keyed by spec names, spec units."""
    if not isinstance(table, dict):
        raise CalibError("missing table [errors]", where,
                         "add [errors] with the 21 parameters: " + " ".join(P.NAMES))
    missing = [n for n in P.NAMES if n not in table]
    if missing:
        raise CalibError("[errors] lacks " + ", ".join(missing), where,
                         "give all 21 parameters in the units of conventions.md")
    values = [_finite(table[n], f"{where}: [errors] {n}") for n in P.NAMES]
    # Beyond these the small-error model of the conventions no longer holds.
    limits = {"bias": None, "scale": 0.05, "misalignment": 0.05}
    for p, v in zip(P.PARAMETERS, values):
        lim = limits[p.kind]
        if lim is not None and abs(v * p.si_per_unit) > lim:
            raise CalibError(f"{p.name} = {v} {p.unit} is beyond the small-error model (|.| <= "
                             f"{lim / p.si_per_unit:g} {p.unit})", f"{where}: [errors] {p.name}")
    return ErrorModel.from_units(values)


def read_errors(path: str | Path) -> ErrorModel:
    """The ``[errors]`` table of an error or truth file."""
    return errors_from_table(_load_toml(Path(path)).get("errors"), str(path))


def read_truth(path: str | Path) -> Truth:
    """Read a truth file written by :func:`write_truth` (or by hand)."""
    doc = _load_toml(Path(path))
    where = str(path)
    errors = errors_from_table(doc.get("errors"), where)
    setup = doc.get("setup", {})
    if not isinstance(setup, dict):
        raise CalibError("[setup] must be a table", where)
    rotvec = np.radians([_finite(setup.get(k, 0.0), f"{where}: [setup] {k}")
                         for k in ("east_deg", "north_deg", "up_deg")])
    meta = doc.get("meta", {}) if isinstance(doc.get("meta", {}), dict) else {}
    flips = doc.get("flips", {}).get("angle_error_deg", []) if isinstance(doc.get("flips"), dict) else []
    return Truth(errors=errors, setup_rotvec=rotvec,
                 flip_errors_deg=np.array([_finite(f, f"{where}: [flips]") for f in flips]),
                 profile=str(meta.get("profile", "")), seed=meta.get("seed"),
                 noise=bool(meta.get("noise", True)))


def truth_to_dict(truth: Truth) -> dict:
    values = truth.errors.in_units()
    setup = np.degrees(truth.setup_rotvec)
    meta = {"profile": truth.profile, "noise": bool(truth.noise)}
    if truth.seed is not None:
        meta["seed"] = int(truth.seed)
    return {
        "errors": {n: float(v) for n, v in zip(P.NAMES, values)},
        "setup": {"east_deg": float(setup[0]), "north_deg": float(setup[1]),
                  "up_deg": float(setup[2])},
        "flips": {"angle_error_deg": [float(f) for f in truth.flip_errors_deg]},
        "meta": meta,
    }


def write_truth(path: str | Path, truth: Truth, provenance: dict | None = None) -> None:
    import tomli_w

    from .fileio import atomic_write_text
    doc = truth_to_dict(truth)
    if provenance:
        doc["provenance"] = provenance
    atomic_write_text(path, tomli_w.dumps(doc))
