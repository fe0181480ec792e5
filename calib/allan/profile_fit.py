"""A noise profile from a static log: Allan deviation per axis, fitted terms, the file.

The profile's scalars (``gyro_arw_dph``, ``accel_vrw_ug`` and the Gauss-Markov
keys of :mod:`calib.noise.profiles`) follow the worst axis (:mod:`calib.allan.profile_gm`);
the per-axis terms and fit quality (:mod:`calib.allan.noise_terms`), what the scalars do
not model, the biases and the fit's provenance go in a ``[fit]`` table that
`load_profile` ignores (``docs/profiles.md``), and what they do not model also in
the comment the file opens with.
"""

from __future__ import annotations

import tomllib
import warnings
from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError
from calib.io.files import atomic_write_text
from calib.model.params import DEG, DEG_PER_HOUR, MICRO_G
from calib.nav.site import site_of
from calib.noise.profiles import NoiseProfile, _from_doc
from calib.runlog import Run, read_run

from .deviation import AllanCurve, allan_deviation
from .noise_terms import TRUSTED_CI, NoiseFit, fit_noise
from .plot import plot_allan
from .profile_gm import CALIBRATION_TAU_S, PROFILE_SIGMA_MAX, ProfileGM, not_modelled, profile_gm
from .static import StaticLevel, static_level

AXES = ("x", "y", "z")
METHOD = (
    "overlapping Allan deviation (allantools.oadev, 4 taus per octave, 68 % CI from "
    "edf_greenhall); per axis, the terms the curve shows (N, Q, one or two GMs, RRW, a "
    "sinusoid; least BIC, none on a bound) by weighted least squares in log deviation; "
    "B = floor / 0.664; the profile's GM by minimax against the worst axis over 10 s to 1 h"
)
PROFILE_RULE = (
    "white noise: the largest axis'; GM: with that white noise held, the one sigma and "
    "correlation time whose worst ratio to the largest of the three axes' Allan deviations, "
    f"from {CALIBRATION_TAU_S[0]:g} s to {CALIBRATION_TAU_S[1]:g} s (or the last tau known to "
    f"{TRUSTED_CI:.0%}), is closest to 1 (minimax); none when it lands on a bound"
)
MODELLED_BY = "white noise and one GM bias, what analyze, design, simulate and calibrate use"
# Units at the edge: SI per unit of each reported figure.
ARW_UNIT = DEG / 60.0  # deg/sqrt(h) in rad/sqrt(s)
RRW_GYRO_UNIT = DEG_PER_HOUR / 60.0  # deg/h/sqrt(h) in rad/s/sqrt(s)
RRW_ACCEL_UNIT = MICRO_G / 60.0  # ug/sqrt(h) in m/s^2/sqrt(s)


@dataclass(frozen=True)
class ProfileFit:
    """Everything ``profile fit`` measured on one static log (SI inside)."""

    name: str
    gyro_curves: tuple[AllanCurve, ...]  # x, y, z
    accel_curves: tuple[AllanCurve, ...]  # x, y, z
    gyro: tuple[NoiseFit, ...]  # x, y, z
    accel: tuple[NoiseFit, ...]  # x, y, z
    gyro_profile: ProfileGM  # the profile's white noise and GM (profile_gm)
    accel_profile: ProfileGM
    level: StaticLevel
    latitude_deg: float
    height_m: float
    sample_rate_hz: float
    duration_s: float
    n_samples: int


