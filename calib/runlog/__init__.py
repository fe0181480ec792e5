"""Run logs (``imu-run/1``): the raw IMU increments of one calibration run, in CSV or NPZ.

The one owner of the run-log format: its name, metadata and columns
(:mod:`~calib.runlog.format`), the `Run` and its metadata builder
(:mod:`~calib.runlog.run`), the checks every reader applies
(:mod:`~calib.runlog.checks`), the CSV and NPZ readers and writers
(:mod:`~calib.runlog.csv`, :mod:`~calib.runlog.npz`), a file by its suffix
(:mod:`~calib.runlog.runfile`), reading a chunk at a time
(:mod:`~calib.runlog.chunks`), a logger's column names
(:mod:`~calib.runlog.columns`), the sample clock of the time column
(:mod:`~calib.runlog.clock`; a polling logger's, :mod:`~calib.runlog.polled`; samples lost at
rest filled, :mod:`~calib.runlog.fill`), the PSINS ``.imu`` log (:mod:`~calib.runlog.psins`);
for hand recordings, a sample counter in place of the time
(:mod:`~calib.runlog.counter`) and a fixed-width count's rollover
(:mod:`~calib.runlog.rollover`), a file's bytes as lines (:mod:`~calib.runlog.text`),
a text log without a header (:mod:`~calib.runlog.headerless`),
raw counts and their nominal conversion
(:mod:`~calib.runlog.conversion`), imu_tk's two files (:mod:`~calib.runlog.imutk`),
a logger's two CSV files, one per sensor (:mod:`~calib.runlog.csvpair`), a RealSense
camera's motion streams in one file of blocks (:mod:`~calib.runlog.realsense`),
two files on two clocks (:mod:`~calib.runlog.streams`) and clipped stretches
(:mod:`~calib.runlog.clipping`). CSV writing is
:mod:`~calib.runlog.csvwrite`.

Every refusal is a `CalibError` naming the file and where in it the problem is:
for CSV the 1-based line number counted from the top of the file (plus the
column and the 0-based sample index), for NPZ the array element (``dv_mps[12, 1]``)
or the metadata key.
"""

from .checks import check_run
from .chunks import READ_ROWS, nominal_period, read_chunks, read_meta
from .clipping import describe_clipping
from .conversion import Conversion, read_conversion
from .format import (
    DTHETA_COLUMNS,
    DV_COLUMNS,
    FORMAT,
    GIMBAL_COLUMNS,
    REQUIRED_COLUMNS,
    REQUIRED_META,
    TIME_COLUMN,
)
from .run import Run, make_meta
from .runfile import read_run, write_run, write_windows

__all__ = [
    "DTHETA_COLUMNS",
    "DV_COLUMNS",
    "FORMAT",
    "GIMBAL_COLUMNS",
    "READ_ROWS",
    "REQUIRED_COLUMNS",
    "REQUIRED_META",
    "TIME_COLUMN",
    "Conversion",
    "Run",
    "check_run",
    "describe_clipping",
    "make_meta",
    "nominal_period",
    "read_chunks",
    "read_conversion",
    "read_meta",
    "read_run",
    "write_run",
    "write_windows",
]
