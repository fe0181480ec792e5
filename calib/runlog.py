"""Run logs: the raw IMU increments of one calibration run, in CSV or NPZ.

The formats are specified in ``spec/files.md`` ("Run log, CSV" and "Run log,
NPZ"). Both readers return the same `Run` and apply the same checks, so a run
that loads from one format loads from the other.

Every refusal is a `CalibError` naming the file and where in it the problem is:
for CSV the 1-based line number counted from the top of the file (plus the
column and the 0-based sample index), for NPZ the array element (``dv_mps[12, 1]``)
or the metadata key.
"""

from __future__ import annotations

import gzip
import io
import json
import lzma
import math
import os
import tokenize
import zipfile
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from calib import clock
from calib.columns import ColumnPlan, plan_columns, to_increments
from calib.earth import HEIGHT_RANGE_M  # one source: the site limits of calib.earth
from calib.errors import CalibError
from calib.fileio import atomic_write_bytes, atomic_write_text
from calib.filekind import expect

FORMAT = "imu-run/1"
REQUIRED_META = ("format", "latitude_deg", "height_m", "sample_rate_hz")

TIME_COLUMN = "time_s"
DTHETA_COLUMNS = ("dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad")
DV_COLUMNS = ("dv_x_mps", "dv_y_mps", "dv_z_mps")
GIMBAL_COLUMNS = ("outer_deg", "middle_deg", "inner_deg")
REQUIRED_COLUMNS = (TIME_COLUMN, *DTHETA_COLUMNS, *DV_COLUMNS)

# CSV column names of each Run array, by component.
_ARRAY_COLUMNS = {
    "time_s": (TIME_COLUMN,),
    "dtheta_rad": DTHETA_COLUMNS,
    "dv_mps": DV_COLUMNS,
    "gimbal_deg": GIMBAL_COLUMNS,
}

GAP_PERIODS = 2.0  # the typical time step must lie within [0.5, 2] nominal periods


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
    clock : calib.clock.SampleClock or None
        Jitter, dropped and duplicated samples found by `read_run`.
    """

    time_s: np.ndarray
    dtheta_rad: np.ndarray
    dv_mps: np.ndarray
    meta: dict[str, str]
    gimbal_deg: np.ndarray | None = None
    source: str = "<memory>"
    clock: clock.SampleClock | None = None  # what read_run found in the time column

    @property
    def latitude_deg(self) -> float:
        """Geodetic latitude of the site, degrees."""
        return _meta_float(self.meta, "latitude_deg", self.source)

    @property
    def height_m(self) -> float:
        """Ellipsoidal height of the site, m."""
        return _meta_float(self.meta, "height_m", self.source)

    @property
    def sample_rate_hz(self) -> float:
        """Nominal IMU output rate, Hz."""
        return _meta_float(self.meta, "sample_rate_hz", self.source)

    @property
    def gravity_mps2(self) -> float | None:
        """Measured gravity at the site, m/s^2, or None to use normal gravity."""
        if "gravity_mps2" not in self.meta:
            return None
        return _meta_float(self.meta, "gravity_mps2", self.source)

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


# --------------------------------------------------------------------------
# Public entry points
# --------------------------------------------------------------------------


def read_run(
    path: str | os.PathLike,
    allow_gaps: bool = False,
    *,
    latitude_deg: float | None = None,
    height_m: float | None = None,
) -> Run:
    """Read and check a run log, ``.csv`` (or ``.csv.gz``), ``.npz`` or PSINS ``.imu``.

    The time column is mapped to sample counts (:mod:`calib.clock`): a run
    whose clock only jitters comes back on the uniform time base
    ``offset + count / sample_rate_hz``, with the jitter in ``run.clock``.

    Parameters
    ----------
    path : str or os.PathLike
        Run log file.
    allow_gaps : bool
        Accept dropped and duplicated samples (``--allow-gaps``): duplicates
        are removed and samples lost at rest filled (`calib.clock.settle`).
    latitude_deg, height_m : float, optional
        Site metadata for a CSV file that lacks it (``--latitude``, ``--height``);
        a file that has the key and a different value is refused.

    A CSV file may be gzip-compressed (``.csv.gz``). A CSV file without a
    ``# format:`` line is a logger's file (``docs/logs-columns.md``): it is read as
    ``imu-run/1``, its sample rate, when absent, comes from the time column.

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
    expect(path, "run")
    kind = _kind(path)
    if kind == ".imu":
        from calib.psins import read_psins

        run = read_psins(path, allow_gaps)
    elif kind == ".csv":
        run = _read_csv(path, allow_gaps, {"latitude_deg": latitude_deg, "height_m": height_m})
    else:
        run = _read_npz(path, allow_gaps)
    return clock.settle(run, allow_gaps)  # the IMU's own time base, gaps repaired if allowed


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
    kind = _kind(path)
    if kind == ".imu":
        raise CalibError(
            "the PSINS .imu format is read, not written", str(path), "write the run as .csv or .npz"
        )
    check_run(run, allow_gaps=True)
    if kind == ".csv":
        _check_meta_writable_as_csv(run.meta, run.source)
        atomic_write_text(path, _format_csv(run))
    else:
        atomic_write_bytes(path, _format_npz(run))