@dataclass(frozen=True)
class FittedProfile:
    """A fitted profile and its file's document: what ``profile fit`` prints, saves and reports.

    Attributes
    ----------
    fit : ProfileFit
        The Allan deviations and the fitted terms, per axis (SI).
    doc : dict
        The profile TOML document (worst-axis scalars, ``[fit]``, ``[provenance]``).
    height_assumed : bool
        True when neither the log nor the caller gave the site's height and 0 m was used.
    """

    fit: ProfileFit
    doc: dict
    height_assumed: bool = False

    @property
    def profile(self) -> NoiseProfile:
        """The profile as the other calls take it (``profile=``)."""
        return _from_doc(tomllib.loads(_toml(self.doc)), self.fit.name)

    def to_json(self) -> dict:
        """The figures of ``profile fit --json`` (without the files written and the time taken)."""
        doc = self.doc
        return plain(
            {
                "profile": {k: v for k, v in doc.items() if k not in ("fit", "provenance")},
                **per_axis_tables(self.fit),
                "profile_fit": doc["fit"]["profile"],
                "site": doc["fit"]["site"],
                "log": doc["fit"]["log"],
            }
        )

    def to_text(self) -> str:
        """The table ``profile fit`` prints."""
        return profile_text(self.doc)

    def save(self, path, plot=None) -> list[str]:
        """Write the profile (``.toml``) and, if ``plot`` names a PNG, the Allan deviations; the files."""
        if not str(path).lower().endswith(".toml"):
            raise CalibError("the profile must be a .toml file", str(path), "name it e.g. myimu.toml")
        save_profile(self.doc, path)
        if plot is not None:
            plot_allan(self.fit, plot)
        return [str(path)] + ([str(plot)] if plot is not None else [])


def read_static_log(path, latitude_deg=None, height_m=None, **read_options) -> tuple[Run, bool]:
    """A static log and whether its height was assumed: 0 m when neither the log nor ``height_m`` gives it.

    The height moves only the accelerometer bias along the vertical (0.31 ug per m), so
    a fit without it is still a fit. ``read_options`` go to :func:`calib.runlog.read_run`.
    """
    first: CalibError | None = None
    with warnings.catch_warnings(record=True) as said:  # said once, by the reading that counts
        warnings.simplefilter("always")
        try:
            run = read_run(path, latitude_deg=latitude_deg, height_m=height_m, **read_options)
        except CalibError as exc:
            first = exc
    if first is None or height_m is not None:
        for w in said:
            warnings.warn(w.message, w.category, stacklevel=2)
        if first is not None:
            raise first
        return run, False
    try:  # the height alone was missing exactly when the log reads with one
        return read_run(path, latitude_deg=latitude_deg, height_m=0.0, **read_options), True
    except CalibError:
        raise first from None


def fit_log(
    path, name: str, provenance: dict, latitude_deg=None, height_m=None, **read_options
) -> FittedProfile:
    """Read a static log (:func:`read_static_log`) and fit its profile (:func:`fit_profile`)."""
    run, assumed = read_static_log(path, latitude_deg, height_m, **read_options)
    fit = fit_profile(run, name)
    return FittedProfile(fit, profile_doc(fit, provenance), assumed)


def fit_profile(run: Run, name: str) -> ProfileFit:
    """Allan deviation and noise fit of each gyro and accelerometer axis of a static run."""
    dt = run.dt_nominal
    if run.duration_s < 100.0 * dt or run.n_samples < 1000:
        raise CalibError(
            f"the log has {run.n_samples} samples ({run.duration_s:.3g} s); "
            "an Allan deviation needs thousands",
            run.source,
            "record at least an hour at rest (bias instability needs hours)",
        )
    gyro_rate, force = run.dtheta_rad / dt, run.dv_mps / dt
    level = static_level(gyro_rate, force, site_of(run))
    curves = {
        s: tuple(allan_deviation(x[:, j], dt) for j in range(3))
        for s, x in (("gyro", gyro_rate), ("accel", force))
    }
    fits = {}
    for sensor, sensor_curves in curves.items():
        try:
            fits[sensor] = tuple(fit_noise(c) for c in sensor_curves)
        except ValueError as exc:
            raise CalibError(
                f"{sensor}: {exc}", run.source, "fit a longer static log at the IMU's full output rate"
            ) from None
    return ProfileFit(
        name=name,
        gyro_curves=curves["gyro"],
        accel_curves=curves["accel"],
        gyro=fits["gyro"],
        accel=fits["accel"],
        gyro_profile=profile_gm(curves["gyro"], fits["gyro"], PROFILE_SIGMA_MAX["gyro"]),
        accel_profile=profile_gm(curves["accel"], fits["accel"], PROFILE_SIGMA_MAX["accel"]),
        level=level,
        latitude_deg=run.latitude_deg,
        height_m=run.height_m,
        sample_rate_hz=run.sample_rate_hz,
        duration_s=run.duration_s,
        n_samples=run.n_samples,
    )


