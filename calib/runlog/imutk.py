"""imu_tk's two files: the accelerometer and the gyro apart, ``t x y z`` in raw counts.

imu_tk (Tedaldi, Pretto, Menegatti, ICRA 2014) records a hand calibration as
two whitespace-separated text files without a header, one row per sample::

    2.9840000e-02   3.3108000e+04   3.3329000e+04   3.6429000e+04

time in seconds, then the three axes in raw converter counts. Files that
share their time stamps (as many rows, each pair within half a period) are
read row for row; others each on its own clock, the accelerometer carried
onto the gyro's samples (:mod:`calib.runlog.streams`). The counts
become SI through a nominal conversion (:mod:`calib.runlog.conversion`), the
time stamps go through the sample clock (:mod:`calib.runlog.clock`) as a
CSV's do. Each row is one IMU sample over one nominal period, so its
increment is its rate (or force) times that period: the host clock's jitter
in the stamps does not enter the increments. ``#`` and ``%`` lines are comments.
"""

from __future__ import annotations

import os
import warnings

import numpy as np

from calib.errors import CalibError
from calib.model.params import STANDARD_GRAVITY

from .checks import check_meta, check_samples
from .clipping import at_limits, clip_mask, flat_top
from .clock import sampled_at_stamps, stamps_rate
from .columns import IMPLAUSIBLE_RATES_HZ, IMU_RATES_HZ, TIME_UNITS
from .conversion import SI_ALREADY, SI_WORD, Conversion
from .format import FORMAT
from .paths import read_bytes
from .polled import own_intervals
from .run import Run
from .streams import Stream, two_clocks

ROW = "t x y z"


class _TwoFiles:
    """Names places in the two files: the gyro's rows in its file, the rest in the accelerometer's."""

    def __init__(self, acc: str, gyro: str, acc_lines: np.ndarray, gyro_lines: np.ndarray):
        self.name, self.gyro = acc, gyro
        self.lines = {"acc": acc_lines, "gyro": gyro_lines}

    def key(self, key: str) -> str:
        return f"{self.name} (metadata '{key}')"

    def sample(self, array: str, index: int, component: int | None = None) -> str:
        file, kind = (self.gyro, "gyro") if array == "dtheta_rad" else (self.name, "acc")
        column = "t" if component is None else "xyz"[component]
        return f"{file}, line {int(self.lines[kind][index])}, column {column} (sample {index})"


def read_imutk(
    acc_path: str | os.PathLike,
    gyro_path: str | os.PathLike,
    allow_gaps: bool,
    options: dict,
    conversion: Conversion | None,
) -> Run:
    """Read imu_tk's accelerometer and gyro files into one run.

    Parameters
    ----------
    acc_path, gyro_path : str or os.PathLike
        The two files, ``t x y z`` in counts (gzip-compressed or not).
    allow_gaps : bool
        Accept dropped and duplicated samples (repaired later by `calib.runlog.clock.settle`).
    options : dict
        ``latitude_deg``, ``height_m`` (required) and ``sample_rate_hz`` (default: the
        stamps' own rate, :func:`calib.runlog.clock.stamps_rate`).
    conversion : Conversion or None
        The nominal conversion of the counts; None is refused.

    Returns
    -------
    Run
        With ``conversion``, ``clock`` and ``clipped`` set; ``meta`` records the conversion.

    Raises
    ------
    CalibError
        On a missing conversion or site, a row that is not four numbers, or files
        with no common time.
    """
    acc_name, gyro_name = str(acc_path), str(gyro_path)
    acc, acc_lines = _table(acc_name)
    gyro, gyro_lines = _table(gyro_name)
    for table, name in ((acc, acc_name), (gyro, gyro_name)):
        table[:, 0] *= _seconds_per_stamp(table[:, 0], name)
    if conversion is None:
        raise CalibError(
            "imu_tk's files are raw counts, and counts say no rate or force without the sensor's "
            "zero and scale" + _already_si(acc[:, 1:]),
            acc_name,
            "give the conversion file: conversion=FILE (the CLI's --conversion FILE), e.g. imu_tk's "
            "nominal-values text or a TOML (docs/logs-columns.md); files already in m/s^2 and rad/s: "
            f"the CLI's --conversion {SI_WORD}",
        )
    si = conversion is SI_ALREADY
    locate = _TwoFiles(acc_name, gyro_name, acc_lines, gyro_lines)
    if not _row_for_row(acc[:, 0], gyro[:, 0], options.get("sample_rate_hz")):
        # Each file on its own clock (another rate, other stamps, other rows): the
        # accelerometer's increments are carried onto the gyro's samples.
        meta = _meta(options, gyro[:, 0], acc_name, conversion)
        check_meta(meta, locate)
        rate = conversion.to_si(gyro[:, 1:], "gyro")
        gyro_clipped = at_limits(gyro[:, 1:], conversion.range_counts, gyro_name, "gyro") | flat_top(rate)
        run = two_clocks(
            Stream(acc_name, acc[:, 0], acc_lines, conversion.to_si(acc[:, 1:], "accel"),
                   at_limits(acc[:, 1:], conversion.range_counts, acc_name, "accel")),
            Stream(gyro_name, gyro[:, 0], gyro_lines, rate, gyro_clipped),
            meta,
            allow_gaps,
        )  # fmt: skip
        run.conversion = None if si else conversion
        return run
    meta = _meta(options, acc[:, 0], acc_name, conversion)
    check_meta(meta, locate)
    period: float | np.ndarray = 1.0 / float(meta["sample_rate_hz"])
    if sampled_at_stamps(acc[:, 0], float(meta["sample_rate_hz"])):  # each row over its own stamp interval
        period = own_intervals(acc[:, 0])
    rate = conversion.to_si(gyro[:, 1:], "gyro")
    clipped = clip_mask(
        at_limits(gyro[:, 1:], conversion.range_counts, gyro_name, "gyro") | flat_top(rate),
        at_limits(acc[:, 1:], conversion.range_counts, acc_name, "accel"),
        len(acc),
    )
    run = Run(
        time_s=np.ascontiguousarray(acc[:, 0]),
        dtheta_rad=rate * period,
        dv_mps=conversion.to_si(acc[:, 1:], "accel") * period,
        meta=meta,
        source=acc_name,
        conversion=None if si else conversion,
        clipped=clipped,
    )
    run.clock = check_samples(run, locate, allow_gaps, "time_s")
    return run


