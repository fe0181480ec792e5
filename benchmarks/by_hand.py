"""Our fit of runs placed by hand side by side with imu_tk and imucal, on their own real recordings.

Scores every calibration with :mod:`calib.peers.scores` on the same rests (found by
:func:`calib.hand.rests.find_rests` with the mems profile on the log read with its
nominal conversion), and prints Markdown tables:

* Xsens MTi (imu_tk's test log): ours (by hand, g-sensitivity, mems) vs imu_tk's result; then ours
  fitted on the first two thirds of the samples, both scored on the rests and moves of the last third;
* Ferraris session (imucal's example): ours vs imucal's result, and our rests against imucal's
  section list.

    PYTHONPATH=. python benchmarks/by_hand.py [--moves]

Reads the recordings copied into tests/data/realdata (or REALDATA=<folder>).
"""

from __future__ import annotations

import argparse
import gzip
import json
import math
import os
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from calib.calibration.correction import Correction, correction_from_parameters
from calib.calibration.entry import CalibrateOptions, calibrate
from calib.hand.rests import find_rests
from calib.nav.strapdown import sample_intervals
from calib.noise.profiles import load_profile
from calib.peers.published import read_imu_tk, read_imucal
from calib.peers.scores import HandScore, RestSpans, score
from calib.runlog import Run, make_meta

DATA = Path(os.environ.get("REALDATA", Path(__file__).resolve().parents[1] / "tests" / "data" / "realdata"))
XSENS_ZERO_G = np.array([32768.0, 32466.0, 32485.0])  # counts (the authors' nominal values)
XSENS_K_G = np.array([4778.0, 4758.0, 4766.0])  # counts per rad/s
XSENS_ZERO_A = np.array([33123.0, 33276.0, 32360.0])
XSENS_K_A = np.array([415.0, 413.0, 415.0])  # counts per m/s^2
XSENS_GRAVITY, XSENS_LATITUDE = 9.81744, 45.4  # the authors' gravity; Padova
FERRARIS_RATE_HZ, FERRARIS_GRAVITY, FERRARIS_LATITUDE = 102.4, 9.81, 49.6  # imucal's g; Erlangen
# The held-out poses are scored where held long enough that a pose's own noise does not rule the
# score, and the same poses whatever the shortest rest the fit takes: scores compare across changes
# of the rest finder (the fit itself keeps rests from 0.15 s, calib.hand.rests.MIN_REST_S).
SCORED_REST_S = 0.5
CLIP_FRACTION = 0.95  # of the range: a sample beyond is taken as clipped
BMI160_RANGE_DEG_S = 2000.0
DEG_PER_RAD_H = 180.0 / math.pi * 3600.0


@dataclass
class Recording:
    """A recording's raw samples, its run in SI and what the scores need."""

    name: str
    raw_gyro: np.ndarray
    raw_accel: np.ndarray
    run: Run
    clipped: np.ndarray
    gyro_conversion: tuple
    accel_conversion: tuple
    latitude_deg: float
    gravity: float

    def cut(self, stop: int) -> Recording:
        run = Run(
            self.run.time_s[:stop],
            self.run.dtheta_rad[:stop],
            self.run.dv_mps[:stop],
            self.run.meta,
            source=f"{self.run.source}[:{stop}]",
        )
        run.clipped = _per_channel(self.clipped[:stop])
        return replace(self, run=run, clipped=self.clipped[:stop])


def _run(time_s, rate_si, force_si, rate_hz, latitude, gravity, clipped, source) -> Run:
    dt = sample_intervals(time_s)
    run = Run(
        time_s,
        rate_si * dt[:, None],
        force_si * dt[:, None],
        make_meta(latitude, 0.0, rate_hz, gravity),
        source=source,
    )
    run.clipped = _per_channel(clipped)  # read by the hand fit: a move holding a clipped sample is left out
    return run


def _per_channel(clipped: np.ndarray) -> np.ndarray:
    """The Run's (n, 6) mask (gyro x y z, accel x y z) of a per-sample gyro mask."""
    return np.column_stack([clipped] * 3 + [np.zeros_like(clipped)] * 3)


