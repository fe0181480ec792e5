"""What limits the gyro's out-of-sample score (issue 37): the held-out third's floor, split by split.

For every split of :mod:`by_hand_cv` (same fits, same held-out rests), beside the pose-to-pose
RMS of ours and of imu_tk's method:

* **floor**: what the held-out rests alone leave, whatever the calibration: each rest's mean
  specific force errs by its own noise (per axis, the variance of the mean by batch means over
  blocks of the rest finder's window, at least the white ``var / n``), which tilts the measured
  gravity direction by ``sigma / g`` on two axes at each end of a move:
  ``floor^2 = 2 (v_r + v_r+1) / g^2``, RMS over the used moves;
* **above floor**: each tool's RMS less the floor in quadrature, and their ratio;
* **turning moves**: the ratio over the moves the calibrated gyro turns through at least 1 deg
  (a rest split in two inside one pose gives a "move" that turns by a tremor; its error is the
  floor's, the same for every tool);
* **ours, whole recording**: our fit of the whole recording (it saw the held-out third) scored on
  the same rests, over imu_tk's method out of sample: what a better estimate of the 21 from the
  fitting part could reach at best;
* **ours, predicted**: the RMS change of the predicted gravity directions when our 21 are drawn
  from their covariance (times chi2/dof when above 1; 30 draws, seed 0): our own sigma on the score.

    PYTHONPATH=. .venv/bin/python benchmarks/by_hand_cv_floor.py

Reads the recordings copied into tests/data/realdata (or REALDATA=<folder>); about 40 s.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from by_hand import DATA, rests_of, scored, xsens
from by_hand_cv import imutk_on, mikoff, ours_on, slice_run

from calib.calibration.correction import correction_from_parameters
from calib.hand.moves import move_rotation
from calib.hand.rests import WINDOW_S
from calib.nav.strapdown import sample_intervals
from calib.peers.scores import rest_means

TURNING_DEG = 1.0  # a move the gyro turns through less than this is a rest split inside one pose
DRAWS = 30


def mean_variance(x: np.ndarray, block: int) -> float:
    """Per-axis variance of the mean of ``(n, 3)`` ``x``: batch means over ``block`` samples, >= white."""
    n = len(x)
    white = float(x.var(axis=0, ddof=1).mean()) / n
    k = n // block
    if k < 2:
        return white
    means = x[: k * block].reshape(k, block, 3).mean(axis=1)
    return max(float(means.var(axis=0, ddof=1).mean()) / k, white)


def rms(x: np.ndarray) -> float:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else math.nan


def above(x: float, floor: float) -> float:
    return math.sqrt(max(x * x - floor * floor, 0.0))


def predicted_directions(c, rec, start, end, dt) -> np.ndarray:
    """Each used move's predicted minus measured gravity direction (cross product), ``(K - 1, 3)``."""
    rate, force = c.apply(rec.raw_gyro, rec.raw_accel)
    up = rest_means(force, start, end)
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    dth = rate * dt[:, None]
    out = []
    for r in range(len(start) - 1):
        a, b = int(end[r]), int(start[r + 1])
        R, _, _ = move_rotation(dth[a:b], dth[a - 1])
        out.append(np.cross(R.T @ up[r], up[r + 1]))
    return np.array(out)


def our_sigma_on_score(res, rec, start, end, dt, used) -> float:
    """RMS (deg) of the change of the predicted directions over draws of our 21 from their covariance."""
    cov = np.asarray(res.covariance)[:21, :21] * max(1.0, res.chi2_per_dof)
    values = np.asarray(res.values, dtype=float)
    zero = np.zeros((21, 21))

    def corr(v):
        return correction_from_parameters(v, zero, None, None, rec.gyro_conversion, rec.accel_conversion)

    e0 = predicted_directions(corr(values), rec, start, end, dt)[used]
    rng = np.random.default_rng(0)
    L = np.linalg.cholesky(cov + 1e-30 * np.eye(21))
    d = [
        np.linalg.norm(
            predicted_directions(corr(values + L @ rng.standard_normal(21)), rec, start, end, dt)[used] - e0,
            axis=1,
        )
        for _ in range(DRAWS)
    ]
    return math.degrees(float(np.sqrt(np.mean(np.square(d)))))


def rows_of(rec) -> list[str]:
    rests = rests_of(rec)
    t = rec.run.time_s
    dt = sample_intervals(t)
    block = max(3, int(round(WINDOW_S / float(np.median(dt)))))
    whole, _ = ours_on(rec, rec.run)
    t0 = float(t[0] - (t[1] - t[0]))
    third = (float(t[-1]) - t0) / 3.0
    out = []
    for held, fit_span, score_span in (
        ("last third", (t0, t0 + 2 * third), (t0 + 2 * third, t[-1])),
        ("first third", (t0 + third, t[-1]), (t0, t0 + third)),
    ):
        keep = (t > fit_span[0]) & (t <= fit_span[1])
        part = slice_run(rec.run, *fit_span)
        lo, hi = np.searchsorted(t, score_span[0], side="right"), np.searchsorted(t, score_span[1], "right")
        inside = (rests.start >= lo) & (rests.end <= hi)
        start, end = rests.start[inside], rests.end[inside]
        c, res = ours_on(rec, part)
        fit, _ = imutk_on(rec, part, keep)
        if fit is None:
            continue
        so, sk, sw = (scored(x, rec, start, end).poses for x in (c, fit.correction, whole))
        _, force = c.apply(rec.raw_gyro, rec.raw_accel)
        v = np.array([mean_variance(force[a:b], block) for a, b in zip(start, end, strict=True)])
        per_move = np.degrees(np.sqrt(2.0 * (v[:-1] + v[1:])) / rec.gravity)
        used = so.used & sk.used
        floor = rms(per_move[used])
        turning = used & (so.turn_deg >= TURNING_DEG)
        o, k = rms(so.angle_deg[used]), rms(sk.angle_deg[used])
        ot, kt = rms(so.angle_deg[turning]), rms(sk.angle_deg[turning])
        ow = rms(sw.angle_deg[used])
        sigma = our_sigma_on_score(res, rec, start, end, dt, used)
        out.append(
            f"| {rec.name} | {held} | {int(used.sum())} ({int(turning.sum())}) | "
            f"{o:.3f} | {k:.3f} | {o / k:.2f} | "
            f"{floor:.3f} | {above(o, floor) / max(above(k, floor), 1e-12):.2f} | {ot / kt:.2f} | "
            f"{ow:.3f} ({ow / k:.2f}) | {sigma:.3f} |"
        )
    return out


def main() -> None:
    if not DATA.is_dir():
        sys.exit(f"{DATA} is absent (set REALDATA)")
    print(
        "| recording | held out | moves (turning) | ours RMS deg | imu_tk's method | ratio | floor deg | "
        "ratio above floor | ratio, turning moves | ours whole recording (ratio) | ours predicted deg |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for rec in (xsens(), mikoff("imu0"), mikoff("imu1")):
        print("\n".join(rows_of(rec)))


if __name__ == "__main__":
    main()
