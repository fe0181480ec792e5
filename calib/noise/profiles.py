"""Noise profiles: the IMU's white noise (ARW, VRW), per ``docs/conventions.md``, and
optional first-order Gauss-Markov bias instability (see :mod:`calib.noise.gauss_markov`).
"""

from __future__ import annotations

import tomllib
import warnings
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from calib.errors import CalibError
from calib.io.fields import Fields, check_format_version
from calib.io.files import load_toml
from calib.io.kinds import expect
from calib.model.params import DEG, DEG_PER_HOUR, MICRO_G

DEFAULT_PROFILE = "navigation"
_RAD_PER_S_PER_DPH = DEG / 60.0  # 1 deg/sqrt(h) in rad/sqrt(s)


@dataclass(frozen=True)
class NoiseProfile:
    """White noise of the gyros and accelerometers, and optional GM bias instability.

    Frozen and hashable: it is a cache key of the noise models.

    Attributes
    ----------
    name : str
    gyro_arw_dph : float
        Angle random walk, deg/sqrt(h).
    accel_vrw_ug : float
        Velocity random walk, ug/sqrt(Hz).
    gyro_bias_instability_dph : float
        Steady-state 1-sigma of the first-order Gauss-Markov gyro bias, deg/h
        (0: no GM bias).
    gyro_bias_correlation_s : float
        Its correlation time, s.
    accel_bias_instability_ug : float
        Steady-state 1-sigma of the GM accelerometer bias, ug (0: none).
    accel_bias_correlation_s : float
        Its correlation time, s.
    """

    name: str
    gyro_arw_dph: float
    accel_vrw_ug: float
    gyro_bias_instability_dph: float = 0.0
    gyro_bias_correlation_s: float = 0.0
    accel_bias_instability_ug: float = 0.0
    accel_bias_correlation_s: float = 0.0

    @property
    def arw(self) -> float:
        """ARW in rad/sqrt(s): ``sigma(dtheta) = arw * sqrt(dt)``."""
        return self.gyro_arw_dph * _RAD_PER_S_PER_DPH

    @property
    def vrw(self) -> float:
        """VRW in m/s/sqrt(s): ``sigma(dv) = vrw * sqrt(dt)``."""
        return self.accel_vrw_ug * MICRO_G

    @property
    def gyro_gm_sigma(self) -> float:
        """Steady-state 1-sigma of the GM gyro bias, rad/s."""
        return self.gyro_bias_instability_dph * DEG_PER_HOUR

    @property
    def accel_gm_sigma(self) -> float:
        """Steady-state 1-sigma of the GM accelerometer bias, m/s^2."""
        return self.accel_bias_instability_ug * MICRO_G

    @property
    def has_gauss_markov(self) -> bool:
        """Whether either sensor has a GM bias (then the noise filter has 9 states)."""
        return self.gyro_bias_instability_dph > 0 or self.accel_bias_instability_ug > 0


def white_part(profile: NoiseProfile) -> NoiseProfile:
    """The profile's white noise alone (its Gauss-Markov biases dropped), named so."""
    if not profile.has_gauss_markov:
        return profile
    return NoiseProfile(f"{profile.name} (white part)", profile.gyro_arw_dph, profile.accel_vrw_ug)


def builtin_profiles() -> list[str]:
    """Names of the profiles shipped with the tool."""
    folder = resources.files("calib") / "data" / "profiles"
    return sorted(Path(p.name).stem for p in folder.iterdir() if p.name.endswith(".toml"))