def xsens() -> Recording:
    d = DATA / "imu_tk-xsens"
    acc = np.loadtxt(gzip.open(d / "xsens_acc.mat.gz"))
    gyr = np.loadtxt(gzip.open(d / "xsens_gyro.mat.gz"))
    t, rg, ra = acc[:, 0], gyr[:, 1:], acc[:, 1:]
    clipped = np.any(np.abs(rg - 32768.0) > CLIP_FRACTION * 32768.0, axis=1)
    rate, force = (rg - XSENS_ZERO_G) / XSENS_K_G, (ra - XSENS_ZERO_A) / XSENS_K_A
    run = _run(t, rate, force, 100.0, XSENS_LATITUDE, XSENS_GRAVITY, clipped, "xsens")
    return Recording(
        "Xsens MTi (imu_tk)",
        rg,
        ra,
        run,
        clipped,
        (XSENS_ZERO_G, XSENS_K_G),
        (XSENS_ZERO_A, XSENS_K_A),
        XSENS_LATITUDE,
        XSENS_GRAVITY,
    )


def ferraris() -> Recording:
    a = np.loadtxt(DATA / "imucal-ferraris" / "example_ferraris_session.csv", delimiter=",", skiprows=1)
    n, rg, ra = a[:, 0], a[:, 1:4], a[:, 4:7]
    t = (n - n[0] + 1.0) / FERRARIS_RATE_HZ  # sample i ends at (i + 1) / rate
    clipped = np.any(np.abs(rg) > CLIP_FRACTION * BMI160_RANGE_DEG_S, axis=1)
    run = _run(
        t, np.radians(rg), ra, FERRARIS_RATE_HZ, FERRARIS_LATITUDE, FERRARIS_GRAVITY, clipped, "ferraris"
    )
    zero = np.zeros(3)
    return Recording(
        "Ferraris session (imucal)",
        rg,
        ra,
        run,
        clipped,
        (zero, np.full(3, 180.0 / math.pi)),
        (zero, np.ones(3)),
        FERRARIS_LATITUDE,
        FERRARIS_GRAVITY,
    )


def ours(rec: Recording, partial: bool = False) -> tuple[Correction, object]:
    """Our calibration of the recording (by hand, g-sensitivity, mems) as a correction in its raw units."""
    res = calibrate(
        rec.run,
        "mems",
        by_hand=True,
        extras="g-sensitivity",
        requirements="mems",
        options=CalibrateOptions(gravity_mps2=rec.gravity, partial=partial),
    )
    G = res.extra_values.reshape(3, 3)
    c = correction_from_parameters(
        res.values,
        res.covariance,
        G,
        res.extra_sigma.reshape(3, 3),
        rec.gyro_conversion,
        rec.accel_conversion,
        source="ours",
    )
    return c, res


def rests_of(rec: Recording):
    """The rests every tool is scored on: found on the whole log with the mems profile, each at
    least :data:`SCORED_REST_S` long."""
    p = load_profile("mems")
    run = rec.run
    dt = sample_intervals(run.time_s)
    return find_rests(run.dtheta_rad, run.dv_mps, dt, p.arw, p.vrw, rec.name, min_rest_s=SCORED_REST_S)


def scored(c: Correction, rec: Recording, start, end) -> HandScore:
    zero_g, zero_a = rec.gyro_conversion[0], rec.accel_conversion[0]
    return score(
        c,
        rec.raw_gyro,
        rec.raw_accel,
        RestSpans(rec.run.time_s, start, end, rec.clipped, rec.latitude_deg),
        raw_zero=(zero_g, zero_a),
    )


def score_rows(label: str, pairs: list[tuple[str, HandScore]]) -> list[str]:
    rows = []
    for tool, s in pairs:
        p = s.poses
        rows.append(
            f"| {label} | {tool} | {len(s.spread.magnitude)} | {s.spread.mean:.5f} | "
            f"{1e3 * s.spread.std:.2f} | {1e3 * s.spread.range:.2f} | {int(p.used.sum())}/{len(p.used)} | "
            f"{p.rms_deg:.3f} | {p.max_deg:.3f} | {p.earth_bound_deg:.4f} |"
        )
    return rows


SCORE_HEAD = [
    "| recording | calibration | rests | mean \\|f\\| m/s² | std \\|f\\| mm/s² | max−min mm/s² | moves | "
    "pose-to-pose RMS deg | max deg | Earth turn left out ≤ deg |",
    "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|",
]


def goal_lines(label: str, a: HandScore, b: HandScore, other: str) -> list[str]:
    ratio = a.spread.std / b.spread.std
    return [
        f"- {label}: |f| std ours/{other} = {ratio:.3f} "
        f"(goal ≤ 1.05: {'met' if ratio <= 1.05 else 'NOT met'}); "
        f"pose-to-pose RMS ours {a.poses.rms_deg:.3f}° vs {other} {b.poses.rms_deg:.3f}° "
        f"(goal below: {'met' if a.poses.rms_deg < b.poses.rms_deg else 'NOT met'})"
    ]