def _per_axis(fits, white_unit, bias_unit, rrw_unit, q_unit) -> dict:
    return {
        "white": [f.white / white_unit for f in fits],
        "white_tau_s": [list(f.white_tau_s) for f in fits],
        "quantisation": [f.quantisation / q_unit for f in fits],
        "bias_instability": [f.bias_instability / bias_unit for f in fits],
        "floor_tau_s": [f.floor_tau_s for f in fits],
        "gm_sigma": [f.gm_sigma / bias_unit for f in fits],
        "gm_correlation_s": [f.gm_correlation_s for f in fits],
        "gm2_sigma": [f.gm2_sigma / bias_unit for f in fits],
        "gm2_correlation_s": [f.gm2_correlation_s for f in fits],
        "rate_random_walk": [f.rate_random_walk / rrw_unit for f in fits],
        "sinusoid": [f.sinusoid / bias_unit for f in fits],
        "sinusoid_hz": [f.sinusoid_hz for f in fits],
        "fit_tau_s": [list(f.fit_tau_s) for f in fits],
        "fit_ratio": [list(f.fit_ratio) for f in fits],
        "notes": ["; ".join(f.notes) for f in fits],
    }


def per_axis_tables(fit: ProfileFit) -> dict:
    """The ``[fit.gyro]`` and ``[fit.accel]`` tables: per-axis figures in their units."""
    g = _per_axis(fit.gyro, ARW_UNIT, DEG_PER_HOUR, RRW_GYRO_UNIT, 1e-6)
    a = _per_axis(fit.accel, MICRO_G, MICRO_G, RRW_ACCEL_UNIT, 1e-3)
    rename = {
        "gyro": {
            "white": "arw_dph",
            "quantisation": "quantisation_urad",
            "bias_instability": "bias_instability_dph",
            "gm_sigma": "gm_sigma_dph",
            "gm2_sigma": "gm2_sigma_dph",
            "rate_random_walk": "rrw_dph_per_sqrt_h",
            "sinusoid": "sinusoid_dph",
        },
        "accel": {
            "white": "vrw_ug",
            "quantisation": "quantisation_mmps",
            "bias_instability": "bias_instability_ug",
            "gm_sigma": "gm_sigma_ug",
            "gm2_sigma": "gm2_sigma_ug",
            "rate_random_walk": "rrw_ug_per_sqrt_h",
            "sinusoid": "sinusoid_ug",
        },
    }
    out = {s: {rename[s].get(k, k): v for k, v in d.items()} for s, d in (("gyro", g), ("accel", a))}
    out["gyro"]["bias_dph"] = list(fit.level.gyro_bias / DEG_PER_HOUR)
    out["accel"]["bias_ug"] = list(fit.level.accel_bias / MICRO_G)
    return out


def profile_table(fit: ProfileFit) -> dict:
    """The ``[fit.profile]`` table: how the scalars were chosen, how well they follow, what they leave out."""
    out: dict = {"rule": PROFILE_RULE, "modelled": MODELLED_BY}
    for sensor, prof, fits in (("gyro", fit.gyro_profile, fit.gyro), ("accel", fit.accel_profile, fit.accel)):
        out[f"{sensor}_tau_s"] = list(prof.tau_s)
        out[f"{sensor}_ratio"] = list(prof.ratio)
        out[f"{sensor}_note"] = prof.note
        out[f"{sensor}_not_modelled"] = not_modelled(fits)
    return out