# Plausible white noise, from the best navigation-grade sensors to the cheapest
# MEMS with a wide margin. Far outside, the analysis' noise weighting overflows
# (or loses positive definiteness) and its figures would mean nothing.
_RANGES = {"gyro_arw_dph": (1e-6, 100.0), "accel_vrw_ug": (1e-3, 1e5)}
# Optional GM bias instability: sigma >= 0 (0 = off) up to cheap-MEMS levels; a
# correlation time outside [1 s, ~12 days] is not a GM bias the runs (minutes to
# hours, 1 s observation intervals) can tell from white noise or a constant bias.
_GM_KEYS = {  # sigma key: (its correlation-time key, upper bound, unit)
    "gyro_bias_instability_dph": ("gyro_bias_correlation_s", 100.0, "deg/h"),
    "accel_bias_instability_ug": ("accel_bias_correlation_s", 1e5, "ug"),
}
_TAU_RANGE = (1.0, 1e6)


def _gauss_markov(fields: Fields) -> dict:
    """The optional GM keys, validated; absent keys are 0 (off)."""
    values = {}
    for key, (tau_key, high, unit) in _GM_KEYS.items():
        sigma = fields.number(
            key,
            0.0,
            low=0.0,
            high=high,
            unit=f" {unit}",
            fix=f"give the bias instability (steady-state 1-sigma) in {unit}, "
            "or leave it out for no Gauss-Markov bias",
        )
        tau_fix = (
            f"give the Gauss-Markov correlation time in seconds, in [{_TAU_RANGE[0]:g}, {_TAU_RANGE[1]:g}]"
        )
        tau = fields.number(tau_key, 0.0, low=0.0, unit=" s", fix=tau_fix)
        if sigma > 0 and tau == 0:
            raise CalibError(
                f"'{key}' = {sigma:g} needs a correlation time, but '{tau_key}' "
                f"is {'missing' if tau_key not in fields.table else 0}",
                fields.where,
                f"add '{tau_key} = <seconds>' in [{_TAU_RANGE[0]:g}, {_TAU_RANGE[1]:g}], or set '{key} = 0'",
            )
        if tau != 0:  # 0 means off; any other value must be a plausible correlation time
            fields.number(tau_key, low=_TAU_RANGE[0], high=_TAU_RANGE[1], unit=" s", fix=tau_fix)
        values[key], values[tau_key] = sigma, tau
    return values


PROFILE_KEYS = (
    "format_version",
    "name",
    "description",
    "source",
    "gyro_arw_dph",
    "accel_vrw_ug",
    "gyro_bias_instability_dph",
    "gyro_bias_correlation_s",
    "accel_bias_instability_ug",
    "accel_bias_correlation_s",
    "fit",
    "provenance",
)


def _from_doc(doc: dict, where: str) -> NoiseProfile:
    check_format_version(doc, "profile", where)
    fields = Fields(doc, where)
    for message in fields.check_keys(PROFILE_KEYS, "profile"):
        warnings.warn(message, stacklevel=3)
    values = {
        key: fields.number(
            key, low=low, high=high, positive=True, fix="give ARW in deg/sqrt(h) and VRW in ug/sqrt(Hz)"
        )
        for key, (low, high) in _RANGES.items()
    }
    values.update(_gauss_markov(fields))
    name = fields.string("name", Path(where).stem)
    if not name:
        raise CalibError("'name' must be a non-empty string", fields.here("name"))
    return NoiseProfile(name=name, **values)


def load_profile(name_or_path: NoiseProfile | str | Path = DEFAULT_PROFILE) -> NoiseProfile:
    """A built-in profile by name (``navigation``, ``navigation-gm``, ``tactical``) or a
    profile TOML file; a :class:`NoiseProfile` is returned as it is.
    """
    if isinstance(name_or_path, NoiseProfile):
        return name_or_path
    text = str(name_or_path)
    path = Path(text)
    if not path.exists():
        if text in builtin_profiles():
            resource = resources.files("calib") / "data" / "profiles" / f"{text}.toml"
            return _from_doc(tomllib.loads(resource.read_text("utf-8")), text)
        raise CalibError(
            f"no noise profile {text!r}",
            None,
            "give a built-in name (" + ", ".join(builtin_profiles()) + ") or a path to a profile TOML file",
        )
    expect(path, "profile")
    doc = load_toml(path)
    return _from_doc(doc, str(path))
