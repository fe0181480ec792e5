"""Run-log files: `read_run` and `write_run` pick the format by the file's suffix.

``.csv`` (or ``.csv.gz``) and ``.npz`` are read and written (:mod:`calib.runlog.csv`,
:mod:`calib.runlog.npz`); a PSINS ``.imu`` log is read only (:mod:`calib.runlog.psins`).
Both run-log readers apply the same checks (:mod:`calib.runlog.checks`), so a run
that loads from one format loads from the other.
"""

from __future__ import annotations

import os

from calib.errors import CalibError
from calib.io.files import atomic_write_file
from calib.io.kinds import expect

from . import clock, polled
from .checks import check_run
from .conversion import Conversion, as_conversion
from .csv import read_csv
from .csvpair import has_header, read_csv_pair
from .csvwrite import check_meta_writable_as_csv, write_csv
from .imutk import read_imutk
from .npz import read_npz, write_npz
from .paths import run_kind
from .psins import read_psins
from .realsense import is_realsense, read_realsense
from .run import Run

_NOT_WRITTEN = "the PSINS .imu format is read, not written"


# over 8 parameters: the reader's keywords, each one of the CLI's reading options
def read_run(
    path: str | os.PathLike,
    allow_gaps: bool = False,
    *,
    latitude_deg: float | None = None,
    height_m: float | None = None,
    columns: str | dict[str, str] | None = None,
    gyro_path: str | os.PathLike | None = None,
    conversion: Conversion | str | os.PathLike | None = None,
    sample_rate_hz: float | None = None,
    guess_turns: bool = False,
    at_stamps: bool = False,
) -> Run:
    """Read and check a run log, ``.csv`` (or ``.csv.gz``), ``.npz`` or PSINS ``.imu``.

    The time column is mapped to sample counts (:mod:`calib.runlog.clock`): a run
    whose clock only jitters comes back on the uniform time base
    ``offset + count / sample_rate_hz``, with the jitter in ``run.clock``.

    Parameters
    ----------
    path : str or os.PathLike
        Run log file.
    allow_gaps : bool
        Accept dropped and duplicated samples (the CLI's ``--allow-gaps``): duplicates
        are removed and samples lost at rest filled (`calib.runlog.clock.settle`).
    latitude_deg, height_m : float, optional
        Site metadata for a CSV file that lacks it (the CLI's ``--latitude``, ``--height``);
        a file that has the key and a different value is refused.
    columns : str or dict, optional
        For a CSV file, the file's column names mapped to the names of
        ``docs/logs-columns.md`` (the CLI's ``--columns``):
        ``"t=time_ms,gx=gyro_x_dps,gy=gyro_y_dps,gz=gyro_z_dps,ax=accel_x_g,ay=accel_y_g,az=accel_z_g"``
        or the same pairs as a dict; columns it does not name keep their names.
    gyro_path : str or os.PathLike, optional
        The gyro's own file (the CLI's ``--gyro-file``): ``path`` is then the
        accelerometer's. Two CSV files with headers, each its time and its sensor
        (:mod:`calib.runlog.csvpair`; ``columns`` maps both), or imu_tk's headerless
        ``t x y z`` files in raw counts (:mod:`calib.runlog.imutk`).
    conversion : Conversion or str or os.PathLike, optional
        The nominal conversion of raw counts to SI, or its file (the CLI's
        ``--conversion``; :mod:`calib.runlog.conversion`): needed by columns in
        ``counts`` and by imu_tk's files; kept as ``run.conversion``.
    sample_rate_hz : float, optional
        The IMU's rate (the CLI's ``--sample-rate-hz``) for a file that does not
        state it: needed by a sample counter (``counter`` column); a file that
        states another is refused.
    guess_turns : bool
        With ``allow_gaps``, for a hand fit: a sample lost amid a turn is put in as a
        guess and marked in ``run.guessed`` (the fit leaves its move out) instead of
        refused.
    at_stamps : bool
        The rows were sampled at their stamps (the CLI's ``--at-stamps``): a logger that
        reads the sensor whenever its loop comes round, whose stamps no rule of
        :mod:`calib.runlog.polled` tells from a crystal's under a host's jitter. Every row
        is then the next sample over its own stamp interval; a stall is a hole.

    A CSV file may be gzip-compressed (``.csv.gz``). A CSV file without a
    ``# format:`` line is a logger's file (``docs/logs-columns.md``): it is read as
    ``imu-run/1``, its sample rate, when absent, comes from the time column, whose
    unit (s, ms, us or ns) its name gives.

    Returns
    -------
    Run
        Arrays in float64, ``source`` set to ``str(path)``, ``clock`` set.

    Raises
    ------
    CalibError
        On any unreadable or invalid content, naming the file and the line,
        key or sample.
    """
    with polled.told_at_stamps(at_stamps):
        return _read_run(path, allow_gaps, latitude_deg, height_m, columns, gyro_path, conversion,
                         sample_rate_hz, guess_turns)  # fmt: skip


