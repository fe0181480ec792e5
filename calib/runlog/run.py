"""The `Run`: the raw IMU increments of one calibration run, and its metadata."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError

from .clock import SampleClock
from .conversion import Conversion
from .format import FORMAT


@dataclass
class Run:
    """One run log: IMU increments as the IMU output them, plus site metadata.

    Attributes
    ----------
    time_s : numpy.ndarray
        ``(n,)`` float64, end of each sample interval, s.
    dtheta_rad : numpy.ndarray
        ``(n, 3)`` gyro angle increments over each interval, body frame, rad.
    dv_mps : numpy.ndarray
        ``(n, 3)`` accelerometer velocity increments, body frame, m/s.
    meta : dict of str to str
        All ``# key: value`` metadata as strings, in file order, including
        ``format``; unknown keys are kept.
    gimbal_deg : numpy.ndarray or None
        ``(n, 3)`` outer, middle, inner encoder angles in degrees, or None.
    source : str
        Path the run was read from, used to name it in messages.
    clock : calib.runlog.clock.SampleClock or None
        Jitter, dropped and duplicated samples found by `read_run`.
    gyro_columns : tuple of (str, str) or None
        For a CSV file, the gyro's columns x, y, z as ``(the file's name, the name
        it was read as)`` (they differ under a column map): messages about the
        gyro's unit name these. None for a run whose increments were given as such.
    conversion : calib.runlog.conversion.Conversion or None
        The nominal conversion its raw counts were read with (zero and counts per SI
        unit per axis), so that a result can be told back in counts; None for a
        log in physical units.
    clipped : numpy.ndarray or None
        ``(n, 6)`` bool, per sample and channel (gyro x, y, z, accel x, y, z): the
        samples read at or next to the end of the sensor's range
        (:mod:`calib.runlog.clipping`; ``clipped.any(axis=1)`` per sample); None
        when nothing is clipped.
    guessed : numpy.ndarray or None
        ``(n,)`` bool: samples lost amid a turn and put in as a guess (read with
        gaps allowed for a hand fit, which leaves their moves out); None when none is.
    """

    time_s: np.ndarray
    dtheta_rad: np.ndarray
    dv_mps: np.ndarray
    meta: dict[str, str]
    gimbal_deg: np.ndarray | None = None
    source: str = "<memory>"
    clock: SampleClock | None = None  # what read_run found in the time column
    gyro_columns: tuple[tuple[str, str], ...] | None = None  # (file's name, read as), x y z
    conversion: Conversion | None = None  # raw counts to SI, when the log was in counts
    clipped: np.ndarray | None = None  # (n, 6) bool: gyro x y z, accel x y z at the range's end
    guessed: np.ndarray | None = None  # (n,) bool: lost amid a turn, put in by a guess

    @property
    def latitude_deg(self) -> float:
        """Geodetic latitude of the site, degrees."""
        return meta_float(self.meta, "latitude_deg", self.source)

    @property
    def height_m(self) -> float:
        """Ellipsoidal height of the site, m."""
        return meta_float(self.meta, "height_m", self.source)

    @property
    def sample_rate_hz(self) -> float:
        """Nominal IMU output rate, Hz."""
        return meta_float(self.meta, "sample_rate_hz", self.source)

    @property
    def gravity_mps2(self) -> float | None:
        """Measured gravity at the site, m/s^2, or None to use normal gravity."""
        if "gravity_mps2" not in self.meta:
            return None
        return meta_float(self.meta, "gravity_mps2", self.source)

    @property
    def sequence_name(self) -> str | None:
        """Name of the sequence the run executed (``sequence`` key), or None."""
        name = self.meta.get("sequence", "").strip()
        return name or None

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.time_s.shape[0])

    @property
    def dt_nominal(self) -> float:
        """Nominal sample period ``1 / sample_rate_hz``, s."""
        return 1.0 / self.sample_rate_hz

    @property
    def time_origin_s(self) -> float:
        """The absolute time of ``time_s = 0``, s: the origin the log states, plus its first stamp when
        its stamps counted from an epoch (UNIX or ROS time; ``calib.runlog.clock.epoch_origin``: a float64
        at 1.7e9 s rounds each interval, so such a log is read from its first stamp).
        """
        stated = meta_float(self.meta, "time_origin_s", self.source) if "time_origin_s" in self.meta else 0.0
        return stated + (self.clock.origin_s if self.clock is not None else 0.0)

    @property
    def duration_s(self) -> float:
        """Time the samples cover, s.

        Each ``time_s`` ends its interval, so the first sample starts one
        nominal period before ``time_s[0]``: ``time_s[-1] - time_s[0] + dt_nominal``.
        """
        return float(self.time_s[-1] - self.time_s[0]) + self.dt_nominal


def make_meta(
    latitude_deg: float,
    height_m: float,
    sample_rate_hz: float,
    gravity_mps2: float | None = None,
    sequence: str | None = None,
    **extra: str,
) -> dict[str, str]:
    """Build a valid ``Run.meta`` dict, ``format`` first, numbers as exact reprs.

    Parameters
    ----------
    latitude_deg, height_m, sample_rate_hz : float
        Required site and rate metadata.
    gravity_mps2 : float, optional
        Measured gravity; omitted when None.
    sequence : str, optional
        Sequence name; omitted when None.
    **extra : str
        Further keys, kept as given (converted with ``str``).

    Returns
    -------
    dict of str to str
    """
    meta = {
        "format": FORMAT,
        "latitude_deg": repr(float(latitude_deg)),
        "height_m": repr(float(height_m)),
        "sample_rate_hz": repr(float(sample_rate_hz)),
    }
    if gravity_mps2 is not None:
        meta["gravity_mps2"] = repr(float(gravity_mps2))
    if sequence is not None:
        meta["sequence"] = str(sequence)
    meta.update({key: str(value) for key, value in extra.items()})
    return meta


# What each numeric key means, for the fix part of messages.
META_HINTS = {
    "latitude_deg": "geodetic latitude in degrees, north positive, within [-90, 90]",
    "height_m": "ellipsoidal height in metres, within [-1000, 10000]",
    "sample_rate_hz": "the IMU output rate in Hz, greater than 0",
    "gravity_mps2": "measured gravity in m/s^2, greater than 0, or leave the key out",
    "time_origin_s": "the absolute time of time_s = 0 in s (e.g. UNIX time), or leave the key out",
}


def meta_float(meta: dict[str, str], key: str, where: str) -> float:
    """Parse one numeric metadata value; refuse missing, non-numeric or non-finite."""
    if key not in meta:
        raise CalibError(
            f"required metadata '{key}' is missing",
            where,
            f"add a line '# {key}: <value>' ({META_HINTS[key]})",
        )
    text = meta[key]
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise CalibError(
            f"metadata '{key}' is {text!r}, not a number", where, f"write a plain number: {META_HINTS[key]}"
        ) from None
    if not math.isfinite(value):
        raise CalibError(
            f"metadata '{key}' is {text!r}, not a finite number",
            where,
            f"write a plain number: {META_HINTS[key]}",
        )
    return value
