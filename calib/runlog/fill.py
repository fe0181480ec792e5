"""Samples a logger lost at rest, put back as the mean increment of their neighbours.

A sample lost while the IMU is still holds the Earth rate and gravity seen through the
IMU's errors, plus white noise: the mean of its neighbours stands for it up to one
sample's noise. One lost while the IMU turns cannot be known: refused, or for a fit
that can leave its move out (a hand fit), put in as a marked guess.

At rest is judged two ways, either enough: by absolute rates (a calibration-grade unit,
whose bias is far below a flip's rate), or relative to the recording's own quietest
stretches (a MEMS unit, whose bias alone can be degrees per second): no row near the
hole strays from the others by more than a few times the noise the log shows when still.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.errors import CalibError
from calib.nav.strapdown import sample_intervals

# Samples each side of a lost one whose mean increment fills it (at rest).
FILL_NEIGHBOURS = 100
# The longest hole filled: beyond this the fill would be mostly invented, not measured.
MAX_FILL = 2 * FILL_NEIGHBOURS
# A neighbourhood is at rest when its mean rate is below this: 14x the Earth rate,
# far above any calibration-grade gyro bias, far below a flip (rad/s).
REST_RATE = 1e-3
# No single neighbour may turn faster than this: a flip (0.57 deg/s; the estimator's threshold).
TURN_RATE = 1e-2
# Around a polling loop's stall (a hand run's MEMS unit: per-sample noise to 0.03 rad/s, bias to
# 0.005 rad/s) no row may turn faster than this (5.7 deg/s).
STALL_REST_RATE = 0.1
# The relative rule. Rows each side of a hole judged and averaged: a quarter second, short
# against a hand's pose (1-6 s) so that a turn's settling a second away is not in it.
QUIET_WINDOW_S = 0.25
QUIET_MIN_ROWS = 10
# The noise the log shows when still: per axis, this percentile of the standard deviations
# of its quarter-second blocks (a hand recording is still a good part of its time).
QUIET_PERCENTILE = 10
# No row near a hole strays from the rows' mean by more than this times that noise. The
# tenth percentile of a 25-row standard deviation is about 0.8 sigma, so this is about 5 sigma:
# beyond the largest of some fifty rows of white noise (4 sigma one time in a thousand), below
# a hand's settling (tens of times the noise).
QUIET_PEAK = 6.0


def fill_dropped(
    index: np.ndarray,
    time_of: tuple[float, float],
    dtheta: np.ndarray,
    dv: np.ndarray,
    gimbal: np.ndarray | None = None,
    guess_turns: bool = False,
):
    """Put each lost sample back, at rest, as the mean increment of its neighbours.

    At rest the increments are the Earth rate and gravity seen through the
    IMU errors plus white noise; the mean of ``FILL_NEIGHBOURS`` samples each
    side is the lost increment up to one sample's noise, so the navigation
    error a filled sample adds is that of the noise the IMU would have added.
    A sample lost while the IMU turns cannot be known and is refused (or, with
    ``guess_turns``, put in as the straight line between its neighbours and
    marked, for a fit that leaves its move out), as is a hole longer than
    ``MAX_FILL`` samples.

    Parameters
    ----------
    index : numpy.ndarray
        ``(n,)`` sample count of each row present (a `SampleClock`'s, duplicates
        already removed: increasing).
    time_of : (float, float)
        The clock's offset and period, s: sample ``k`` ends at ``offset + k * period``.
    dtheta, dv : numpy.ndarray
        ``(n, 3)`` increments of the rows that are present.
    gimbal : numpy.ndarray, optional
        ``(n, 3)`` encoder angles: the lost rows repeat the previous one.
    guess_turns : bool
        Put a hole amid a turn in as a guess instead of refusing it.

    Returns
    -------
    dtheta, dv, gimbal, index : numpy.ndarray
        Full arrays over ``index[0] .. index[-1]`` and that index.
    guessed : numpy.ndarray or None
        ``(len(index),)`` bool: the samples put in amid a turn (None when none is).

    Raises
    ------
    CalibError
        For a hole whose neighbourhood is not at rest (``where`` is the time).
    """
    full = np.arange(index[0], index[-1] + 1)
    pos = index - index[0]
    out_th = np.full((len(full), 3), np.nan)
    out_dv = np.full((len(full), 3), np.nan)
    out_th[pos], out_dv[pos] = dtheta, dv
    judge = _HoleJudge(index, time_of, dtheta, dv)
    guessed = np.zeros(len(full), dtype=bool)
    for row in np.flatnonzero(np.diff(index) > 1):
        _check_too_long(index, time_of, row)
        lo, hi, stray = judge.neighbours(row)
        hole = slice(pos[row] + 1, pos[row + 1])
        if stray > QUIET_PEAK and guess_turns:
            # No measurement: a line between the rows either side keeps the arrays whole for a
            # fit that leaves this stretch out (a hand fit's move), marked so that it does.
            share = np.linspace(0.0, 1.0, hole.stop - hole.start + 2)[1:-1, None]
            out_th[hole] = (1 - share) * dtheta[row] + share * dtheta[row + 1]
            out_dv[hole] = (1 - share) * dv[row] + share * dv[row + 1]
            guessed[hole] = True
            continue
        if stray > QUIET_PEAK:
            _refuse_turning(
                index,
                time_of,
                row,
                f"; within {QUIET_WINDOW_S:g} s of it the rows stray "
                f"{stray:.3g} times the noise the log shows when still",
            )
        out_th[hole] = dtheta[lo:hi].mean(axis=0)
        out_dv[hole] = dv[lo:hi].mean(axis=0)
    out_g = None
    if gimbal is not None:
        filled = np.zeros(len(full), dtype=np.int64)
        filled[pos] = 1
        out_g = np.asarray(gimbal)[np.cumsum(filled) - 1]
    return out_th, out_dv, out_g, full, (guessed if guessed.any() else None)


def _resolution(x: np.ndarray) -> np.ndarray:
    """Per axis, the smallest step a quantised channel takes (its 1st percentile of the non-zero
    changes from row to row; 0 for a channel that never changes). A channel still to its last
    digit has no spread; its quantisation's, step / sqrt(12), stands for its noise, so that a
    one-step tick near a hole is no turn.
    """
    out = np.zeros(x.shape[1])
    for axis in range(x.shape[1]):
        steps = np.abs(np.diff(x[:, axis]))
        steps = steps[steps > 0.0]
        out[axis] = np.percentile(steps, 1.0) if steps.size else 0.0
    return out


class _HoleJudge:
    """Whether the IMU is still around each hole, and the rows that stand for it."""

    def __init__(self, index: np.ndarray, time_of: tuple[float, float], dtheta: np.ndarray, dv: np.ndarray):
        self.index, self.period, self.dtheta, self.dv = index, time_of[1], dtheta, dv
        self.quiet: QuietNoise | None = None  # measured once, where the rate rule fails

    def neighbours(self, row: int | np.integer) -> tuple[int, int, float]:
        """The rows standing for the hole after ``row`` and how far they stray (0: still by rate)."""
        n = len(self.index)
        lo, hi = max(0, int(row) + 1 - FILL_NEIGHBOURS), min(n, int(row) + 1 + FILL_NEIGHBOURS)
        if _still_by_rate(self.dtheta[lo:hi], self.period):
            return lo, hi, 0.0
        # A MEMS unit's bias alone fails the absolute rule: judged against its own noise, on
        # the nearest rows only (a hand's pose is short), and filled from those.
        self.quiet = self.quiet or QuietNoise.of(self.dtheta, self.dv, self.period)
        lo, hi = self.quiet.near(row, n)
        return lo, hi, self.quiet.stray(self.dtheta[lo:hi], self.dv[lo:hi])


def holes_at_rest(
    index: np.ndarray, time_of: tuple[float, float], dtheta: np.ndarray, dv: np.ndarray
) -> list[str]:
    """For each hole in ``index`` (in order), what `fill_dropped` makes of it: ``"still"`` (filled),
    ``"turning"`` or ``"long"`` (more than `MAX_FILL` samples: refused either way).
    """
    judge = _HoleJudge(index, time_of, dtheta, dv)
    out = []
    for row in np.flatnonzero(np.diff(index) > 1):
        if index[row + 1] - index[row] - 1 > MAX_FILL:
            out.append("long")
        else:
            out.append("still" if judge.neighbours(row)[2] <= QUIET_PEAK else "turning")
    return out


def _lost_at(index: np.ndarray, time_of: tuple[float, float], row: int | np.integer) -> tuple[int, float]:
    """How many samples are lost after ``row`` and the time of the first, s."""
    offset, period = time_of
    return int(index[row + 1] - index[row] - 1), offset + (index[row] + 1) * period


def _check_too_long(index: np.ndarray, time_of: tuple[float, float], row: int | np.integer) -> None:
    """Refuse a hole after ``row`` longer than the neighbours can stand for."""
    lost, t = _lost_at(index, time_of, row)
    if lost > MAX_FILL:
        raise CalibError(
            f"{lost} samples lost at t = {t:.6g} s, more than the "
            f"{MAX_FILL} that the {FILL_NEIGHBOURS} samples each side can "
            "stand for",
            f"t = {t:.6g} s",
            "split the log at the hole and calibrate each part",
        )


def _still_by_rate(neighbours: np.ndarray, period: float) -> bool:
    """The absolute rule: the neighbours' mean rate and every one's below a flip's."""
    rate = np.linalg.norm(neighbours.mean(axis=0)) / period
    peak = np.max(np.linalg.norm(neighbours, axis=1)) / period
    return bool(rate <= REST_RATE and peak <= TURN_RATE)


