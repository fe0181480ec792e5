"""Two streams on two clocks: the accelerometer's increments carried onto the gyro's samples.

Some loggers write the gyro and the accelerometer apart, each at its own rate
and with its own stamps (a phone, a camera's IMU, a driver publishing two
topics). The run format holds one clock, so one stream is carried onto the
other's. The gyro's is kept: its increments are what the moves integrate, and
any resampling of them would bend the turns. The accelerometer's matter at the
rests, where they are averaged.

Each accelerometer sample is the velocity increment over its interval
``(t_i - T_a, t_i]``, so its running sum ``V(t)`` is known at every sample end
and is linear in between for a specific force held over each interval (what
an averaging output filter gives). The increment over a gyro interval
``(tau_k - T_g, tau_k]`` is then ``V(tau_k) - V(tau_k - T_g)``, with ``V``
interpolated linearly: the sum over any stretch is the accelerometer's own
integral there, exactly, so a rest's mean specific force is unchanged; only
the sample-to-sample shape inside an accelerometer interval is assumed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError

from . import clock
from .checks import check_samples
from .clipping import clip_mask
from .polled import own_intervals
from .run import Run

SENSORS = {"accel": "accelerometer", "gyro": "gyro"}


@dataclass(frozen=True)
class Stream:
    """One sensor's file: its stamps, values in SI and clipped samples, and where each row is.

    Attributes
    ----------
    name : str
        The file.
    stamps_s : ndarray, shape (n,)
        Each row's time stamp, s.
    lines : ndarray of int, shape (n,)
        Each row's line in the file (1-based), for messages.
    values : ndarray, shape (n, 3)
        Rates (rad/s) or specific force (m/s^2).
    clipped : ndarray of bool, shape (n, 3)
        Samples at the sensor's range.
    columns : tuple of str
        The file's own names of its time and three axes, for messages (imu_tk's ``t x y z``).
    """

    name: str
    stamps_s: np.ndarray
    lines: np.ndarray
    values: np.ndarray
    clipped: np.ndarray
    columns: tuple[str, str, str, str] = ("t", "x", "y", "z")


class _OneFile:
    """Names places in one stream's file for the clock's checks."""

    def __init__(self, stream: Stream):
        self.stream = stream

    def key(self, key: str) -> str:
        return f"{self.stream.name} (metadata '{key}')"

    def sample(self, array: str, index: int, component: int | None = None) -> str:
        column = self.stream.columns[0 if component is None else 1 + component]
        return f"{self.stream.name}, line {int(self.stream.lines[index])}, column {column} (sample {index})"


def on_own_clock(stream: Stream, sensor: str, meta: dict, allow_gaps: bool) -> tuple[Run, clock.SampleClock]:
    """One stream as a run on its own uniform clock (jitter measured, gaps refused or filled).

    ``sensor`` is ``"gyro"`` or ``"accel"``; the other sensor's increments are zero.
    ``meta["sample_rate_hz"]`` is this stream's rate. Returns the run and its clock.
    """
    period: float | np.ndarray = 1.0 / float(meta["sample_rate_hz"])
    if clock.sampled_at_stamps(np.asarray(stream.stamps_s, dtype=float), float(meta["sample_rate_hz"])):
        period = own_intervals(np.asarray(stream.stamps_s, dtype=float))
    increments = stream.values * period
    zeros = np.zeros_like(increments)
    gyro, accel = (increments, zeros) if sensor == "gyro" else (zeros, increments)
    gyro_clipped, accel_clipped = (stream.clipped, None) if sensor == "gyro" else (None, stream.clipped)
    run = Run(np.asarray(stream.stamps_s, dtype=float), gyro, accel, dict(meta), source=stream.name)
    run.clipped = clip_mask(gyro_clipped, accel_clipped, len(increments))
    run.clock = check_samples(run, _OneFile(stream), allow_gaps, "time_s")
    settled = clock.settle(run, allow_gaps)
    return settled, run.clock


def two_clocks(accel: Stream, gyro: Stream, meta: dict, allow_gaps: bool) -> Run:
    """The two streams as one run on the gyro's clock (module docstring).

    Parameters
    ----------
    accel, gyro : Stream
    meta : dict
        The run's metadata; ``sample_rate_hz`` is the gyro's (the accelerometer's comes from
        its own stamps). A ``streams`` entry saying what was done is added.
    allow_gaps : bool
        Fill samples either stream lost at rest (`calib.runlog.clock.settle`).

    Returns
    -------
    Run
        Over the gyro samples whose intervals the accelerometer covers; ``clock`` is the gyro's.

    Raises
    ------
    CalibError
        When the two files do not overlap in time, or either stream's clock is refused.
    """
    g, g_clock = on_own_clock(gyro, "gyro", meta, allow_gaps)
    accel_rate = clock.stamps_rate(np.asarray(accel.stamps_s, dtype=float))
    a, a_clock = on_own_clock(accel, "accel", meta | {"sample_rate_hz": repr(accel_rate)}, allow_gaps)
    a_period = 1.0 / accel_rate
    # On the gyro's time base (epoch stamps are re-based to each stream's first; the origins' difference
    # is taken once, so the times keep their resolution).
    a_end, g_end = a.time_s + (a_clock.origin_s - g_clock.origin_s), g.time_s
    keep = inside(a_end, a_period, g_end)
    if keep.sum() < 2:
        raise CalibError(
            f"the accelerometer's stamps ({a_end[0]:.6g}-{a_end[-1]:.6g} s) and the gyro's "
            f"({g_end[0]:.6g}-{g_end[-1]:.6g} s) do not overlap",
            f"{accel.name}; {gyro.name}",
            "give the two files of one recording, stamped on one clock",
        )
    first, last = np.flatnonzero(keep)[[0, -1]]
    sel = slice(int(first), int(last) + 1)
    dv = carry_onto(a_end, a.dv_mps, a_period, g_end[sel])
    clipped = g.clipped[sel] if g.clipped is not None else np.zeros((last - first + 1, 6), dtype=bool)
    if a.clipped is not None:  # a gyro sample overlapping a clipped accelerometer sample is clipped
        share = carry_onto(a_end, a.clipped[:, 3:].astype(float), a_period, g_end[sel])
        clipped = clipped.copy()
        clipped[:, 3:] |= share > 0.0
    g_period = float(g_end[-1] - g_end[0]) / (len(g_end) - 1)  # the mean step: stamps may jitter
    left_out = (first + len(g_end) - 1 - last) * g_period
    note = (
        f"two clocks: the accelerometer's {len(a_end)} samples at {accel_rate:.6g} Hz carried onto the "
        f"gyro's at {1.0 / g_period:.6g} Hz by the integral of the specific force (docs/logs-columns.md)"
        + (f"; {left_out:.3g} s of the gyro's outside the accelerometer's span left out" if left_out else "")
        + "; accelerometer "
        + a_clock.summary().removeprefix("clock: ")
        + (
            "; gyro " + g_clock.summary().removeprefix("clock: ")
            if g_clock.dropped or g_clock.duplicates
            else ""
        )
    )
    run = Run(
        g.time_s[sel],
        g.dtheta_rad[sel],
        dv,
        dict(meta) | {"streams": note},
        source=accel.name,
    )
    run.clipped = clipped if clipped.any() else None
    run.clock = dataclasses.replace(
        g_clock, index=np.arange(len(run.time_s), dtype=np.int64), dropped=[], duplicates=[]
    )
    return run


def carry_onto(
    source_end_s: np.ndarray, increments: np.ndarray, source_period_s: float, target_end_s: np.ndarray
) -> np.ndarray:
    """A stream's increments over other sample intervals, from its running sum.

    Parameters
    ----------
    source_end_s : ndarray, shape (n,)
        End of each source sample's interval, s, on a uniform time base (increasing).
    increments : ndarray, shape (n, 3)
        The source's increment over each interval.
    source_period_s : float
        The source's period (its first interval starts one period before its first end).
    target_end_s : ndarray, shape (m,)
        End of each target interval, s; interval ``k`` starts at ``target_end_s[k - 1]`` (the
        first one period of the target before, taken as ``target_end_s[1] - target_end_s[0]``).
        Every interval must lie within the source's span (:func:`inside`).

    Returns
    -------
    ndarray, shape (m, 3)
        The increments over the target intervals.
    """
    ends = np.concatenate([[source_end_s[0] - source_period_s], source_end_s])
    running = np.vstack([np.zeros((1, 3)), np.cumsum(increments, axis=0)])
    step = float(target_end_s[1] - target_end_s[0]) if len(target_end_s) > 1 else source_period_s
    edges = np.concatenate([[target_end_s[0] - step], target_end_s])
    at_edges = np.column_stack([np.interp(edges, ends, running[:, j]) for j in range(3)])
    return np.diff(at_edges, axis=0)


COVER_SLACK = 1e-3  # of a period uncovered at a span's end: a thousandth of one sample's increment


def inside(source_end_s: np.ndarray, source_period_s: float, target_end_s: np.ndarray) -> np.ndarray:
    """Which target intervals (one target period each, ending at ``target_end_s``) the source covers.

    The source's span is ``[source_end_s[0] - source_period_s, source_end_s[-1]]``, to
    ``COVER_SLACK`` of a target period: two files of one logger on the same stamps, each put on
    its own fitted clock, end a few ns apart (their rates differ in the 12th digit), and the
    first and last samples were left out for it.
    """
    step = float(target_end_s[1] - target_end_s[0]) if len(target_end_s) > 1 else 0.0
    first = float(source_end_s[0]) - source_period_s
    return (target_end_s - step >= first - COVER_SLACK * step) & (
        target_end_s <= float(source_end_s[-1]) + COVER_SLACK * step
    )