# over 8 parameters: read_run's own, passed on
def _read_run(
    path, allow_gaps, latitude_deg, height_m, columns, gyro_path, conversion, sample_rate_hz, guess_turns
) -> Run:
    expect(path, "run")
    conversion = as_conversion(conversion)
    site = {"latitude_deg": latitude_deg, "height_m": height_m, "sample_rate_hz": sample_rate_hz}
    if gyro_path is not None and (has_header(path) or columns):
        # Files with a header, or without one and mapped by position (OpenCamera's x,y,z,t rows).
        run = read_csv_pair(path, gyro_path, allow_gaps, site, columns, conversion)
        return clock.settle(run, allow_gaps, guess_turns)
    if gyro_path is not None:
        run = read_imutk(path, gyro_path, allow_gaps, site, conversion)
        return clock.settle(run, allow_gaps, guess_turns)
    kind = run_kind(path)
    if kind != ".csv" and (conversion is not None or sample_rate_hz is not None):
        raise CalibError(
            f"{kind} files state their own units and rate",
            str(path),
            "leave out conversion (the CLI's --conversion) and sample_rate_hz "
            "(the CLI's --sample-rate-hz) for this file",
        )
    if columns and kind != ".csv":
        raise CalibError(
            f"a column map renames a CSV file's header, and {kind} files have no header to rename",
            str(path),
            "leave out the column map (columns) for this file",
        )
    if kind == ".imu":
        run = read_psins(path, allow_gaps)
    elif kind == ".csv" and is_realsense(path):
        run = read_realsense(path, allow_gaps, site, columns, conversion)
    elif kind == ".csv":
        run = read_csv(path, allow_gaps, site, columns, conversion)
    else:
        run = read_npz(path, allow_gaps)
    return clock.settle(run, allow_gaps, guess_turns)  # the IMU's own time base, gaps repaired if allowed


def write_run(run: Run, path: str | os.PathLike) -> None:
    """Write a run log atomically as ``.csv`` or ``.npz`` (by suffix).

    The run is checked first as a reader would check it (gaps excepted), so
    the tool never writes a file it would refuse to read. CSV numbers use
    Python's shortest round-trip repr, so reading gives back the exact floats.

    Parameters
    ----------
    run : Run
        Run to write; ``meta`` must contain ``format: imu-run/1`` and the
        required keys (see `make_meta`).
    path : str or os.PathLike
        Destination, ``.csv`` or ``.npz``.

    Raises
    ------
    CalibError
        If the suffix is unknown, the run is invalid, or the file cannot be
        written.
    """
    kind = run_kind(path)
    if kind == ".imu":
        raise CalibError(_NOT_WRITTEN, str(path), "write the run as .csv or .npz")
    # A run read at its stamps as told is checked as it was read (read again, it is told again).
    with polled.told_at_stamps(run.clock is not None and run.clock.told):
        check_run(run, allow_gaps=True)
    if kind == ".csv":
        check_meta_writable_as_csv(run.meta, run.source)
    gimbal = run.gimbal_deg is not None
    window = (run.time_s, run.dtheta_rad, run.dv_mps) + ((run.gimbal_deg,) if gimbal else ())
    _write(path, kind, run.meta, [window], gimbal)


def write_windows(path: str | os.PathLike, meta: dict[str, str], windows) -> int:
    """Write a run given a block at a time atomically as ``.csv`` or ``.npz`` (by suffix).

    For a run too long to hold in memory (:mod:`calib.sim.to_disk`): memory is
    one block's. The samples are not checked, as `write_run` checks them.

    Parameters
    ----------
    path : str or os.PathLike
        Destination, ``.csv`` or ``.npz``.
    meta : dict of str to str
        Metadata (see `make_meta`).
    windows : iterable of tuple of numpy.ndarray
        Consecutive blocks ``(time_s, dtheta_rad, dv_mps)``.

    Returns
    -------
    int
        Number of samples written.
    """
    kind = run_kind(path)
    if kind == ".imu":
        raise CalibError(_NOT_WRITTEN, str(path), "write the run as .csv or .npz")
    return _write(path, kind, meta, windows, gimbal=False)


def _write(path: str | os.PathLike, kind: str, meta: dict[str, str], windows, gimbal: bool) -> int:
    """The one writer of both formats: complete, flushed to disk, or nothing at ``path``."""
    if kind == ".csv":
        return atomic_write_file(path, lambda handle: write_csv(handle, meta, windows, gimbal), text=True)
    return atomic_write_file(path, lambda handle: write_npz(handle, meta, windows, gimbal))