def _refuse_turning(index: np.ndarray, time_of: tuple[float, float], row: int | np.integer, why: str) -> None:
    lost, t = _lost_at(index, time_of, row)
    raise CalibError(
        f"{lost} sample(s) lost at t = {t:.6g} s, while the IMU turns{why}",
        f"t = {t:.6g} s",
        "the increments of a turn cannot be recovered; repair the log or record the run again",
    )


@dataclass(frozen=True)
class QuietNoise:
    """The noise a log shows when still, per axis of each triad, and the rows it judges by.

    Attributes
    ----------
    gyro, accel : numpy.ndarray
        ``(3,)`` the `QUIET_PERCENTILE` of the standard deviation of the increments over
        blocks of ``rows`` rows (the log's own units, per row).
    rows : int
        Rows each side of a hole that are judged (`QUIET_WINDOW_S`).
    """

    gyro: np.ndarray
    accel: np.ndarray
    rows: int

    @classmethod
    def of(cls, dtheta: np.ndarray, dv: np.ndarray, period: float) -> QuietNoise:
        rows = max(QUIET_MIN_ROWS, int(round(QUIET_WINDOW_S / period)))
        blocks = max(1, len(dtheta) // rows)

        def level(x: np.ndarray) -> np.ndarray:
            spread = x[: blocks * rows].reshape(blocks, -1, 3).std(axis=1)
            return np.maximum(np.percentile(spread, QUIET_PERCENTILE, axis=0), _resolution(x) / np.sqrt(12.0))

        return cls(level(dtheta), level(dv), rows)

    def near(self, row: int | np.integer, n: int) -> tuple[int, int]:
        """The rows judged for a hole after ``row`` (of ``n``): ``rows`` each side."""
        return max(0, int(row) + 1 - self.rows), min(n, int(row) + 1 + self.rows)

    def stray(self, dtheta: np.ndarray, dv: np.ndarray) -> float:
        """The largest deviation of any row from the rows' mean, in units of the quiet noise.

        A channel that never changes at all has no noise to judge by: any change there is
        a stray, said as 1e6 (no inf in a message).
        """
        worst = 0.0
        for x, noise in ((dtheta, self.gyro), (dv, self.accel)):
            dev = np.max(np.abs(x - x.mean(axis=0)), axis=0)
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(dev > 0.0, np.minimum(dev / noise, 1e6), 0.0)
            worst = max(worst, float(np.max(ratio)))
        return worst


def check_stalls_at_rest(
    dtheta: np.ndarray, time_s: np.ndarray, stalls_s: list, guess_turns: bool = False
) -> np.ndarray | None:
    """Refuse a polling loop's stall (:func:`calib.runlog.polled.stalls`) while the IMU turns.

    The row after a stall holds one reading over the whole hole: at rest that is the hole's
    increment to its noise; while turning the rate changed unseen. At rest means no row of
    the ``FILL_NEIGHBOURS`` each side turns faster than ``STALL_REST_RATE`` (a MEMS unit's
    noise and bias stay below it; a hand's turn passes it within its first rows).
    ``time_s``: the rows' own ends, s. With ``guess_turns`` a stall amid a turn is not
    refused: its row is returned marked (``(n,)`` bool, None if none), as a sample
    :func:`fill_dropped` guesses is, so that a hand fit leaves its move out.
    """
    dt = sample_intervals(time_s)
    guessed = np.zeros(len(time_s), dtype=bool)
    for start in stalls_s:
        row = int(np.searchsorted(time_s, start))
        lo, hi = max(0, row - FILL_NEIGHBOURS), min(len(time_s), row + 1 + FILL_NEIGHBOURS)
        near = np.r_[lo:row, row + 1 : hi]  # the stall's own row is the one in doubt
        peak = np.max(np.linalg.norm(dtheta[near], axis=1) / dt[near])
        if peak <= STALL_REST_RATE:
            continue
        if guess_turns:
            guessed[row] = True
            continue
        raise CalibError(
            f"the logger stalled for {1e3 * dt[row]:.3g} ms at t = {start:.6g} s, while the IMU turns",
            f"t = {start:.6g} s",
            "a turn's rate over a stall cannot be recovered; log without stalls (a polling loop "
            "that writes to a card blocks) or record the run again; by hand, allow_gaps with "
            "guess_turns (the CLI's --allow-gaps, by hand) leaves its move out",
        )
    return guessed if guessed.any() else None
