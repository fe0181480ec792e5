"""Truth files of simulated runs (``run.truth.toml``) and error files (``--errors``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.io.fields import FORMAT_VERSION, Fields, check_format_version
from calib.io.files import atomic_write_text, load_toml, toml_number
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.model.optional_terms import OptionalTermValues

from .gimbal_run import Truth


def truth_path_for(run_path: str | Path) -> Path:
    """``run.csv`` / ``run.npz`` -> ``run.truth.toml`` beside it."""
    p = Path(run_path)
    return p.with_name(p.stem + ".truth.toml")


def _finite(value, where: str) -> float:
    number = toml_number(value)
    if number is None or not math.isfinite(number):
        raise CalibError(f"must be a finite number, got {value!r}", where)
    return number


# What ``simulate`` can produce (its --setup-deg and --flip-error-deg limits), degrees.
SETUP_LIMIT_DEG = 10.0
FLIP_ERROR_LIMIT_DEG = 10.0


def errors_from_table(table, where: str) -> ErrorModel:
    """An :class:`ErrorModel` from an ``[errors]`` table keyed by spec names, spec units."""
    if not isinstance(table, dict):
        raise CalibError(
            "missing table [errors]", where, "add [errors] with the 21 parameters: " + " ".join(P.NAMES)
        )
    missing = [n for n in P.NAMES if n not in table]
    if missing:
        raise CalibError(
            "[errors] lacks " + ", ".join(missing),
            where,
            "give all 21 parameters in the units of docs/conventions.md",
        )
    values = [_finite(table[n], f"{where}: [errors] {n}") for n in P.NAMES]
    # Beyond these the small-error model of the conventions no longer holds (SI):
    # 5 % for scale factors and misalignments; a gyro bias of 1 deg/s (a tenth of
    # the flip rate) and an accelerometer bias of 0.05 g.
    limits = {("gyro", "bias"): math.radians(1.0), ("accel", "bias"): 0.05 * P.STANDARD_GRAVITY}
    for p, v in zip(P.PARAMETERS, values, strict=True):
        lim = limits.get((p.sensor, p.kind), 0.05)
        if abs(v * p.si_per_unit) > lim:
            raise CalibError(
                f"{p.name} = {v} {p.unit} is beyond the small-error model (|.| <= "
                f"{lim / p.si_per_unit:g} {p.unit})",
                f"{where}: [errors] {p.name}",
            )
    return ErrorModel.from_units(values)


def read_errors(path: str | Path) -> ErrorModel:
    """The ``[errors]`` table of an error or truth file."""
    return errors_from_table(load_toml(Path(path)).get("errors"), str(path))


def read_truth(path: str | Path) -> Truth:
    """Read a truth file written by :func:`write_truth` (or by hand)."""
    doc = load_toml(Path(path))
    where = str(path)
    check_format_version(doc, "truth", where)
    errors = errors_from_table(doc.get("errors"), where)
    fields = Fields(doc, where)
    small = "a simulated run's mounting rotation and flip errors are small angles"
    setup = fields.sub("setup") or Fields({}, f"{where}: [setup]")
    rotvec = np.radians(
        [
            setup.number(k, 0.0, low=-SETUP_LIMIT_DEG, high=SETUP_LIMIT_DEG, unit=" deg", fix=small)
            for k in ("east_deg", "north_deg", "up_deg")
        ]
    )
    flips = fields.sub("flips") or Fields({}, f"{where}: [flips]")
    flip_errors = np.array(
        flips.numbers(
            "angle_error_deg",
            [],
            low=-FLIP_ERROR_LIMIT_DEG,
            high=FLIP_ERROR_LIMIT_DEG,
            unit=" deg",
            fix="a simulated run's flip errors: one small angle per flip, in degrees",
        ),
        dtype=float,
    )
    meta = fields.sub("meta") or Fields({}, f"{where}: [meta]")
    profile = meta.string("profile", "")
    seed = meta.integer("seed", None)
    noise = meta.boolean("noise", True)
    return Truth(
        errors=errors,
        setup_rotvec=rotvec,
        flip_errors_deg=flip_errors,
        profile=profile,
        seed=seed,
        noise=noise,
        extra=_extra(doc.get("extra"), where),
    )


def _extra(table, where: str):
    """The optional ``[extra]`` table (calib.model.optional_terms names, report units), or None."""
    if table is None:
        return None
    here = f"{where}: [extra]"
    if not isinstance(table, dict):
        raise CalibError("must be a table of name = value", here)
    values = {k: _finite(v, f"{here} {k}") for k, v in table.items()}
    extra = OptionalTermValues.from_units(values, here)
    return extra if extra.active else None


def truth_to_dict(truth: Truth) -> dict:
    """The truth TOML document of a simulated run (spec units)."""
    values = truth.errors.in_units()
    setup = np.degrees(truth.setup_rotvec)
    meta = {"profile": truth.profile, "noise": bool(truth.noise)}
    if truth.seed is not None:
        meta["seed"] = int(truth.seed)
    doc = {
        "format_version": FORMAT_VERSION,
        "errors": {n: float(v) for n, v in zip(P.NAMES, values, strict=True)},
        "setup": {"east_deg": float(setup[0]), "north_deg": float(setup[1]), "up_deg": float(setup[2])},
        "flips": {"angle_error_deg": [float(f) for f in truth.flip_errors_deg]},
        "meta": meta,
    }
    if truth.extra is not None:
        doc["extra"] = {k: v for k, v in truth.extra.in_units().items() if v != 0.0}
    return doc


def write_truth(path: str | Path, truth: Truth, provenance: dict | None = None) -> None:
    """Write a truth file atomically, with the provenance of the simulation."""
    import tomli_w

    doc = truth_to_dict(truth)
    if provenance:
        doc["provenance"] = provenance
    atomic_write_text(path, tomli_w.dumps(doc))
