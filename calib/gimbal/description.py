"""A gimbal description: its three axes' limits, the lock margin, and the gimbal files.

What a gimbal *is* (read from ``sequences/gimbals/*.toml`` or a user's file); what it
*does* along a sequence (which gimbal plays each flip, lock, encoder angles) is
:mod:`calib.gimbal.rule`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from calib.errors import CalibError
from calib.io.fields import Fields, check_format_version
from calib.io.files import load_toml, toml_number

NAMES = ("outer", "middle", "inner")


@dataclass(frozen=True)
class GimbalAxis:
    """Limits of one gimbal (SI); ``inf`` means unlimited."""

    name: str
    min_angle: float = -math.inf
    max_angle: float = math.inf
    max_rate: float = math.inf
    max_accel: float = math.inf
    max_jerk: float = math.inf


@dataclass(frozen=True)
class Gimbal:
    """A gimbal description: three axes, the lock margin, and whether runs must end at home."""

    name: str
    axes: tuple[GimbalAxis, ...]  # outer, middle, inner
    lock_margin: float = 0.0  # rad: the middle gimbal stays this far from +-90 deg
    end_at_home: bool = False
    description: str = ""
    path: str | None = None

    @property
    def min_rate(self) -> float:
        return min(a.max_rate for a in self.axes)


DEFAULT_GIMBAL = Gimbal(
    name="default (slip rings, no limits)",
    axes=(GimbalAxis(NAMES[0]), GimbalAxis(NAMES[1]), GimbalAxis(NAMES[2])),
)


# ---------------------------------------------------------------------------
# The gimbal file


def _limit(table: dict, key: str, where: str) -> float:
    """A positive limit in file units, or inf when absent."""
    if key not in table:
        return math.inf
    value = toml_number(table[key])
    if value is None or not math.isfinite(value) or value <= 0:
        raise CalibError(
            f"'{key}' must be a positive number, got {table[key]!r}",
            where,
            f"give {key} > 0, or leave it out for no limit",
        )
    return value


def _axis_from_dict(name: str, table, where: str) -> GimbalAxis:
    here = f"{where}: [{name}]"
    if not isinstance(table, dict):
        raise CalibError(f"'{name}' must be a table", here, f"write [{name}] with its limits")
    _warn_unknown(table, AXIS_KEYS, "gimbal axis", here)
    lo, hi = Fields(table, here).numbers(  # no range: slip rings
        "range_deg",
        (-math.inf, math.inf),
        length=2,
        unit=" deg",
        fix="give [min, max] in degrees, e.g. range_deg = [-360, 360]; leave it out for slip rings",
    )
    if not lo < 0.0 < hi:
        raise CalibError(
            f"range_deg = [{lo:g}, {hi:g}] excludes the start (every encoder starts at 0)",
            here,
            "give min < 0 < max",
        )
    deg = math.radians
    return GimbalAxis(
        name,
        deg(lo),
        deg(hi),
        deg(_limit(table, "max_rate_dps", here)),
        deg(_limit(table, "max_accel_dps2", here)),
        deg(_limit(table, "max_jerk_dps3", here)),
    )


GIMBAL_KEYS = (
    "format_version",
    "name",
    "description",
    "lock_margin_deg",
    "end_at_home",
    "outer",
    "middle",
    "inner",
)
AXIS_KEYS = ("range_deg", "max_rate_dps", "max_accel_dps2", "max_jerk_dps3")


def _warn_unknown(table: dict, known, kind: str, where: str) -> None:
    """A near miss of a known key is refused (a typo would drop a limit); others are warned."""
    import warnings

    for message in Fields(table, where).check_keys(known, kind):
        warnings.warn(message, stacklevel=3)


def gimbal_from_dict(doc: dict, where: str) -> Gimbal:
    """Validate a parsed gimbal TOML document (see docs/gimbal.md)."""
    check_format_version(doc, "gimbal", where)
    _warn_unknown(doc, GIMBAL_KEYS, "gimbal", where)
    name = doc.get("name", Path(where).stem)
    if not isinstance(name, str) or not name:
        raise CalibError("'name' must be a non-empty string", f"{where}: key 'name'")
    missing = [n for n in NAMES if n not in doc]
    if missing:
        raise CalibError(
            f"no [{missing[0]}] table",
            where,
            "give [outer], [middle] and [inner] (an empty table means no limits)",
        )
    axes = tuple(_axis_from_dict(n, doc[n], where) for n in NAMES)
    margin = toml_number(doc.get("lock_margin_deg", 0.0))
    if margin is None or not 0.0 <= margin < 90.0:
        raise CalibError(
            f"lock_margin_deg must be in [0, 90), got {doc.get('lock_margin_deg')!r}",
            f"{where}: key 'lock_margin_deg'",
        )
    home = doc.get("end_at_home", False)
    if not isinstance(home, bool):
        raise CalibError(f"end_at_home must be true or false, got {home!r}", f"{where}: key 'end_at_home'")
    description = doc.get("description", "")
    return Gimbal(
        name=name,
        axes=axes,
        lock_margin=math.radians(margin),
        end_at_home=home,
        description=description if isinstance(description, str) else "",
        path=where,
    )


def builtin_gimbal_dir() -> Path:
    """Folder of the gimbal descriptions shipped with the tool."""
    return Path(str(resources.files("sequences"))) / "gimbals"


def load_gimbal(name_or_path: Gimbal | str | Path | None) -> Gimbal:
    """A gimbal file by path or shipped name (``cable-wrap``); None gives :data:`DEFAULT_GIMBAL`, a
    :class:`Gimbal` is returned as it is.
    """
    if name_or_path is None:
        return DEFAULT_GIMBAL
    if isinstance(name_or_path, Gimbal):
        return name_or_path
    p = Path(name_or_path)
    if not p.exists():
        shipped = builtin_gimbal_dir() / f"{p.name}.toml"
        if p.suffix == "" and shipped.exists():
            p = shipped
        else:
            names = ", ".join(sorted(f.stem for f in builtin_gimbal_dir().glob("*.toml")))
            raise CalibError(
                f"no gimbal file {str(name_or_path)!r}",
                "gimbal",
                f"give a path to a .toml file or a shipped name: {names}",
            )
    return gimbal_from_dict(load_toml(p), str(p))