def _seconds_per_stamp(time: np.ndarray, name: str) -> float:
    """Seconds per unit of a file's time column: 1, unless its rate in seconds is no IMU's.

    imu_tk's time is in seconds; a logger's may count ms, us or ns (a ROS stamp). Below the
    slowest plausible rate (``IMPLAUSIBLE_RATES_HZ``) the unit that puts it among an IMU's
    (``IMU_RATES_HZ``) is the file's, as :func:`calib.runlog.columns.time_unit_suspect` judges a CSV's.
    """
    if len(time) < 3:
        return 1.0
    rate = stamps_rate(time - time[0])
    if rate >= IMPLAUSIBLE_RATES_HZ[0]:
        return 1.0
    unit = next((u for u, k in TIME_UNITS.items() if IMU_RATES_HZ[0] <= rate * k < IMU_RATES_HZ[1]), None)
    if unit is None:
        return 1.0
    warnings.warn(
        f"{name}: the time column steps by {1.0 / rate:.4g} per sample, {rate * TIME_UNITS[unit]:.4g} Hz "
        f"if it counts {unit}: read as {unit} (imu_tk's files count seconds)",
        stacklevel=3,
    )
    return 1.0 / TIME_UNITS[unit]


def _row_for_row(acc_s: np.ndarray, gyro_s: np.ndarray, rate_hz: float | None) -> bool:
    """Whether the two files share their stamps: as many rows, each pair within half a period."""
    if len(acc_s) != len(gyro_s) or len(acc_s) < 2:
        return False
    rate = rate_hz if rate_hz is not None else stamps_rate(acc_s)
    return bool(np.all(np.abs(acc_s - gyro_s) <= 0.5 / rate))


def _table(name: str) -> tuple[np.ndarray, np.ndarray]:
    """A file's rows of four numbers and their 1-based line numbers."""
    data = read_bytes(name)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise CalibError(
            "the file is not text", name, f"give imu_tk's text file, one row '{ROW}' per sample"
        ) from None
    lines = text.splitlines()
    keep = [i for i, line in enumerate(lines) if line.strip() and line.lstrip()[0] not in "#%"]
    numbers = np.array(keep, dtype=np.int64) + 1
    if not keep:
        raise CalibError("the file has no data rows", name, f"one row '{ROW}' per sample")
    rows = [lines[i] for i in keep]
    try:
        table = np.loadtxt(rows, dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        table = None
    if table is None or table.shape != (len(rows), 4) or not np.isfinite(table).all():
        for row, line in zip(rows, numbers.tolist(), strict=True):
            fields = row.split()
            try:
                ok = len(fields) == 4 and all(np.isfinite(float(f)) for f in fields)
            except ValueError:
                ok = False
            if not ok:
                raise CalibError(
                    f"row {row.strip()[:60]!r} is not four numbers '{ROW}'",
                    f"{name}, line {line}",
                    "each row is the time in s and the three axes in counts, separated by spaces",
                )
    assert table is not None
    return table, numbers


def _meta(options: dict, time_s: np.ndarray, name: str, conversion: Conversion) -> dict[str, str]:
    """The run's metadata: the site from the options, the rate stated or the stamps', the conversion."""
    missing = [k for k in ("latitude_deg", "height_m") if options.get(k) is None]
    if missing:
        hint = {
            "latitude_deg": "latitude_deg (the CLI's --latitude DEG)",
            "height_m": "height_m (the CLI's --height M)",
        }
        raise CalibError(
            "imu_tk's files do not say the site: " + ", ".join(f"'{k}'" for k in missing) + " missing",
            name,
            "give " + ", ".join(hint[k] for k in missing),
        )
    rate = options.get("sample_rate_hz")
    if rate is None:
        rate = float(f"{stamps_rate(time_s):.12g}") if len(time_s) >= 2 else float("nan")
    meta = {
        "format": FORMAT,
        "latitude_deg": repr(float(options["latitude_deg"])),
        "height_m": repr(float(options["height_m"])),
        "sample_rate_hz": repr(float(rate)),
        "source_format": "imu_tk",
    }
    return meta if conversion is SI_ALREADY else meta | conversion.meta()


def _already_si(force: np.ndarray) -> str:
    """What the accelerometer file's size says of its unit, when it is no count's (m/s^2 or g)."""
    size = float(np.median(np.linalg.norm(force, axis=1)))
    for unit, g in (("m/s^2", STANDARD_GRAVITY), ("g", 1.0)):
        if 0.8 * g < size < 1.2 * g:
            return f"; the accelerometer's rows are {size:.3g} in size, as if already in {unit}"
    return ""