def check_run(run: Run, allow_gaps: bool = False) -> None:
    """Apply the run-log checks to an in-memory run.

    Parameters
    ----------
    run : Run
        Run to check; messages name ``run.source`` and array elements.
    allow_gaps : bool
        Accept time steps longer than two nominal periods.

    Raises
    ------
    CalibError
        On the first problem found.
    """
    name = run.source
    for key, value in run.meta.items():
        if not isinstance(key, str) or not isinstance(value, str):
            raise CalibError(
                f"metadata {key!r}: {value!r} is not a pair of strings",
                name,
                "metadata keys and values are strings, e.g. from make_meta()",
            )
    time = np.asarray(run.time_s)
    n = time.shape[0] if time.ndim >= 1 else 0
    for array_name in _ARRAY_COLUMNS:
        array = getattr(run, array_name)
        if array is not None:
            _check_array_shape(np.asarray(array), array_name, n, f"{name}, array '{array_name}'")
    locate = _ArrayLocator(name)
    _check_meta(run.meta, locate)
    _check_samples(run, locate, allow_gaps)


# --------------------------------------------------------------------------
# Shared checks
# --------------------------------------------------------------------------


class _ArrayLocator:
    """Names places in an NPZ file or in-memory run: array elements and meta keys."""

    def __init__(self, name: str):
        self.name = name

    def key(self, key: str) -> str:
        return f"{self.name}, meta key '{key}'"

    def sample(self, array: str, index: int, component: int | None = None) -> str:
        element = f"{index}" if component is None else f"{index}, {component}"
        return f"{self.name}, {array}[{element}]"


class _CsvLocator:
    """Names places in a CSV file: 1-based line numbers, column names, sample index."""

    def __init__(
        self,
        name: str,
        key_lines: dict[str, int],
        sample_lines: np.ndarray,
        columns: dict[str, tuple[str, ...]] | None = None,
    ):
        self.name = name
        self.key_lines = key_lines
        self.sample_lines = sample_lines
        self.columns = {**_ARRAY_COLUMNS, **(columns or {})}  # the file's own column names

    def key(self, key: str) -> str:
        line = self.key_lines.get(key)
        return self.name if line is None else f"{self.name}, line {line}"

    def sample(self, array: str, index: int, component: int | None = None) -> str:
        text = f"{self.name}, line {int(self.sample_lines[index])}"
        if component is not None or array == "time_s":
            text += f", column {self.columns[array][component or 0]}"
        return text + f" (sample {index})"


# What each numeric key means, for the fix part of messages.
_META_HINTS = {
    "latitude_deg": "geodetic latitude in degrees, north positive, within [-90, 90]",
    "height_m": "ellipsoidal height in metres, within [-1000, 10000]",
    "sample_rate_hz": "the IMU output rate in Hz, greater than 0",
    "gravity_mps2": "measured gravity in m/s^2, greater than 0, or leave the key out",
}


def _meta_float(meta: dict[str, str], key: str, where: str) -> float:
    """Parse one numeric metadata value; refuse missing, non-numeric or non-finite."""
    if key not in meta:
        raise CalibError(
            f"required metadata '{key}' is missing",
            where,
            f"add a line '# {key}: <value>' ({_META_HINTS[key]})",
        )
    text = meta[key]
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise CalibError(
            f"metadata '{key}' is {text!r}, not a number", where, f"write a plain number: {_META_HINTS[key]}"
        ) from None
    if not math.isfinite(value):
        raise CalibError(
            f"metadata '{key}' is {text!r}, not a finite number",
            where,
            f"write a plain number: {_META_HINTS[key]}",
        )
    return value


