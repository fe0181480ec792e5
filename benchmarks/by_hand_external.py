"""Hand recordings as they come: each calibrated, scored out of sample against imu_tk's method.

For recordings nobody here tuned to (the shared ones have `by_hand_cv.py`): logs of one unit
read with one column map and site, as their owner would give them. For each:

* our fit of the whole recording as a user runs it (``--by-hand --profile mems`` and the site):
  chi2/dof, rests, moves, the weights the data earned;
* the cross-validation of `by_hand_cv.py`: fit two thirds, score the third held out, ours and
  imu_tk's method (:mod:`calib.peers.imutk_method`) fitted on the same part;

and, given two recordings or more, each fitted on one and scored on another (a second recording
is the strictest held-out set: other poses, another power-up), with the repeatability check of
``seqdesign compare`` between our calibrations.

    PYTHONPATH=. .venv/bin/python benchmarks/by_hand_external.py LOG [LOG ...] \\
        --columns 1=time_s,2=accel_x_mps2,...,7=gyro_z_radps --latitude 37.46 --height 100 [--gravity G]

Logs in SI (rates or increments in any unit of the column grammar); counts are not read here. A
logger's two files, one per sensor, are one LOG written ``ACCEL_FILE::GYRO_FILE`` (as calibrate's
RUN and ``--gyro-file``).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from pathlib import Path

import numpy as np
from by_hand import Recording, scored
from by_hand_cv import carried_lines, imutk_on, ours_on, rests_of, split_rows, table

from calib.calibration.entry import CalibrateOptions, calibrate
from calib.errors import CalibError
from calib.nav.site import Site
from calib.nav.strapdown import sample_intervals
from calib.runlog import read_run
from seqdesign.repeatability import Repeatability

SAID = ("noise", "model")  # the lines of our summary that say what the data chose


def recording(path: str, args) -> Recording:
    """The log read as its owner would, its samples in SI as the raw units of the scores."""
    path, _, gyro_path = path.partition("::")
    run = read_run(
        path,
        gyro_path=gyro_path or None,
        columns=args.columns,
        sample_rate_hz=args.sample_rate_hz,
        latitude_deg=args.latitude,
        height_m=args.height,
        allow_gaps=args.allow_gaps,
        guess_turns=args.allow_gaps,
    )
    gravity = args.gravity or Site.at(math.radians(args.latitude), args.height).gravity_mps2
    run.meta["gravity_mps2"] = repr(gravity)
    dt = sample_intervals(run.time_s)[:, None]
    clipped = np.zeros(len(run.time_s), bool) if run.clipped is None else run.clipped.any(axis=1)
    one = (np.zeros(3), np.ones(3))
    rate, force = run.dtheta_rad / dt, run.dv_mps / dt
    return Recording(Path(path).name, rate, force, run, clipped, one, one, args.latitude, gravity)


def whole_lines(rec: Recording):
    """Our default fit of the whole recording, in a few lines, and the result (None when refused)."""
    try:
        res = calibrate(rec.run, "mems", by_hand=True, options=CalibrateOptions(gravity_mps2=rec.gravity))
    except CalibError as exc:
        return [f"- {rec.name}: refused: {exc.message}"], None
    hand = res.by_hand
    lines = [
        f"- {rec.name}: {rec.run.n_samples} samples, {rec.run.duration_s:.1f} s; chi2/dof "
        f"{res.chi2_per_dof:.3f}; {len(hand.rest_s)} rests, moves used {int(np.sum(hand.move_used))} of "
        f"{len(hand.move_used)}",
        *(f"  - {line}" for line in hand.lines() if line.startswith(SAID) or "block(s) beyond" in line),
    ]
    return lines, res


def cross_lines(recs: list[Recording]) -> list[str]:
    """Each fitted on one recording (ours, imu_tk's method), scored on every other."""
    out = [
        "| fitted on | scored on | ours std\\|f\\| mm/s² | imu_tk's method | "
        "ours pose-to-pose deg | imu_tk's method |",
        "|---|---|---:|---:|---:|---:|",
    ]
    fits = {}
    for rec in recs:
        mine = None
        try:
            mine = ours_on(rec, rec.run)[0]
        except CalibError:
            pass
        theirs, _ = imutk_on(rec, rec.run, np.ones(rec.run.n_samples, bool))
        fits[rec.name] = (mine, None if theirs is None else theirs.correction)
    for a, b in itertools.permutations(recs, 2):
        rests = rests_of(b)
        cells = []
        for c in fits[a.name]:
            if c is None:
                cells.append(("refused", "refused"))
                continue
            s = scored(c, b, rests.start, rests.end)
            cells.append((f"{1e3 * s.spread.std:.2f}", f"{s.poses.rms_deg:.3f}"))
        out.append(f"| {a.name} | {b.name} | {cells[0][0]} | {cells[1][0]} | {cells[0][1]} | {cells[1][1]} |")
    return out


def main() -> int | None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("logs", nargs="+", metavar="LOG")
    ap.add_argument("--columns", required=True, help="the column map, as calibrate's --columns")
    ap.add_argument("--latitude", type=float, required=True)
    ap.add_argument("--height", type=float, required=True)
    ap.add_argument("--gravity", type=float, default=None, help="local gravity, m/s^2 (default: normal)")
    ap.add_argument("--sample-rate-hz", type=float, default=None)
    ap.add_argument("--allow-gaps", action="store_true", help="as calibrate's --allow-gaps, by hand")
    args = ap.parse_args()
    try:
        recs = [recording(p, args) for p in args.logs]
    except CalibError as exc:  # a log the reader refuses: said as the CLI says it, no traceback
        print(f"error: {exc}", file=sys.stderr)
        return 2
    results = {}
    print("## Each recording, calibrated as its owner would\n")
    for rec in recs:
        lines, results[rec.name] = whole_lines(rec)
        print("\n".join(lines))
    print("\n## Two thirds fitted, the third held out scored\n")
    rows = []
    for rec in recs:
        try:
            rows += split_rows(rec, None)
        except CalibError as exc:  # no rests to score on (the tool's own refusal): said, no traceback
            print(f"- {rec.name}: not scored: {exc}")
    print("\n".join(table(rows) + [""] + carried_lines(rows)))
    if len(recs) < 2:
        return
    print("\n## Fitted on one recording, scored on another\n")
    print("\n".join(cross_lines(recs)))
    print("\n## Our calibrations of the recordings two by two (seqdesign compare)\n")
    for a, b in itertools.combinations([r for r in recs if results[r.name] is not None], 2):
        s, dof, p = Repeatability(results[a.name], results[b.name], (a.name, b.name)).chi2()
        print(f"- {a.name} and {b.name}: chi2 {s:.1f} on {dof}, p = {p:.3g}")


if __name__ == "__main__":
    sys.exit(main())
