"""The run-log checks: metadata, array shapes, finite samples and the time column.

Both readers and `check_run` apply them, so a run that loads from one format
loads from the other, and the tool never writes a file it would refuse to read.
"""

from __future__ import annotations

import numpy as np

from calib.errors import CalibError
from calib.nav.earth import HEIGHT_RANGE_M  # one source: the site limits of calib.nav.earth

from . import clock, coarse
from .columns import time_unit_suspect
from .fill import holes_at_rest
from .format import ARRAY_COLUMNS, FORMAT, REQUIRED_META
from .polled import interleaved
from .run import Run, meta_float
from .wallclock import SPLIT_FIX, split_stamp_suspect

GAP_PERIODS = 2.0  # the typical time step must lie within [0.5, 2] nominal periods


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
    for array_name in ARRAY_COLUMNS:
        array = getattr(run, array_name)
        if array is not None:
            check_array_shape(np.asarray(array), array_name, n, f"{name}, array '{array_name}'")
    locate = ArrayLocator(name)
    check_meta(run.meta, locate)
    check_samples(run, locate, allow_gaps)


class ArrayLocator:
    """Names places in an NPZ file or in-memory run: array elements and meta keys."""

    def __init__(self, name: str):
        self.name = name

    def key(self, key: str) -> str:
        return f"{self.name}, meta key '{key}'"

    def sample(self, array: str, index: int, component: int | None = None) -> str:
        element = f"{index}" if component is None else f"{index}, {component}"
        return f"{self.name}, {array}[{element}]"


def check_meta(meta: dict[str, str], locate) -> None:
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
    values = {key: meta_float(meta, key, locate.key(key)) for key in REQUIRED_META[1:]}
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
        gravity = meta_float(meta, "gravity_mps2", locate.key("gravity_mps2"))
        if gravity <= 0.0:
            raise CalibError(
                f"gravity_mps2 = {gravity} is not positive",
                locate.key("gravity_mps2"),
                "give the measured gravity in m/s^2, or leave the key out",
            )


def check_array_shape(array: np.ndarray, name: str, n: int, where: str) -> None:
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


# Holes judged still or turning for the refusal: a log with more is mis-read (a rate, a unit) or
# broken, and what each one is tells the user nothing.
HOLES_JUDGED = 20


def check_samples(run: Run, locate, allow_gaps: bool, time_name: str | None = None) -> clock.SampleClock:
    """Refuse too few samples, non-finite values, non-increasing time and (unless allowed) gaps.

    ``time_name`` is the name a CSV's time column was read as (``time_ms``...),
    None for arrays. Returns the sample clock of the time column
    (:func:`calib.runlog.clock.sample_clock`).
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
    duplicate = coarse.duplicate_rows(time, np.asarray(run.dtheta_rad), np.asarray(run.dv_mps), period)
    # Equal stamps with other data may be a host that read two samples at once: the clock's
    # count rule places them, or refuses them where the stamps never make room for the extra row.
    half = split_stamp_suspect(time) if time_name is not None else None
    if half is not None:
        raise CalibError(
            half + ": part of a stamp, too coarse to time the samples", locate.sample("time_s", 1), SPLIT_FIX
        )
    backwards = np.flatnonzero((step < 0.0) & ~duplicate[1:])
    if backwards.size:
        i = int(backwards[0]) + 1
        raise CalibError(
            f"time goes backwards: time_s = {float(time[i])!r} follows "
            f"{float(time[i - 1])!r}"
            + (f" ({backwards.size} such steps in all)" if backwards.size > 1 else ""),
            locate.sample("time_s", i),
            "samples must be in time order without repeats; sort the log or remove duplicates",
        )
    mixed = interleaved(time, np.asarray(run.dv_mps))
    if mixed is not None:
        m, every = mixed
        raise CalibError(
            f"the rows look like {m} IMUs' samples interleaved: the stamps keep a {1e3 * every:.4g} ms "
            f"period every {m} rows but step by {1e3 * float(step.min()):.3g}-{1e3 * float(step.max()):.3g}"
            " ms from row to row, and gravity's direction jumps from row to row (another unit's mounting)",
            locate.sample("time_s", 1),
            "keep one IMU's rows (one value of the log's instance column, such as ArduPilot's I) and "
            "calibrate each IMU on its own",
        )
    # The nominal period must describe the time stamps (gaps and jitter aside), or
    # gap detection, durations and the first sample's interval are all wrong.
    typical = float(np.median(step))
    if not 0.5 * period <= typical <= GAP_PERIODS * period:
        file_name = getattr(locate, "columns", {}).get("time_s", (None,))[0] if time_name else None
        suspect = time_unit_suspect(typical, time_name, n, run.sample_rate_hz, file_name)
        if suspect is not None:  # the rate is right and the time column's unit is not its name's
            raise CalibError(suspect.what, locate.sample("time_s", 1), suspect.fix)
        raise CalibError(
            f"sample_rate_hz = {run.sample_rate_hz:g} (a period of {period:g} s) does not match "
            f"the time stamps, which are typically {typical:.6g} s apart",
            locate.key("sample_rate_hz"),
            "give the IMU output rate in Hz, the inverse of the time between samples",
        )
    try:
        found = clock.sample_clock(time, run.sample_rate_hz, duplicate)
    except CalibError as exc:
        assert exc.where is not None  # sample_clock names the row of each refusal
        raise CalibError(exc.what, locate.sample("time_s", int(exc.where)), exc.fix) from None
    if not allow_gaps and (found.dropped or found.duplicates):
        jumps = np.flatnonzero(np.diff(found.index) != 1)
        if jumps.size:
            first = int(jumps[0]) + 1
        else:  # sampled at its stamps: a stall is a long step, not a jump of the count
            first = int(np.searchsorted(time - found.origin_s, found.dropped[0][0]))
        at_rest = None
        if 0 < len(found.dropped) <= HOLES_JUDGED and found.rule != "stamps":
            keep = ~duplicate
            at_rest = holes_at_rest(
                found.index[keep], (found.offset_s, period), run.dtheta_rad[keep], run.dv_mps[keep]
            )
        raise clock.refusal(found, locate.sample("time_s", first), at_rest)
    return found


def _check_finite(run: Run, locate) -> None:
    """Refuse NaN or infinity anywhere, naming the earliest sample that has one."""
    first: tuple[int, str, int | None] | None = None
    for name in ARRAY_COLUMNS:
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