def _check_meta(meta: dict[str, str], locate) -> None:
    """Refuse missing/unknown format, missing required keys and out-of-range values."""
    if "format" not in meta:
        raise CalibError(
            "no 'format' metadata: this does not look like a run log",
            locate.key("format"),
            f"start the file with '# format: {FORMAT}'",
        )
    if meta["format"].strip() != FORMAT:
        raise CalibError(
            f"unknown format {meta['format']!r}",
            locate.key("format"),
            f"this tool reads '{FORMAT}'; convert the file to that format",
        )
    values = {key: _meta_float(meta, key, locate.key(key)) for key in REQUIRED_META[1:]}
    if not -90.0 <= values["latitude_deg"] <= 90.0:
        raise CalibError(
            f"latitude_deg = {values['latitude_deg']} is outside [-90, 90]",
            locate.key("latitude_deg"),
            "give the geodetic latitude in degrees",
        )
    low, high = HEIGHT_RANGE_M
    if not low <= values["height_m"] <= high:
        raise CalibError(
            f"height_m = {values['height_m']} is outside [{low:g}, {high:g}] m",
            locate.key("height_m"),
            "give the ellipsoidal height of the site in metres",
        )
    if values["sample_rate_hz"] <= 0.0:
        raise CalibError(
            f"sample_rate_hz = {values['sample_rate_hz']} is not positive",
            locate.key("sample_rate_hz"),
            "give the IMU output rate in Hz",
        )
    if "gravity_mps2" in meta:
        gravity = _meta_float(meta, "gravity_mps2", locate.key("gravity_mps2"))
        if gravity <= 0.0:
            raise CalibError(
                f"gravity_mps2 = {gravity} is not positive",
                locate.key("gravity_mps2"),
                "give the measured gravity in m/s^2, or leave the key out",
            )


def _check_array_shape(array: np.ndarray, name: str, n: int, where: str) -> None:
    """Refuse arrays that are not real numbers of shape (n,) for time, (n, 3) otherwise."""
    if array.dtype.kind not in "iuf":
        raise CalibError(
            f"array '{name}' has dtype {array.dtype}, not real numbers", where, "store float64 values"
        )
    expected = (n,) if name == "time_s" else (n, 3)
    if array.shape != expected:
        text = "(n,)" if name == "time_s" else "(n, 3)"
        raise CalibError(
            f"array '{name}' has shape {array.shape}, expected {text} with n = {n} (the length of time_s)",
            where,
            "store one row per sample, all arrays the same length",
        )


def _check_samples(run: Run, locate, allow_gaps: bool) -> clock.SampleClock:
    """Refuse too few samples, non-finite values, non-increasing time and (unless allowed) gaps.

    Returns the sample clock of the time column (:func:`calib.clock.sample_clock`).
    """
    time = np.asarray(run.time_s)
    n = time.shape[0]
    if n < 2:
        raise CalibError(
            f"the run has {n} sample{'s' if n != 1 else ''}; at least 2 are needed",
            run.source,
            "record a longer run",
        )
    _check_finite(run, locate)
    step = np.diff(time)
    period = 1.0 / run.sample_rate_hz
    # A row repeating the previous one is a duplicated sample, named below with the gaps.
    duplicate = clock.duplicate_rows(time, np.asarray(run.dtheta_rad), np.asarray(run.dv_mps), period)
    backwards = np.flatnonzero((step <= 0.0) & ~duplicate[1:])
    if backwards.size:
        i = int(backwards[0]) + 1
        raise CalibError(
            f"time does not strictly increase: time_s = {float(time[i])!r} follows "
            f"{float(time[i - 1])!r}"
            + (f" ({backwards.size} such steps in all)" if backwards.size > 1 else ""),
            locate.sample("time_s", i),
            "samples must be in time order without repeats; sort the log or remove duplicates",
        )
    # The nominal period must describe the time stamps (gaps and jitter aside), or
    # gap detection, durations and the first sample's interval are all wrong.
    typical = float(np.median(step))
    if not 0.5 * period <= typical <= GAP_PERIODS * period:
        raise CalibError(
            f"sample_rate_hz = {run.sample_rate_hz:g} (a period of {period:g} s) does not match "
            f"the time stamps, which are typically {typical:.6g} s apart",
            locate.key("sample_rate_hz"),
            "give the IMU output rate in Hz, the inverse of the time between samples",
        )
    try:
        found = clock.sample_clock(time, run.sample_rate_hz, duplicate)
    except CalibError as exc:
        raise CalibError(exc.what, locate.sample("time_s", int(exc.where)), exc.fix) from None
    if not allow_gaps and (found.dropped or found.duplicates):
        first = np.flatnonzero(np.diff(found.index) != 1)[0] + 1
        raise clock.refusal(found, locate.sample("time_s", int(first)))
    return found