def profile_doc(fit: ProfileFit, provenance: dict) -> dict:
    """The profile TOML document: the scalars (`profile_gm`), ``[fit]`` tables, ``[provenance]``."""
    g, a = fit.gyro_profile, fit.accel_profile
    lv = fit.level
    return {
        "name": fit.name,
        "gyro_arw_dph": g.white / ARW_UNIT,
        "accel_vrw_ug": a.white / MICRO_G,
        "gyro_bias_instability_dph": g.sigma / DEG_PER_HOUR,
        "gyro_bias_correlation_s": g.correlation_s,
        "accel_bias_instability_ug": a.sigma / MICRO_G,
        "accel_bias_correlation_s": a.correlation_s,
        "fit": {
            **per_axis_tables(fit),
            "profile": profile_table(fit),
            "site": {
                "latitude_deg": fit.latitude_deg,
                "height_m": fit.height_m,
                "gravity_removed_mps2": lv.gravity_mps2,
                "up_body": list(lv.up_b),
                "earth_rate_removed_dph": lv.earth_rate_vertical / DEG_PER_HOUR,
                "earth_rate_left_in_bias_dph": lv.earth_rate_horizontal / DEG_PER_HOUR,
            },
            "log": {
                "sample_rate_hz": fit.sample_rate_hz,
                "duration_s": fit.duration_s,
                "n_samples": fit.n_samples,
            },
        },
        "provenance": provenance,
    }


