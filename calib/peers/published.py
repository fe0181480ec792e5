"""Other tools' calibrations read as a :class:`~calib.calibration.correction.Correction` (``M (raw - b)``).

* **imu_tk** (``CalibratedTriad``): per triad a misalignment ``T``, a scale
  ``K`` and a bias ``b`` in raw units, with ``calibrated = T K (raw - b)``; so
  ``M = T K``. Its gyro has no g-sensitivity. A result file holds the two
  triads as ``## acc`` and ``## gyro`` sections of 21 numbers each (``T`` row
  by row, ``K`` row by row, ``b``); ``#`` lines are comments.
* **imucal** (``FerrarisCalibrationInfo``, JSON): scale ``K``, rotation and
  non-orthogonality ``R``, bias ``b`` per sensor and the gyro's acceleration
  influence ``K_ga``::

      acc = R_a^-1 K_a^-1 (raw_acc - b_a)
      gyr = R_g^-1 K_g^-1 (raw_gyr - K_ga acc - b_g)

  so ``M_a = R_a^-1 K_a^-1``, ``M_g = u R_g^-1 K_g^-1`` (``u`` the factor from
  its output unit ``gyr_unit`` to rad/s) and ``G = K_ga`` (raw gyro units per
  the calibrated acceleration's unit, m/s^2).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from calib.calibration.correction import Correction, SensorCorrection
from calib.errors import CalibError

GYRO_TO_RAD_S = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
ACCEL_TO_MPS2 = {"m/s^2": 1.0}


def _unknown(shape) -> np.ndarray:
    return np.full(shape, np.nan)


def imu_tk_triad(numbers, raw_unit: str = "counts") -> SensorCorrection:
    """One imu_tk triad from its 21 numbers (``T`` 3x3, ``K`` 3x3, ``b`` 3): ``M = T K``."""
    v = np.asarray(numbers, dtype=float)
    if v.shape != (21,):
        raise CalibError(
            f"an imu_tk triad is 21 numbers (T, K, b), not {v.size}", "imu_tk result", "give T, K and b"
        )
    T, K, b = v[:9].reshape(3, 3), v[9:18].reshape(3, 3), v[18:]
    return SensorCorrection(T @ K, b, _unknown((3, 3)), _unknown(3), raw_unit)


def parse_imu_tk(text: str, where: str = "imu_tk result") -> Correction:
    """imu_tk's two triads from the text of a result file (``## acc`` and ``## gyro`` sections)."""
    sections: dict[str, list[float]] = {}
    current: str | None = None
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("##"):
            words = s[2:].split()
            current = words[0].lower() if words else None
            if current is not None:
                sections[current] = []
        elif s and not s.startswith("#") and current is not None:
            try:
                sections[current] += [float(x) for x in s.split()]
            except ValueError:
                raise CalibError(f"not numbers: {s!r}", where, "give imu_tk's T, K and b") from None
    found = {}
    for name, keys in (("accel", ("acc", "accel", "accelerometer")), ("gyro", ("gyro", "gyr"))):
        key = next((k for k in keys if k in sections), None)
        if key is None:
            raise CalibError(f"has no ## {keys[0]} section", where, "give both triads, ## acc and ## gyro")
        found[name] = imu_tk_triad(sections[key])
    return Correction(found["gyro"], found["accel"], None, None, f"imu_tk ({where})")


def read_imu_tk(path: str | Path) -> Correction:
    """imu_tk's result file (see :func:`parse_imu_tk`)."""
    return parse_imu_tk(Path(path).read_text(), str(path))


def _matrix(doc: dict, key: str, where: str, shape=(3, 3)) -> np.ndarray:
    try:
        m = np.array(doc[key], dtype=float)
    except (KeyError, TypeError, ValueError):
        m = np.zeros(0)
    if m.shape != shape or not np.all(np.isfinite(m)):
        raise CalibError(f"{key} must be {'x'.join(map(str, shape))} numbers", where, "give imucal's result")
    return m


def imucal_correction(doc: dict, where: str = "imucal result") -> Correction:
    """The correction of imucal's Ferraris (or turntable) calibration, a parsed JSON document."""
    kind = doc.get("cal_type", "Ferraris")
    if kind not in ("Ferraris", "Turntable"):
        raise CalibError(f"cal_type {kind!r} is not a Ferraris calibration", where, "give a Ferraris result")
    gyr_unit, acc_unit = doc.get("gyr_unit", "deg/s"), doc.get("acc_unit", "m/s^2")
    if gyr_unit not in GYRO_TO_RAD_S or acc_unit not in ACCEL_TO_MPS2:
        raise CalibError(
            f"units {gyr_unit!r}, {acc_unit!r} are not read",
            where,
            f"give a result whose gyr_unit is one of {sorted(GYRO_TO_RAD_S)} and acc_unit m/s^2",
        )
    K_a, R_a = _matrix(doc, "K_a", where), _matrix(doc, "R_a", where)
    K_g, R_g = _matrix(doc, "K_g", where), _matrix(doc, "R_g", where)
    K_ga = _matrix(doc, "K_ga", where)
    b_a, b_g = _matrix(doc, "b_a", where, (3,)), _matrix(doc, "b_g", where, (3,))
    M_a = np.linalg.inv(R_a) @ np.linalg.inv(K_a) * ACCEL_TO_MPS2[acc_unit]
    M_g = np.linalg.inv(R_g) @ np.linalg.inv(K_g) * GYRO_TO_RAD_S[gyr_unit]
    accel = SensorCorrection(M_a, b_a, _unknown((3, 3)), _unknown(3), doc.get("from_acc_unit", acc_unit))
    gyro = SensorCorrection(M_g, b_g, _unknown((3, 3)), _unknown(3), doc.get("from_gyr_unit", gyr_unit))
    return Correction(gyro, accel, K_ga, None, f"imucal ({where})")


def read_imucal(path: str | Path) -> Correction:
    """The result file imucal writes, ``*-imucal-result.json`` (see :func:`imucal_correction`)."""
    try:
        doc = json.loads(Path(path).read_text())
    except json.JSONDecodeError as exc:
        raise CalibError(f"is not JSON ({exc.msg})", str(path), "give imucal's result file") from None
    return imucal_correction(doc, str(path))


def read_correction(path: str | Path) -> Correction:
    """Any calibration a user may hold, as a :class:`Correction`: ours (``.toml``, what
    ``calibrate --correction`` writes), imucal's result (``.json``) or imu_tk's result text
    (anything else: ``## acc`` and ``## gyro`` sections of ``T``, ``K`` and ``b``).
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".toml":
        return Correction.load(path)
    if suffix == ".json":
        return read_imucal(path)
    try:
        return read_imu_tk(path)
    except UnicodeDecodeError:
        raise CalibError(
            "is neither a correction of ours (.toml), imucal's result (.json) nor imu_tk's result text",
            str(path),
            "give calibrate --correction's TOML, imucal's *-imucal-result.json or imu_tk's result text",
        ) from None