def _check_finite(run: Run, locate) -> None:
    """Refuse NaN or infinity anywhere, naming the earliest sample that has one."""
    first: tuple[int, str, int | None] | None = None
    for name in _ARRAY_COLUMNS:
        array = getattr(run, name)
        if array is None:
            continue
        array = np.asarray(array)
        if np.isfinite(array).all():  # the common case, without a row-by-row reduction
            continue
        bad = ~np.isfinite(array)
        rows = np.flatnonzero(bad if array.ndim == 1 else bad.any(axis=1))
        if rows.size and (first is None or rows[0] < first[0]):
            i = int(rows[0])
            component = None if array.ndim == 1 else int(np.flatnonzero(bad[i])[0])
            first = (i, name, component)
    if first is None:
        return
    i, name, component = first
    array = np.asarray(getattr(run, name))
    value = array[i] if component is None else array[i, component]
    raise CalibError(
        f"value {float(value)!r} is not a finite number",
        locate.sample(name, i, component),
        "every sample must be a finite number; remove or repair the sample",
    )


def _kind(path: str | os.PathLike) -> str:
    """Lower-case suffix, refused unless .csv, .npz or .imu."""
    suffix = Path(path).suffix.lower()
    if suffix == ".gz" and Path(path).name.lower().endswith(".csv.gz"):
        return ".csv"  # read through gzip (_read_bytes)
    if suffix not in (".csv", ".npz", ".imu"):
        raise CalibError(
            f"unknown run log type {suffix or '(no suffix)'!r}",
            str(path),
            "name run logs *.csv (interchange), *.npz (fast native) or *.imu (PSINS text, read only)",
        )
    return suffix


def _require_file(path: str | os.PathLike) -> None:
    """Refuse a missing path or a directory before a parser sees it."""
    if not Path(path).exists():
        raise CalibError("file not found", str(path), "check the path")
    if not Path(path).is_file():
        raise CalibError("not a regular file", str(path), "give the path of a run log file")


def _read_bytes(path: str | os.PathLike) -> bytes:
    """Read a whole file, turning OS errors into CalibError."""
    _require_file(path)
    try:
        data = Path(path).read_bytes()
        return gzip.decompress(data) if data[:2] == b"\x1f\x8b" else data
    except (OSError, EOFError, zlib.error) as exc:  # gzip.BadGzipFile is an OSError
        raise CalibError(
            f"cannot read the file: {getattr(exc, 'strerror', None) or exc}",
            str(path),
            "check the path and permissions",
        ) from None


# --------------------------------------------------------------------------
# CSV
# --------------------------------------------------------------------------


def _read_csv(path: str | os.PathLike, allow_gaps: bool, options: dict | None = None) -> Run:
    """Read a CSV run log (see module docstring for how places are named)."""
    name = str(path)
    lines = _decode_lines(_read_bytes(path), name)
    meta, key_lines, header_index = _parse_preamble(lines, name)
    lines = _to_commas(lines, header_index, name)
    plan, has_gimbal, positions = _parse_header(lines[header_index], header_index + 1, name)
    rows, row_lines = _data_rows(lines, header_index + 1)
    if not rows:
        raise CalibError(
            "the header row is not followed by any data rows",
            f"{name}, line {header_index + 1}",
            "a run log needs one row per sample",
        )
    n_fields = len(lines[header_index].split(","))
    _check_field_counts(rows, row_lines, n_fields, name)
    wanted = [plan.time, *plan.gyro.positions, *plan.accel.positions]
    if has_gimbal:
        wanted += [positions[c] for c in GIMBAL_COLUMNS]
    all_names = [c.strip() for c in lines[header_index].split(",")]
    data = _parse_numbers(rows, row_lines, wanted, all_names, name)
    time_s = np.ascontiguousarray(data[:, 0])
    _fill_meta(meta, options or {}, time_s, name, header_index + 1)
    locate = _CsvLocator(
        name, key_lines, row_lines, {"dtheta_rad": plan.gyro.names, "dv_mps": plan.accel.names}
    )
    _check_meta(meta, locate)
    dt = 1.0 / _meta_float(meta, "sample_rate_hz", name)
    run = Run(
        time_s=time_s,
        dtheta_rad=np.ascontiguousarray(to_increments(data[:, 1:4], plan.gyro, time_s, dt)),
        dv_mps=np.ascontiguousarray(to_increments(data[:, 4:7], plan.accel, time_s, dt)),
        meta=meta,
        gimbal_deg=np.ascontiguousarray(data[:, 7:10]) if has_gimbal else None,
        source=name,
    )
    # The clock the checks found goes with the run: clock.settle does not find it again.
    return replace(run, clock=_check_samples(run, locate, allow_gaps))


