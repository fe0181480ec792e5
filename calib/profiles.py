"""Noise profiles: the IMU's white noise (ARW, VRW), per ``conventions.md``."""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from .errors import CalibError
from .fileio import load_toml
from .params import DEG, MICRO_G

DEFAULT_PROFILE = "navigation"
_RAD_PER_S_PER_DPH = DEG / 60.0  # 1 deg/sqrt(h) in rad/sqrt(s)


@dataclass(frozen=True)
class NoiseProfile:
    """White noise of the gyros and accelerometers.

    Attributes
    ----------
    name : str
    gyro_arw_dph : float
        Angle random walk, deg/sqrt(h).
    accel_vrw_ug : float
        Velocity random walk, ug/sqrt(Hz).
    """

    name: str
    gyro_arw_dph: float
    accel_vrw_ug: float

    @property
    def arw(self) -> float:
        """ARW in rad/sqrt(s): ``sigma(dtheta) = arw * sqrt(dt)``."""
        return self.gyro_arw_dph * _RAD_PER_S_PER_DPH

    @property
    def vrw(self) -> float:
        """VRW in m/s/sqrt(s): ``sigma(dv) = vrw * sqrt(dt)``."""
        return self.accel_vrw_ug * MICRO_G


def builtin_profiles() -> list[str]:
    folder = resources.files("calib") / "profiles"
    return sorted(Path(p.name).stem for p in folder.iterdir() if p.name.endswith(".toml"))


# Plausible white noise, from the best navigation-grade sensors to the cheapest
# MEMS with a wide margin. Far outside, the analysis' noise weighting overflows
# (or loses positive definiteness) and its figures would mean nothing.
_RANGES = {"gyro_arw_dph": (1e-6, 100.0), "accel_vrw_ug": (1e-3, 1e5)}


def _from_doc(doc: dict, where: str) -> NoiseProfile:
    values = {}
    for key in ("gyro_arw_dph", "accel_vrw_ug"):
        if key not in doc:
            raise CalibError(f"missing key '{key}'", where, f"add '{key} = <number>'")
        v = doc[key]
        try:
            number = float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None
        except OverflowError:  # an integer beyond the float range
            number = None
        if number is None or not math.isfinite(number) or number <= 0:
            raise CalibError(f"'{key}' must be a positive finite number, got {v!r}", where)
        low, high = _RANGES[key]
        if not low <= number <= high:
            raise CalibError(f"'{key}' = {number:g} is outside the plausible range "
                             f"[{low:g}, {high:g}]", where,
                             "give ARW in deg/sqrt(h) and VRW in ug/sqrt(Hz)")
        values[key] = number
    name = doc.get("name", Path(where).stem)
    if not isinstance(name, str) or not name:
        raise CalibError("'name' must be a non-empty string", where)
    return NoiseProfile(name=name, **values)


def load_profile(name_or_path: str | Path = DEFAULT_PROFILE) -> NoiseProfile:
    """A built-in profile by name (``navigation``, ``tactical``) or a profile TOML file."""
    text = str(name_or_path)
    path = Path(text)
    if not path.exists():
        if text in builtin_profiles():
            resource = resources.files("calib") / "profiles" / f"{text}.toml"
            return _from_doc(tomllib.loads(resource.read_text("utf-8")), text)
        raise CalibError(f"no noise profile {text!r}", None,
                         "give a built-in name (" + ", ".join(builtin_profiles())
                         + ") or a path to a profile TOML file")
    doc = load_toml(path)
    return _from_doc(doc, str(path))