def plain(x):
    """Numpy scalars and arrays as Python floats and lists (for TOML and JSON)."""
    if isinstance(x, dict):
        return {k: plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [plain(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return x


def _rows(d: dict, sensor: str) -> list[tuple[str, list]]:
    """The per-axis rows of one sensor's table: label, values."""
    if sensor == "gyro":
        unit, white, rrw, q = (
            "deg/h",
            ("ARW, deg/sqrt(h)", "arw_dph"),
            "RRW, deg/h/sqrt(h)",
            "quantisation, urad",
        )
        keys = {"rrw": "rrw_dph_per_sqrt_h", "q": "quantisation_urad", "sfx": "dph"}
    else:
        unit, white, rrw, q = "ug", ("VRW, ug/sqrt(Hz)", "vrw_ug"), "RRW, ug/sqrt(h)", "quantisation, mm/s"
        keys = {"rrw": "rrw_ug_per_sqrt_h", "q": "quantisation_mmps", "sfx": "ug"}
    sfx = keys["sfx"]
    rows = [
        (white[0], d[white[1]]),
        ("  white region, s", d["white_tau_s"]),
        (f"bias instability B, {unit}", d[f"bias_instability_{sfx}"]),
        ("  floor at tau, s", d["floor_tau_s"]),
        (f"GM sigma, {unit}", d[f"gm_sigma_{sfx}"]),
        ("GM correlation, s", d["gm_correlation_s"]),
        (f"GM2 sigma, {unit}", d.get(f"gm2_sigma_{sfx}", [0.0] * 3)),
        ("GM2 correlation, s", d.get("gm2_correlation_s", [0.0] * 3)),
        (rrw, d[keys["rrw"]]),
        (f"sinusoid, {unit}", d.get(f"sinusoid_{sfx}", [0.0] * 3)),
        ("sinusoid, Hz", d.get("sinusoid_hz", [0.0] * 3)),
        (q, d[keys["q"]]),
        (f"{'gyro' if sensor == 'gyro' else 'accel'} bias, {unit}", d[f"bias_{sfx}"]),
    ]
    if "fit_tau_s" in d:
        rows += [("  fitted tau, s", d["fit_tau_s"]), ("  fit/measured, min-max", d["fit_ratio"])]
    return rows


def profile_text(doc: dict) -> str:
    """The table ``profile fit`` prints: per axis, the profile and what it leaves out, what was removed."""
    g, a, site = doc["fit"]["gyro"], doc["fit"]["accel"], doc["fit"]["site"]
    lines = [f"{'':28s}{'x':>16s}{'y':>16s}{'z':>16s}"]
    for label, values in _rows(g, "gyro") + _rows(a, "accel"):
        cells = [f"{v[0]:.3g}-{v[1]:.3g}" if isinstance(v, list) else f"{v:.4g}" for v in values]
        lines.append(f"{label:28s}" + "".join(f"{c:>16s}" for c in cells))
    for sensor, d in (("gyro", g), ("accel", a)):
        lines += [
            f"{sensor} {axis}: {note}"
            for axis, note in zip(AXES, d.get("notes", [""] * 3), strict=True)
            if note
        ]
    lines.append(
        f"profile {doc['name']}: gyro_arw_dph {doc['gyro_arw_dph']:.4g}, accel_vrw_ug "
        f"{doc['accel_vrw_ug']:.4g}, GM gyro {doc['gyro_bias_instability_dph']:.4g} deg/h "
        f"/ {doc['gyro_bias_correlation_s']:.4g} s, GM accel "
        f"{doc['accel_bias_instability_ug']:.4g} ug / {doc['accel_bias_correlation_s']:.4g} s"
    )
    lines += _profile_lines(doc["fit"].get("profile"))
    lines.append(
        f"removed: gravity {site['gravity_removed_mps2']:.6g} m/s^2 along the measured up "
        f"{[round(float(u), 4) for u in site['up_body']]} (body), Earth rate "
        f"{site['earth_rate_removed_dph']:.3g} deg/h along it; the horizontal Earth rate "
        f"({site['earth_rate_left_in_bias_dph']:.3g} deg/h) is left in the gyro bias: "
        "a MEMS gyro cannot find north. The Allan deviations do not change; the biases do."
    )
    return "\n".join(lines)


def _profile_lines(table: dict | None) -> list[str]:
    """How the profile's scalars follow the worst axis, and what they leave out."""
    if not table:
        return []
    lines = [f"  rule: {table['rule']}"]
    for sensor in ("gyro", "accel"):
        lo, hi = table[f"{sensor}_tau_s"]
        r0, r1 = table[f"{sensor}_ratio"]
        line = f"  {sensor}: profile / worst axis {r0:.2f}-{r1:.2f} over {lo:.3g}-{hi:.3g} s"
        if table[f"{sensor}_note"]:
            line += f"; {table[f'{sensor}_note']}"
        lines.append(line)
        if table[f"{sensor}_not_modelled"]:
            lines.append(
                f"  {sensor}: NOT MODELLED by the profile ({table['modelled']}): "
                + "; ".join(table[f"{sensor}_not_modelled"])
            )
    return lines


def header(doc: dict) -> str:
    """The comment a profile file opens with: what its scalars leave out (``[fit.profile]``)."""
    table = doc.get("fit", {}).get("profile")
    if not table:
        return ""
    lines = ["# Noise profile fitted by seqdesign profile fit; the scalars are " + table["modelled"] + "."]
    command = doc.get("provenance", {}).get("command")
    if command:
        lines.append(f"# Made by: {command}")
    for sensor in ("gyro", "accel"):
        if table[f"{sensor}_not_modelled"]:
            lines.append(
                f"# {sensor}: not modelled by the scalars: " + "; ".join(table[f"{sensor}_not_modelled"])
            )
        if table[f"{sensor}_note"]:
            lines.append(f"# {sensor}: {table[f'{sensor}_note']}")
    lines.append(
        "# How they were chosen and how well they follow the data: [fit.profile]; "
        "per axis: [fit.gyro], [fit.accel]."
    )
    return "\n".join(lines) + "\n\n"


def _toml(doc: dict) -> str:
    import tomli_w

    return tomli_w.dumps(plain(doc))


def save_profile(doc: dict, path) -> None:
    """Write the profile atomically (with its `header`), after checking that `load_profile` accepts it."""
    text = header(doc) + _toml(doc)
    try:
        _from_doc(tomllib.loads(text), str(path))
    except CalibError as exc:
        raise CalibError(
            f"the fitted profile would not load: {exc.message}",
            str(path),
            "the log's noise is outside what calib.noise.profiles accepts; check the units of its columns",
        ) from None
    atomic_write_text(path, text)