def _to_commas(lines: list[str], header_index: int, name: str) -> list[str]:
    """Lines of a CSV written with ';' or tabs between fields, rewritten with commas.

    A semicolon-separated file from a locale that writes decimal commas
    (``0,25;1,5``) has its decimal commas read as points. Said on stderr, so a
    user sees how the file was read.
    """
    header = lines[header_index]
    if "," in header:
        return lines
    sep = next((c for c in (";", "\t") if c in header), None)
    if sep is None:
        return lines
    body = lines[header_index + 1 :]
    decimal_commas = sep == ";" and any("," in row for row in body[:100])
    if decimal_commas:
        body = [row.replace(",", ".") for row in body]
    import warnings

    warnings.warn(
        f"{name}: fields separated by {'tabs' if sep == chr(9) else repr(sep)}"
        f"{' with decimal commas' if decimal_commas else ''}; read as such",
        stacklevel=3,
    )
    return lines[:header_index] + [row.replace(sep, ",") for row in [header] + body]


def _fill_meta(meta: dict[str, str], options: dict, time_s: np.ndarray, name: str, header_line: int) -> None:
    """Site keys from options; for a logger's file (no format line) also format and rate.

    A file declaring ``imu-run/1`` keeps the contract of files.md: its sample rate
    must be written in it. A logger's file gets the rate from the median time step
    and a message listing every key still missing, with an example preamble.
    """
    for key, value in options.items():
        if value is None:
            continue
        if key in meta:
            try:
                same = float(meta[key]) == float(value)
            except ValueError:
                same = False
            if not same:
                raise CalibError(
                    f"the file says {key} = {meta[key]} but the option gives {value:g}",
                    name,
                    "drop the option, or correct the file",
                )
            continue
        meta[key] = repr(float(value))
    if "format" in meta:
        return
    meta["format"] = FORMAT
    if "sample_rate_hz" not in meta and time_s.size >= 2:
        step = float(np.median(np.diff(time_s)))
        if step > 0:
            # Printed time stamps carry rounding (0.01 is not exact): 9 digits of the rate.
            meta["sample_rate_hz"] = repr(float(f"{1.0 / step:.9g}"))
    missing = [k for k in REQUIRED_META[1:] if k not in meta]
    if missing:
        options_hint = {
            "latitude_deg": "--latitude DEG",
            "height_m": "--height M",
            "sample_rate_hz": "a time_s column that increases",
        }
        raise CalibError(
            "the file lacks " + ", ".join(f"'{k}'" for k in missing),
            f"{name}, line {header_line}",
            "give " + ", ".join(options_hint[k] for k in missing) + ", or write them above the "
            "header, e.g. '# latitude_deg: 51.08', '# height_m: 1100', '# sample_rate_hz: 100'",
        )