def axes_table(title: str, a: HandScore, b: HandScore, other: str, raw_g: str, raw_a: str) -> list[str]:
    out = [f"**{title}**", "", f"| quantity | ours | {other} | ours − {other} |", "|---|---:|---:|---:|"]

    def row(name, x, y, fmt, unit=""):
        out.append(f"| {name} | {x:{fmt}} | {y:{fmt}} | {x - y:{fmt}}{unit} |")

    for sensor, unit, k, raw in (
        ("gyro", "deg/h", DEG_PER_RAD_H, raw_g),
        ("accel", "mg", 1e3 / 9.80665, raw_a),
    ):
        sa, sb = getattr(a, sensor), getattr(b, sensor)
        for i, ax in enumerate("xyz"):
            x, y = sa.scale[i], sb.scale[i]
            out.append(
                f"| {sensor} scale {ax}, SI per {raw} | {x:.7g} | {y:.7g} | {1e6 * (x / y - 1):+.0f} ppm |"
            )
        for j, pair in enumerate(("xy", "xz", "yz")):
            row(
                f"{sensor} angle {pair} − 90°, arcsec",
                sa.nonorthogonality_arcsec[j],
                sb.nonorthogonality_arcsec[j],
                ".0f",
            )
        for i, ax in enumerate("xyz"):
            row(f"{sensor} bias {ax}, {raw}", sa.bias_raw[i], sb.bias_raw[i], ".4g")
        for i, ax in enumerate("xyz"):
            row(f"{sensor} bias {ax}, {unit}", k * sa.bias_si[i], k * sb.bias_si[i], ".1f")
    out.append("")
    return out


def section_lines(rec: Recording, start, end) -> list[str]:
    """Our rests against imucal's list of the six static faces."""
    sec = json.loads((DATA / "imucal-ferraris" / "example_ferraris_session_list.json").read_text())
    out = [
        "| face | imucal start–end s | our rest s | start offset s | end offset s | ours wider by s |",
        "|---|---|---|---:|---:|---:|",
    ]
    for face in ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a"):
        a, b = sec[face]["start"], sec[face]["end"]
        overlap = np.minimum(end, b) - np.maximum(start, a)
        k = int(np.argmax(overlap))
        if overlap[k] <= 0:
            out.append(f"| {face} | {a / FERRARIS_RATE_HZ:.2f}–{b / FERRARIS_RATE_HZ:.2f} | none | | | |")
            continue
        ds, de = (start[k] - a) / FERRARIS_RATE_HZ, (end[k] - b) / FERRARIS_RATE_HZ
        out.append(
            f"| {face} | {a / FERRARIS_RATE_HZ:.2f}–{b / FERRARIS_RATE_HZ:.2f} | "
            f"{start[k] / FERRARIS_RATE_HZ:.2f}–{end[k] / FERRARIS_RATE_HZ:.2f} | {ds:+.2f} | {de:+.2f} | "
            f"{de - ds:+.2f} |"
        )
    out.append("")
    return out


def move_lines(label: str, rests, pairs) -> list[str]:
    out = [f"{label}: per move, angle deg (" + ", ".join(t for t, _ in pairs) + "), turn deg, s"]
    t = pairs[0][1]
    for r in range(len(t.poses.used)):
        angles = " ".join(f"{s.poses.angle_deg[r]:7.3f}" for _, s in pairs)
        out.append(
            f"  {r:2d} rest {rests[0][r]}-{rests[1][r]} -> {rests[0][r + 1]}: {angles}  "
            f"turn {t.poses.turn_deg[r]:7.1f}"
        )
    return out


def _brief(s: HandScore) -> str:
    return f"|f| std {1e3 * s.spread.std:.2f} mm/s², pose-to-pose RMS {s.poses.rms_deg:.3f}°"


