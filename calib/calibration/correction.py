"""A calibration as the correction a user applies: ``calibrated = M (raw - b)`` per sensor.

What imu_tk and imucal hand out, in the units the log was recorded in (counts
when the log is raw counts read with a nominal conversion, else SI), with the
1-sigma of every element propagated from the fit's covariance. The gyro's
g-sensitivity, when fitted, is removed with the calibrated specific force::

    f = M_a (raw_a - b_a)                       # m/s^2
    w = M_g (raw_g - b_g - G f)                 # rad/s

From the 21-parameter model (``w_meas = A_g w + b_g + G_si f``, with the log's
per-axis nominal conversion ``raw = k * w_meas + z``): ``M_g = A_g^-1 diag(1/k)``,
``b_g = z + k * b_g_si``, ``G = diag(k) G_si``; the accelerometer alike without G.

A hand fit that chose a bias drift gives the biases of the calibrated log's last rest and the drift
``d`` (raw units per s) beside them: ``b(t) = b + d (t - bias_time_s)``, on the log's own time axis.
It is carried only when asked (:meth:`Correction.apply` given the samples' times) and only over the
log it was fitted on (``drift_span_s``): a linear drift is a fact of that run, not of the next one.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.io.fields import FORMAT_VERSION, Fields, check_format_version
from calib.io.files import atomic_write_text, load_toml
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.nav.strapdown import sample_intervals, start_time

SENSORS = ("gyro", "accel")
SI_UNIT = {"gyro": "rad/s", "accel": "m/s^2"}
# Raw units a correction may take besides counts (other tools' results: imucal's in deg/s), per SI.
RAW_PER_SI = {"rad/s": 1.0, "deg/s": 180.0 / np.pi, "m/s^2": 1.0, "g": 1.0 / P.STANDARD_GRAVITY}


@dataclass(frozen=True)
class SensorCorrection:
    """``calibrated = M (raw - b)`` for one sensor triad.

    Attributes
    ----------
    M : ndarray, shape (3, 3)
        SI per raw unit.
    b : ndarray, shape (3,)
        Raw units.
    sigma_M, sigma_b : ndarray
        1-sigma of each element (nan where not known).
    raw_unit : str
        ``counts``, or a unit of ``RAW_PER_SI`` (``rad/s``, ``deg/s``, ``m/s^2``, ``g``), each sensor its own.
    drift, sigma_drift : ndarray, shape (3,), or None
        The bias's fitted drift, raw units per s, and its 1-sigma; None when none was fitted.
    """

    M: np.ndarray
    b: np.ndarray
    sigma_M: np.ndarray
    sigma_b: np.ndarray
    raw_unit: str
    drift: np.ndarray | None = None
    sigma_drift: np.ndarray | None = None

    def bias_at(self, dt_s: np.ndarray | None) -> np.ndarray:
        """The bias at ``dt_s`` (s from the biases' time, ``(n,)``), or the one bias for None."""
        if dt_s is None or self.drift is None:
            return self.b
        return self.b + np.asarray(dt_s, dtype=float)[:, None] * self.drift


@dataclass(frozen=True)
class Correction:
    """Both triads' corrections and the gyro's g-sensitivity (raw gyro units per m/s^2), or None.

    With a drift fitted, ``bias_time_s`` is the absolute time the biases ``b`` are of (the
    calibrated log's last rest) and ``drift_span_s`` the span of that log, both on its own time
    axis (``time_origin_s + time_s``, :attr:`calib.runlog.run.Run.time_origin_s`).
    """

    gyro: SensorCorrection
    accel: SensorCorrection
    g_sensitivity: np.ndarray | None = None
    sigma_g_sensitivity: np.ndarray | None = None
    source: str = ""
    bias_time_s: float | None = None
    drift_span_s: tuple[float, float] | None = None
    drift_samples: int | None = None  # the calibrated log's samples: with its span, which log it was

    @property
    def has_drift(self) -> bool:
        """Whether either sensor's bias carries a fitted drift."""
        return self.gyro.drift is not None or self.accel.drift is not None

    def apply(
        self, raw_gyro: np.ndarray, raw_accel: np.ndarray, time_s: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Calibrated rates (rad/s) and specific force (m/s^2) of ``(n, 3)`` raw samples.

        ``time_s`` (``(n,)``, absolute s, each sample's middle) carries a fitted drift to each
        sample's time; without it, or without a drift, the one bias ``b`` is taken out.
        """
        dt_s = None
        if time_s is not None and self.bias_time_s is not None:
            dt_s = np.asarray(time_s, dtype=float) - self.bias_time_s
        f = (np.asarray(raw_accel, dtype=float) - self.accel.bias_at(dt_s)) @ self.accel.M.T
        g = np.asarray(raw_gyro, dtype=float) - self.gyro.bias_at(dt_s)
        if self.g_sensitivity is not None:
            g = g - f @ self.g_sensitivity.T
        return g @ self.gyro.M.T, f

    def to_dict(self) -> dict:
        doc: dict = {"format_version": FORMAT_VERSION, "kind": "correction", "source": self.source}
        if self.bias_time_s is not None and self.drift_span_s is not None:
            doc["bias_time_s"] = float(self.bias_time_s)
            doc["drift_span_s"] = [float(x) for x in self.drift_span_s]
            if self.drift_samples is not None:
                doc["drift_samples"] = int(self.drift_samples)
        for name, c in (("gyro", self.gyro), ("accel", self.accel)):
            doc[name] = {
                "raw_unit": c.raw_unit,
                "calibrated_unit": SI_UNIT[name],
                "M": [[float(x) for x in row] for row in c.M],
                "b": [float(x) for x in c.b],
                "sigma_M": [[float(x) for x in row] for row in c.sigma_M],
                "sigma_b": [float(x) for x in c.sigma_b],
            }
            if c.drift is not None:
                sd = c.sigma_drift if c.sigma_drift is not None else np.full(3, np.nan)
                doc[name] |= {"drift": [float(x) for x in c.drift], "sigma_drift": [float(x) for x in sd]}
        if self.g_sensitivity is not None:
            doc["gyro"]["G"] = [[float(x) for x in row] for row in self.g_sensitivity]
            sg = self.sigma_g_sensitivity if self.sigma_g_sensitivity is not None else np.full((3, 3), np.nan)
            doc["gyro"]["sigma_G"] = [[float(x) for x in row] for row in sg]
        return doc

    def save(self, path: str | Path) -> None:
        """Write the correction TOML (``docs/by-hand.md``); nothing is written on a failure."""
        atomic_write_text(path, _to_toml(self.to_dict()))

    @classmethod
    def load(cls, path: str | Path) -> Correction:
        doc = load_toml(path)
        where = str(path)
        check_format_version(doc, "correction", where)
        if doc.get("kind") != "correction":
            raise CalibError(
                "is not a correction file (kind = 'correction')",
                where,
                "give the file calibrate --correction wrote",
            )
        parts = {}
        for name in SENSORS:
            table = doc.get(name)
            if not isinstance(table, dict):
                raise CalibError(
                    f"has no [{name}] table", where, "give the file calibrate --correction wrote"
                )
            f = Fields(table, f"{where} [{name}]")
            raw_unit = f.string("raw_unit", "counts")
            parts[name] = SensorCorrection(
                _matrix(table, "M", where, name),
                np.array(f.numbers("b", length=3, fix="give x, y, z")),
                # Optional: a correction written by hand or by another tool may know no sigmas.
                _matrix(table, "sigma_M", where, name, allow_nan=True)
                if "sigma_M" in table
                else np.full((3, 3), np.nan),
                np.array(f.numbers("sigma_b", length=3, finite=False, fix="give x, y, z"))
                if "sigma_b" in table
                else np.full(3, np.nan),
                raw_unit,
                np.array(f.numbers("drift", length=3, fix="give x, y, z in raw units per s"))
                if "drift" in table
                else None,
                np.array(f.numbers("sigma_drift", length=3, finite=False, fix="give x, y, z"))
                if "sigma_drift" in table
                else None,
            )
        G = _matrix(doc["gyro"], "G", where, "gyro") if "G" in doc["gyro"] else None
        sG = (
            _matrix(doc["gyro"], "sigma_G", where, "gyro", allow_nan=True)
            if "sigma_G" in doc["gyro"]
            else None
        )
        bias_time, span = _drift_time(doc, where, any(p.drift is not None for p in parts.values()))
        samples = Fields(doc, where).integer("drift_samples", None, low=1) if span is not None else None
        return cls(parts["gyro"], parts["accel"], G, sG, str(doc.get("source", "")), bias_time, span, samples)


def correction_from_parameters(
    values: np.ndarray,
    covariance: np.ndarray,
    g_sensitivity: np.ndarray | None = None,
    sigma_g_sensitivity: np.ndarray | None = None,
    gyro_conversion: tuple[np.ndarray, np.ndarray] | None = None,
    accel_conversion: tuple[np.ndarray, np.ndarray] | None = None,
    source: str = "",
) -> Correction:
    """The correction of 21 parameters (SI) and their covariance.

    ``*_conversion`` is the log's nominal ``(zero_counts, counts_per_si)`` per
    axis when it was raw counts (the correction is then in counts), else None.
    """
    values = np.asarray(values, dtype=float)
    cov = np.asarray(covariance, dtype=float)

    def elements(v: np.ndarray) -> np.ndarray:
        model = ErrorModel(v)
        out = []
        for sensor, conv in (("gyro", gyro_conversion), ("accel", accel_conversion)):
            zero, k = conv if conv is not None else (np.zeros(3), np.ones(3))
            A = model.gyro_matrix if sensor == "gyro" else model.accel_matrix
            bias = model.gyro_bias if sensor == "gyro" else model.accel_bias
            out += [(np.linalg.inv(A) / k[None, :]).ravel(), zero + k * bias]
        return np.concatenate(out)

    e0 = elements(values)
    # Central differences at a step well inside the model's linear range and far above rounding.
    J = np.empty((len(e0), P.N_PARAMS))
    for i in range(P.N_PARAMS):
        step = 1e-6 * max(abs(values[i]), 1e-3 * P.PARAMETERS[i].si_per_unit)
        d = np.zeros(P.N_PARAMS)
        d[i] = step
        J[:, i] = (elements(values + d) - elements(values - d)) / (2 * step)
    finite = np.all(np.isfinite(cov), axis=1)
    c = np.where(np.outer(finite, finite), cov, 0.0)
    sigma = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", J, c, J), 0.0))
    sigma[np.any(J[:, ~finite] != 0, axis=1)] = np.nan  # rests on a parameter not estimated

    parts = []
    for s, (sensor, conv) in enumerate((("gyro", gyro_conversion), ("accel", accel_conversion))):
        o = 12 * s
        parts.append(
            SensorCorrection(
                e0[o : o + 9].reshape(3, 3),
                e0[o + 9 : o + 12],
                sigma[o : o + 9].reshape(3, 3),
                sigma[o + 9 : o + 12],
                "counts" if conv is not None else SI_UNIT[sensor],
            )
        )
    G = sG = None
    if g_sensitivity is not None:
        k = gyro_conversion[1] if gyro_conversion is not None else np.ones(3)
        G = k[:, None] * np.asarray(g_sensitivity, dtype=float)
        if sigma_g_sensitivity is not None:
            sG = k[:, None] * np.asarray(sigma_g_sensitivity, dtype=float)
    return Correction(parts[0], parts[1], G, sG, source)


def correction_of_result(result, conversion=None, source: str = "", run=None) -> Correction:
    """The correction of a :class:`~calib.calibration.result.CalibrationResult`; in counts when read
    through a nominal ``conversion`` (:class:`calib.runlog.conversion.Conversion`).

    A hand fit's chosen bias drifts come with it when ``run`` (the calibrated
    :class:`calib.runlog.run.Run`) gives their times: the biases are its last rest's.
    """
    G = sG = None
    if "g-sensitivity" in result.extras.groups:
        part = result.extras.index("g-sensitivity")
        G = np.asarray(result.extra_values)[part].reshape(3, 3)
        sG = np.asarray(result.extra_sigma)[part].reshape(3, 3)
    convs: list[tuple[np.ndarray, np.ndarray] | None] = [None, None]
    if conversion is not None:
        convs = [(conversion.zero_counts[s], conversion.counts_per_unit[s]) for s in SENSORS]
    correction = correction_from_parameters(
        result.values, result.covariance, G, sG, convs[0], convs[1], source
    )
    drifts = {"gyro": "gyro-bias-drift", "accel": "accel-bias-drift"}
    if run is None or result.by_hand is None or not any(g in result.extras.groups for g in drifts.values()):
        return correction
    parts = {"gyro": correction.gyro, "accel": correction.accel}
    for (sensor, group), conv in zip(drifts.items(), convs, strict=True):
        if group in result.extras.groups:
            part = result.extras.index(group)
            k = conv[1] if conv is not None else np.ones(3)  # raw units per SI
            value, sigma = np.asarray(result.extra_values)[part], np.asarray(result.extra_sigma)[part]
            parts[sensor] = replace(parts[sensor], drift=k * value, sigma_drift=k * sigma)
    # The summary's seconds count from the start of the first sample's interval.
    start = run.time_origin_s + start_time(run.time_s)
    return replace(
        correction,
        gyro=parts["gyro"],
        accel=parts["accel"],
        bias_time_s=start + float(np.mean(result.by_hand.rest_s[-1])),
        drift_span_s=(start, run.time_origin_s + float(run.time_s[-1])),
        drift_samples=run.n_samples,
    )


def drift_carried_times(correction: Correction, run) -> np.ndarray:
    """Each sample's middle on ``run``'s own time axis, to carry ``correction``'s drift over it.

    Refused unless ``run`` is the log the drift was fitted on (:func:`fitted_on`): a linear
    drift is a fact of that run, not of the next one.
    """
    if not correction.has_drift or correction.drift_span_s is None:
        raise CalibError(
            "the correction carries no bias drift (none was fitted) to carry",
            correction.source or run.source,
            "apply it as one bias (leave out carrying the drift, the CLI's --carry-drift)",
        )
    if not fitted_on(correction, run):
        origin = run.time_origin_s
        start, end = correction.drift_span_s
        times = sample_middles(run)
        raise CalibError(
            f"runs from {times[0] - origin:.3f} to {times[-1] - origin:.3f} s in {run.n_samples} samples, "
            f"not the log the drift was fitted on ({start - origin:.3f} to {end - origin:.3f} s, "
            f"{correction.drift_samples} samples): a linear drift is a fact of that log, not of another",
            run.source,
            "apply the correction as one bias (the last rest's), or calibrate this log",
        )
    return sample_middles(run)


def fitted_on(correction: Correction, run) -> bool:
    """Whether ``run`` is the log ``correction``'s drift was fitted on: its samples inside the
    span (half a sample's slack for the first interval) and as many of them (two logs whose
    time starts near zero share a span).
    """
    if correction.drift_span_s is None:
        return False
    times = sample_middles(run)
    start, end = correction.drift_span_s
    slack = 0.5 * float(np.median(sample_intervals(run.time_s)))
    inside = bool(times[0] >= start - slack and times[-1] <= end + slack)
    return inside and correction.drift_samples in (None, run.n_samples)


def drift_note(correction: Correction, run) -> str | None:
    """What a correction applied as one bias leaves of its drift, for the user; None without one."""
    if not correction.has_drift or correction.drift_span_s is None or correction.bias_time_s is None:
        return None
    if not fitted_on(correction, run):
        return (
            "the correction's biases drift over the log it was fitted on, not this one: applied as one bias"
        )
    origin = run.time_origin_s
    start, end = (round(t - origin, 1) + 0.0 for t in correction.drift_span_s)  # + 0.0: no "-0.0"
    return (
        f"the correction's biases drift over this log ({start:.1f} to {end:.1f} s): applied as one bias, "
        f"the last rest's at {correction.bias_time_s - origin:.1f} s; the CLI's --carry-drift carries "
        "the drift over it"
    )


def sample_middles(run) -> np.ndarray:
    """Each sample's middle on the log's own time axis, s (``time_origin_s + time_s - dt / 2``)."""
    return run.time_origin_s + run.time_s - 0.5 * sample_intervals(run.time_s)


def _drift_time(doc: dict, where: str, drift: bool) -> tuple[float | None, tuple[float, float] | None]:
    """``bias_time_s`` and ``drift_span_s`` of a correction with a drift, checked; None without one."""
    if not drift:
        return None, None
    f = Fields(doc, where)
    fix = "give the file calibrate --correction wrote, or remove the drift keys"
    bias_time = f.number("bias_time_s", fix=fix)
    start, end = f.numbers("drift_span_s", length=2, fix=fix)
    if not start <= bias_time <= end:
        raise CalibError(
            f"bias_time_s = {bias_time} is outside drift_span_s = [{start}, {end}]",
            where,
            "give the time of the biases within the span of the log the drift was fitted on",
        )
    return bias_time, (start, end)


def raw_samples(run, correction: Correction, where: str) -> tuple[np.ndarray, np.ndarray]:
    """The log's samples in the units ``correction`` takes: counts, or rad/s (deg/s) and m/s^2 (g)."""
    dt = sample_intervals(run.time_s)[:, None]
    rate, force = run.dtheta_rad / dt, run.dv_mps / dt
    units = (correction.gyro.raw_unit, correction.accel.raw_unit)
    unknown = [u for u in units if u != "counts" and u not in RAW_PER_SI]
    if unknown:
        raise CalibError(
            f"the correction takes raw {unknown[0]!r}, a unit not read",
            where,
            f"give a correction whose raw units are counts or {', '.join(RAW_PER_SI)}",
        )
    if "counts" in units and run.conversion is None:
        raise CalibError(
            "the correction takes raw counts (it was made from a log in counts), but this log was read in SI",
            where,
            "read the log with the --conversion file it was calibrated with",
        )
    # Each sensor on its own: a correction written by hand may take one in counts, the other in SI.
    raw = []
    for si, unit, sensor in ((rate, units[0], "gyro"), (force, units[1], "accel")):
        raw.append(run.conversion.to_counts(si, sensor) if unit == "counts" else si * RAW_PER_SI[unit])
    return raw[0], raw[1]


def _matrix(table: dict, key: str, where: str, name: str, allow_nan: bool = False) -> np.ndarray:
    rows = table.get(key)
    try:
        M = np.array(rows, dtype=float)
    except (TypeError, ValueError):
        M = np.zeros(0)
    if M.shape != (3, 3) or (not allow_nan and not np.all(np.isfinite(M))):
        raise CalibError(
            f"{key} must be 3 rows of 3 numbers", f"{where} [{name}]", "give the matrix row by row"
        )
    return M


def _to_toml(doc: dict) -> str:
    import tomli_w  # only when a correction is written

    head = "# calibrated = M (raw - b) per sensor; the gyro's: M (raw - b - G f), f the calibrated accel\n"
    return head + tomli_w.dumps(doc)