def _decode_lines(data: bytes, name: str) -> list[str]:
    """UTF-8 (optional BOM) to lines split on LF; CRLF files read the same."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise CalibError(
            f"byte 0x{data[exc.start]:02x} is not valid UTF-8 (byte offset {exc.start})",
            f"{name}, line {line}",
            "save the file as UTF-8",
        ) from None
    if not text.strip():
        raise CalibError(
            "the file is empty",
            name,
            f"a run log starts with '# format: {FORMAT}', metadata, a header row and one row per sample",
        )
    if "\r" in text:
        text = text.replace("\r\n", "\n")
    return text.split("\n")


def _parse_preamble(lines: list[str], name: str) -> tuple[dict[str, str], dict[str, int], int]:
    """Collect ``# key: value`` lines up to the header row.

    Returns
    -------
    meta : dict of str to str
        Metadata in file order.
    key_lines : dict of str to int
        1-based line of each key.
    header_index : int
        0-based index of the header row.
    """
    meta: dict[str, str] = {}
    key_lines: dict[str, int] = {}
    for index, line in enumerate(lines):
        stripped = line.strip()
        if not stripped:
            continue
        if not stripped.startswith("#"):
            return meta, key_lines, index
        key, colon, value = stripped[1:].partition(":")
        if not colon:
            continue  # a plain comment line
        key = key.strip()
        if not key:
            raise CalibError(
                "metadata line has no key before ':'", f"{name}, line {index + 1}", "write '# key: value'"
            )
        if key in meta:
            raise CalibError(
                f"metadata key '{key}' appears twice (first on line {key_lines[key]})",
                f"{name}, line {index + 1}",
                "keep one of the two lines",
            )
        meta[key] = value.strip()
        key_lines[key] = index + 1
    raise CalibError(
        "no header row after the metadata", name, "add the header row: " + ",".join(REQUIRED_COLUMNS)
    )


def _parse_header(line: str, line_number: int, name: str) -> tuple[ColumnPlan, bool, dict[str, int]]:
    """The columns of the header row (grammar of :mod:`calib.columns`) and the gimbal's."""
    names = [c.strip() for c in line.split(",")]
    where = f"{name}, line {line_number}"
    plan = plan_columns(names, where)
    positions: dict[str, int] = {}
    for position, column in enumerate(names):
        if column in positions and column in GIMBAL_COLUMNS:
            raise CalibError(
                f"column '{column}' appears twice in the header", where, "keep one of the two columns"
            )
        positions.setdefault(column, position)
    gimbal = [c for c in GIMBAL_COLUMNS if c in positions]
    if gimbal and len(gimbal) < 3:
        absent = [c for c in GIMBAL_COLUMNS if c not in positions]
        raise CalibError(
            f"header row has gimbal column{'s' if len(gimbal) > 1 else ''} "
            f"{', '.join(gimbal)} but lacks {', '.join(absent)}",
            where,
            "give all three of " + ",".join(GIMBAL_COLUMNS) + " or none",
        )
    return plan, bool(gimbal), positions


def _data_rows(lines: list[str], first: int) -> tuple[list[str], np.ndarray]:
    """Non-blank lines after the header and their 1-based line numbers."""
    body = lines[first:]
    blank = [i for i, line in enumerate(body) if not line.strip()]
    if not blank:
        return body, np.arange(first + 1, first + 1 + len(body))
    keep = np.ones(len(body), dtype=bool)
    keep[blank] = False
    numbers = np.flatnonzero(keep) + first + 1
    return [line for line, k in zip(body, keep.tolist()) if k], numbers


def _check_field_counts(rows: list[str], row_lines: np.ndarray, n_fields: int, name: str) -> None:
    """Refuse rows whose field count differs from the header's."""
    commas = np.fromiter((row.count(",") for row in rows), dtype=np.int64, count=len(rows))
    bad = np.flatnonzero(commas != n_fields - 1)
    if bad.size:
        i = int(bad[0])
        more = f" ({bad.size} such rows in all)" if bad.size > 1 else ""
        raise CalibError(
            f"row has {commas[i] + 1} fields, the header has {n_fields}{more}",
            f"{name}, line {int(row_lines[i])} (sample {i})",
            "every data row needs one value per header column",
        )


def _parse_numbers(
    rows: list[str], row_lines: np.ndarray, wanted: list[int], names: list[str], name: str
) -> np.ndarray:
    """Parse the wanted columns as float64, fast; on failure find and name the bad field."""
    try:
        data = np.loadtxt(rows, delimiter=",", comments=None, dtype=np.float64, usecols=wanted, ndmin=2)
    except ValueError:
        data = None
    if data is not None and data.shape == (len(rows), len(wanted)):
        return data
    return _parse_numbers_slowly(rows, row_lines, wanted, names, name)