def why_lines(x, rx, c_ours, c_tk, f, rf, c_fo, c_ic) -> list[str]:
    """The g-sensitivity's share on the Xsens; both tools on imucal's own six faces."""
    out = ["", "### Checks behind the findings", ""]
    no_g = calibrate(
        x.run, "mems", by_hand=True, requirements="mems", options=CalibrateOptions(gravity_mps2=x.gravity)
    )
    c_no_g = correction_from_parameters(
        no_g.values, no_g.covariance, None, None, x.gyro_conversion, x.accel_conversion
    )
    cases = [
        ("ours", c_ours),
        ("ours, its G set to zero", replace(c_ours, g_sensitivity=None)),
        ("ours fitted without g-sensitivity", c_no_g),
        ("imu_tk", c_tk),
        (
            "imu_tk with our G and our gyro bias",
            replace(c_tk, g_sensitivity=c_ours.g_sensitivity, gyro=replace(c_tk.gyro, b=c_ours.gyro.b)),
        ),
    ]
    out += [f"- Xsens, {name}: {_brief(scored(c, x, rx.start, rx.end))}" for name, c in cases]
    sec = json.loads((DATA / "imucal-ferraris" / "example_ferraris_session_list.json").read_text())
    faces = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")
    st, en = np.array([sec[k]["start"] for k in faces]), np.array([sec[k]["end"] for k in faces])
    for name, c in (("ours", c_fo), ("imucal", c_ic)):
        out.append(f"- Ferraris on imucal's six faces, {name}: {_brief(scored(c, f, st, en))}")
    for name, c in (("ours", c_fo), ("imucal", c_ic)):
        m = scored(c, f, rf.start, rf.end).spread.magnitude
        out.append(
            f"- Ferraris |f| − g per rest, {name}, mm/s²: "
            + " ".join(f"{1e3 * (v - f.gravity):+.1f}" for v in m)
        )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", action="store_true", help="also print each move's angle")
    ap.add_argument("--why", action="store_true", help="also the checks behind the findings")
    args = ap.parse_args()
    if not DATA.is_dir():
        sys.exit(f"no real data at {DATA}")
    lines = ["### Scores", "", *SCORE_HEAD]
    goals, axes, extra = [], [], []

    x = xsens()
    rx = rests_of(x)
    c_ours, _ = ours(x)
    c_tk = read_imu_tk(DATA / "imu_tk-xsens" / "imu_tk-result.txt")
    s_ours, s_tk = scored(c_ours, x, rx.start, rx.end), scored(c_tk, x, rx.start, rx.end)
    lines += score_rows("Xsens, whole", [("ours", s_ours), ("imu_tk", s_tk)])
    goals += goal_lines("Xsens, whole", s_ours, s_tk, "imu_tk")
    axes += axes_table("Xsens: ours vs imu_tk", s_ours, s_tk, "imu_tk", "count", "count")
    if args.moves:
        extra += move_lines("Xsens", (rx.start, rx.end), [("ours", s_ours), ("imu_tk", s_tk)])

    cut = 2 * x.run.n_samples // 3
    c_two, _ = ours(x.cut(cut))
    last = rx.start >= cut
    s3_ours = scored(c_two, x, rx.start[last], rx.end[last])
    s3_tk = scored(c_tk, x, rx.start[last], rx.end[last])
    label = f"Xsens, last third (from {x.run.time_s[cut]:.1f} s); ours fitted on the first two thirds"
    lines += score_rows(label, [("ours (2/3)", s3_ours), ("imu_tk (whole)", s3_tk)])
    goals += goal_lines("Xsens, last third", s3_ours, s3_tk, "imu_tk")
    if args.moves:
        extra += move_lines(
            "Xsens last third", (rx.start[last], rx.end[last]), [("ours", s3_ours), ("imu_tk", s3_tk)]
        )

    f = ferraris()
    rf = rests_of(f)
    c_fo, _ = ours(f)
    c_ic = read_imucal(DATA / "imucal-ferraris" / "example_ferraris_session-imucal-result.json")
    s_fo, s_ic = scored(c_fo, f, rf.start, rf.end), scored(c_ic, f, rf.start, rf.end)
    lines += score_rows("Ferraris", [("ours", s_fo), ("imucal", s_ic)])
    goals += goal_lines("Ferraris", s_fo, s_ic, "imucal")
    axes += axes_table("Ferraris: ours vs imucal", s_fo, s_ic, "imucal", "deg/s", "m/s²")
    if args.moves:
        extra += move_lines("Ferraris", (rf.start, rf.end), [("ours", s_fo), ("imucal", s_ic)])

    print("\n".join([*lines, "", *goals, "", "### Axes", "", *axes]))
    print("### Ferraris: our rests against imucal's faces\n")
    print("\n".join(section_lines(f, rf.start, rf.end)))
    if args.why:
        extra += why_lines(x, rx, c_ours, c_tk, f, rf, c_fo, c_ic)
    if extra:
        print("\n".join(extra))


if __name__ == "__main__":
    main()
