"""Accuracy requirements on the 21 calibration errors: the paper's, a shipped class, or a file.

The ratio ``3 sigma / requirement`` is the figure every verdict, bound and
design objective is judged by, and the requirement-scaled information is
where :mod:`calib.model.information` decides what is observable. A navigation-grade
paper's requirements make no sense for a MEMS unit, so they are an input:
``--requirements FILE`` (TOML with a ``[requirements]`` table, ``NAME =
value`` by spec name in spec units; the parameters it leaves out keep the
paper's), or a shipped name (``paper``, ``tactical``, ``mems``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.io.fields import Fields, check_format_version
from calib.io.files import load_toml

from . import params as P

DEFAULT = "paper"


@dataclass(frozen=True)
class Requirements:
    """The requirement on each of the 21 calibration errors, in spec units.

    Frozen and hashable (by name and values) so that it can key caches.
    """

    name: str
    values: tuple  # (21,) spec units, in spec order
    source: str = ""
    extra: dict = field(default_factory=dict, compare=False, hash=False)

    @property
    def si(self) -> np.ndarray:
        """The requirements in SI (rad/s, m/s^2, dimensionless)."""
        return np.asarray(self.values) * P.SI_PER_UNIT

    def ratio(self, sigma_si: np.ndarray) -> np.ndarray:
        """``3 sigma / requirement`` per parameter."""
        return 3.0 * np.asarray(sigma_si) / self.si

    def of(self, name: str) -> float:
        return float(self.values[P.INDEX[name]])

    @property
    def is_paper(self) -> bool:
        return tuple(self.values) == tuple(P.REQUIREMENTS)


PAPER = Requirements("paper", tuple(float(x) for x in P.REQUIREMENTS), "the reference paper, section 3.2")


def builtin_dir() -> Path:
    """Folder of the requirement sets shipped with the tool."""
    return Path(str(resources.files("calib") / "data" / "requirements"))


def load_requirements(name_or_path: str | Path | Requirements | None = None) -> Requirements:
    """Requirements from a shipped name, a TOML file, or as given (None: the paper's)."""
    if name_or_path is None:
        return PAPER
    if isinstance(name_or_path, Requirements):
        return name_or_path
    text = str(name_or_path)
    if text == DEFAULT:
        return PAPER
    path = Path(text)
    if not path.exists():
        builtin = builtin_dir() / f"{text}.toml"
        if not builtin.exists():
            names = sorted(p.stem for p in builtin_dir().glob("*.toml"))
            raise CalibError(
                f"no requirements file or shipped set named {text!r}",
                "requirements",
                f"give a TOML file or one of: paper, {', '.join(names)}",
            )
        path = builtin
    return requirements_from_dict(load_toml(path), str(path))


# A unit's grade from its gyro's white noise (ARW, deg/sqrt(h), at most): the shipped profiles
# sit at 0.001 (navigation), 0.05 (tactical) and 2.6 (mems). verify draws each grade's errors
# by them (seqdesign.verify.grade_of); each grade's shipped requirements (paper: navigation
# grade) are its default.
GRADES = ((0.01, "navigation", DEFAULT), (0.5, "tactical", "tactical"), (math.inf, "MEMS", "mems"))


def grade_of(profile) -> tuple[str, str]:
    """The grade of a noise profile and the name of its default requirements (``("MEMS", "mems")``)."""
    for arw_dph, grade, name in GRADES:
        if profile.gyro_arw_dph <= arw_dph:
            return grade, name
    raise AssertionError("the last grade has no upper bound")


def default_for(profile, requirements: str | Path | Requirements | None) -> tuple[object, str | None]:
    """The requirements to judge ``profile``'s unit by, and the line that says so when chosen here.

    Given requirements are kept (no line). Without them, the profile's grade gives
    the default: a MEMS unit is not judged by the paper's navigation-grade
    requirements, which every sigma of it would miss a thousand times over.
    """
    if requirements is not None:
        return requirements, None
    grade, name = grade_of(profile)
    if name == DEFAULT:
        return None, None
    return name, (
        f"requirements {name}: the default for profile {profile.name}, a {grade} unit (gyro ARW "
        f"{profile.gyro_arw_dph:.3g} deg/sqrt(h)); give --requirements to judge it by others"
    )


def requirements_from_dict(doc: dict, where: str) -> Requirements:
    """Validate a parsed requirements document; the parameters it omits keep the paper's."""
    top = Fields(doc, where)
    if "requirements" not in doc:
        raise CalibError(
            "missing table [requirements]",
            where,
            "write [requirements] with NAME = value per parameter, e.g. sgx = 50",
        )
    check_format_version(doc, "requirements", where)
    for w in top.check_keys(
        ("name", "source", "format_version", "requirements", "provenance"), "requirements file"
    ):
        warnings.warn(w, stacklevel=2)
    table = top.sub("requirements", required=True)
    table.check_keys(P.NAMES, "parameter")  # a typo of a name is refused, naming the closest
    unknown = [k for k in table.table if k not in P.INDEX]
    if unknown:
        raise CalibError(
            f"unknown parameter(s) {', '.join(unknown)}",
            table.where,
            f"use the spec names: {', '.join(P.NAMES)}",
        )
    values = [table.number(p.name, p.requirement, positive=True, unit=f" {p.unit}") for p in P.PARAMETERS]
    name = top.string("name", Path(where).stem)
    return Requirements(name, tuple(float(v) for v in values), top.string("source", ""))