def _parse_numbers_slowly(
    rows: list[str], row_lines: np.ndarray, wanted: list[int], names: list[str], name: str
) -> np.ndarray:
    """Field-by-field parse: slow, but it can say exactly which field is bad."""
    data = np.empty((len(rows), len(wanted)))
    for i, row in enumerate(rows):
        fields = row.split(",")
        for j, position in enumerate(wanted):
            try:
                data[i, j] = float(fields[position])
            except ValueError:
                raise CalibError(
                    f"field {fields[position].strip()!r} is not a number",
                    f"{name}, line {int(row_lines[i])}, column {names[position]} (sample {i})",
                    "write plain decimal numbers such as 1.5e-07",
                ) from None
    return data


def _format_csv(run: Run) -> str:
    """The CSV text of a run: metadata (format first), header, shortest-repr rows."""
    meta_lines = [f"# format: {FORMAT}"]
    meta_lines += [f"# {key}: {value}" for key, value in run.meta.items() if key != "format"]
    header = list(REQUIRED_COLUMNS)
    columns = [np.reshape(run.time_s, (-1, 1)), run.dtheta_rad, run.dv_mps]
    if run.gimbal_deg is not None:
        header += GIMBAL_COLUMNS
        columns.append(run.gimbal_deg)
    table = np.hstack([np.asarray(c, dtype=np.float64) for c in columns])
    # repr() is the shortest text that reads back to the same float, and
    # mapping it column by column is as fast as np.savetxt('%.17g').
    text_columns = [list(map(repr, column)) for column in table.T.tolist()]
    body = "\n".join(map(",".join, zip(*text_columns)))
    return "\n".join(meta_lines) + "\n" + ",".join(header) + "\n" + body + "\n"


def _check_meta_writable_as_csv(meta: dict[str, str], name: str) -> None:
    """Refuse metadata that would not read back the same from '# key: value' lines."""
    for key, value in meta.items():
        if not key or key != key.strip() or ":" in key or "\n" in key or "\r" in key:
            raise CalibError(
                f"metadata key {key!r} cannot be written as '# key: value'",
                name,
                "use keys without ':', line breaks or surrounding spaces",
            )
        if "\n" in value or "\r" in value:
            raise CalibError(
                f"metadata '{key}' contains a line break", name, "keep metadata values on one line"
            )


# --------------------------------------------------------------------------
# NPZ
# --------------------------------------------------------------------------

_NPZ_ARRAYS = ("time_s", "dtheta_rad", "dv_mps")

# Everything numpy/zipfile raise for a damaged or foreign file: RuntimeError covers
# an encrypted member and (NotImplementedError) an unknown compression method,
# LZMAError a damaged LZMA member, MemoryError a header that declares a huge shape;
# numpy parses the .npy header as a Python literal, which adds TokenError,
# SyntaxError, TypeError (e.g. an unhashable key) and RecursionError.
_ARCHIVE_ERRORS = (
    OSError,
    ValueError,
    EOFError,
    KeyError,
    zipfile.BadZipFile,
    zlib.error,
    RuntimeError,
    lzma.LZMAError,
    MemoryError,
    tokenize.TokenError,
    SyntaxError,
    TypeError,
    RecursionError,
)

# How a zip archive (empty or not) and a single .npy array start.
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
_NPY_MAGIC = b"\x93NUMPY"


def _read_npz(path: str | os.PathLike, allow_gaps: bool) -> Run:
    """Read an NPZ run log; pickled content is never loaded."""
    name = str(path)
    _require_file(path)
    arrays = _load_npz_arrays(path, name)
    meta = _parse_npz_meta(arrays.pop("meta"), name)
    n = arrays["time_s"].shape[0] if arrays["time_s"].ndim >= 1 else 0
    for array_name, array in arrays.items():
        _check_array_shape(array, array_name, n, f"{name}, array '{array_name}'")
    with np.errstate(over="ignore"):  # e.g. longdouble beyond float64: inf, refused below
        as_float = {k: np.ascontiguousarray(v, dtype=np.float64) for k, v in arrays.items()}
    run = Run(
        time_s=as_float["time_s"],
        dtheta_rad=as_float["dtheta_rad"],
        dv_mps=as_float["dv_mps"],
        meta=meta,
        gimbal_deg=as_float.get("gimbal_deg"),
        source=name,
    )
    locate = _ArrayLocator(name)
    _check_meta(meta, locate)
    return replace(run, clock=_check_samples(run, locate, allow_gaps))


def _load_npz_arrays(path: str | os.PathLike, name: str) -> dict[str, np.ndarray]:
    """The run's arrays from an NPZ archive, refusing damaged, foreign or pickled content."""
    fix = "write the file again with numpy.savez, or use the CSV format"
    # Open the file ourselves: np.load leaks its handle when the zip is damaged.
    try:
        handle = open(path, "rb")
    except OSError as exc:
        raise CalibError(
            f"cannot read the file: {exc.strerror or exc}", name, "check the path and permissions"
        ) from None
    with handle:
        try:
            head = handle.read(len(_NPY_MAGIC))
            handle.seek(0)
        except OSError as exc:
            raise CalibError(
                f"cannot read the file: {exc.strerror or exc}", name, "check the path and permissions"
            ) from None
        if not head:
            raise CalibError("not a readable NPZ archive: the file is empty", name, fix)
        if not head.startswith(_ZIP_MAGIC) and not head.startswith(_NPY_MAGIC):
            raise CalibError(
                "not a readable NPZ archive: the file does not start with a zip signature", name, fix
            )
        try:
            archive = np.load(handle, allow_pickle=False)
        except _ARCHIVE_ERRORS as exc:
            raise CalibError(f"not a readable NPZ archive: {exc}", name, fix) from None
        if not isinstance(archive, np.lib.npyio.NpzFile):
            raise CalibError("the file is a single .npy array, not an NPZ archive", name, fix)
        with archive:
            present = set(archive.files)
            missing = [a for a in (*_NPZ_ARRAYS, "meta") if a not in present]
            if missing:
                raise CalibError(
                    f"archive lacks array{'s' if len(missing) > 1 else ''} "
                    f"{', '.join(repr(m) for m in missing)}",
                    name,
                    "store time_s, dtheta_rad, dv_mps and meta (see docs/formats.md)",
                )
            arrays = {}
            for a in (*_NPZ_ARRAYS, "gimbal_deg", "meta"):
                if a not in present:
                    continue
                try:
                    arrays[a] = archive[a]
                except _ARCHIVE_ERRORS as exc:
                    raise CalibError(
                        f"cannot read the archive member: {exc}", f"{name}, array '{a}'", fix
                    ) from None
    for a, array in arrays.items():
        # numpy hands back the raw bytes of a member that is not in .npy format.
        if not isinstance(array, np.ndarray):
            raise CalibError(
                f"archive member '{a}.npy' is not a numpy array (.npy format)", f"{name}, array '{a}'", fix
            )
    return arrays


def _parse_npz_meta(array: np.ndarray, name: str) -> dict[str, str]:
    """Decode the ``meta`` array: one JSON object of string (or number) values."""
    where = f"{name}, array 'meta'"
    fix = "store meta as a JSON object string, e.g. json.dumps(run.meta)"
    if array.size != 1 or array.dtype.kind not in "US":
        raise CalibError(
            f"meta is a {array.dtype} array of shape {array.shape}, not one JSON string", where, fix
        )
    text = array.reshape(()).item()
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError:
            raise CalibError("meta is not valid UTF-8", where, fix) from None
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CalibError(
            f"meta is not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})", where, fix
        ) from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise CalibError(f"meta is not valid JSON ({str(exc).split(';')[0]})", where, fix) from None
    except RecursionError:
        raise CalibError("meta is not valid JSON (nested too deeply)", where, fix) from None
    if not isinstance(raw, dict):
        raise CalibError(f"meta is a JSON {type(raw).__name__}, not an object", where, fix)
    meta: dict[str, str] = {}
    for key, value in raw.items():
        if isinstance(value, str):
            meta[key] = value
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            # Other programs may store numbers as numbers; keep them exactly.
            meta[key] = repr(value)
        else:
            raise CalibError(
                f"meta value {value!r} is neither a string nor a number", f"{name}, meta key '{key}'", fix
            )
    return meta


def _format_npz(run: Run) -> bytes:
    """The bytes of an uncompressed NPZ archive of the run."""
    arrays = {
        "time_s": np.asarray(run.time_s, dtype=np.float64),
        "dtheta_rad": np.asarray(run.dtheta_rad, dtype=np.float64),
        "dv_mps": np.asarray(run.dv_mps, dtype=np.float64),
        "meta": np.array(json.dumps(run.meta, ensure_ascii=False)),
    }
    if run.gimbal_deg is not None:
        arrays["gimbal_deg"] = np.asarray(run.gimbal_deg, dtype=np.float64)
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()
