"""The real hand recordings as other loggers, sensors and hands would write them: does the fit hold?

Each recording copied into tests/data/realdata (or REALDATA=<folder>) is read once, then
written back as a logger's CSV in several ways that change how the samples are told, not
what the unit did, and calibrated through the CLI as a user would (`--by-hand --profile
mems` and the site):

* ``base``: the samples as they are (SI, seconds);
* ``50 Hz`` / ``25 Hz``: pairs / fours of samples summed (a slower logger's averaging output);
* ``epoch ns``: the time in integer nanoseconds from the UNIX epoch;
* ``g, deg/s``: the accelerometer in g and the gyro in deg/s, labelled so;
* ``axes turned``: both triads' axes relabelled x->y->z->x (another mounting);
* ``first half`` / ``second half``: each half alone;
* ``halves swapped``: the second half, then the first (two sessions spliced in one file: the move
  across the seam jumps between unrelated attitudes);
* ``acc 1/2 rate, own stamps``: the accelerometer's samples summed in pairs and stamped 3 ms
  late, the gyro's as they are, as two imu_tk text files (two clocks);
* ``two CSV files``: each sensor its own CSV, as a phone's logger writes them: the gyro in
  deg/s on epoch-ns stamps jittering by up to 3 ms, the accelerometer in g, summed in pairs
  and stamped 4 ms late.

and two mistakes, which must be refused naming them: the accelerometer in g labelled m/s^2,
and the gyro's x axis sign-flipped.

    PYTHONPATH=. python benchmarks/by_hand_variants.py

Prints a Markdown table: exit code, chi2/dof, rests, moves used, the model chosen, loose
blocks of rests, and for variants whose parameters are the base's (same axes, same errors),
the largest difference from the base fit in the base's sigmas.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from calib.runlog import read_run

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("REALDATA", ROOT / "tests" / "data" / "realdata"))
BIN = Path(sys.executable).parent / "seqdesign"
MIKOFF = ",".join(
    [f"{i + 1}=accel_{a}_mps2" for i, a in enumerate("xyz")]
    + [f"{i + 4}=gyro_{a}_radps" for i, a in enumerate("xyz")]
)
FERRARIS = (
    "n_samples=counter,gyr_x=gyro_x_dps,gyr_y=gyro_y_dps,gyr_z=gyro_z_dps,"
    "acc_x=accel_x_mps2,acc_y=accel_y_mps2,acc_z=accel_z_mps2"
)
G0 = 9.80665
COMPARABLE = {
    "50 Hz",
    "25 Hz",
    "epoch ns",
    "g, deg/s",
    "halves swapped",
    "acc 1/2 rate, own stamps",
    "two CSV files",
}


def recordings() -> dict:
    """Each recording's reading options and its site."""
    xs = DATA / "imu_tk-xsens"
    return {
        "Xsens MTi (imu_tk)": (
            dict(
                path=xs / "xsens_acc.mat.gz",
                gyro_path=xs / "xsens_gyro.mat.gz",
                conversion=xs / "xsens-nominal-values.txt",
            ),
            ["--latitude", "45.4", "--height", "0", "--gravity", "9.81744"],
        ),
        "Ferraris session (imucal)": (
            dict(
                path=DATA / "imucal-ferraris" / "example_ferraris_session.csv",
                columns=FERRARIS,
                sample_rate_hz=102.4,
            ),
            ["--latitude", "49.6", "--height", "300", "--gravity", "9.81"],
        ),
        "mikoff imu0 (MPU-9150)": (
            dict(path=DATA / "mikoff-mpu9150" / "imu0.log.gz", columns=MIKOFF, sample_rate_hz=100.0),
            ["--latitude", "55", "--height", "100"],
        ),
        "mikoff imu1 (MPU-9150)": (
            dict(path=DATA / "mikoff-mpu9150" / "imu1.log.gz", columns=MIKOFF, sample_rate_hz=100.0),
            ["--latitude", "55", "--height", "100"],
        ),
    }


def write_csv(path: Path, t, w, f, units=("s", "radps", "mps2")) -> None:
    """A logger's CSV: time, gyro, accelerometer, named by their units."""
    tu, wu, fu = units
    header = [f"time_{tu}"] + [f"gyro_{a}_{wu}" for a in "xyz"] + [f"accel_{a}_{fu}" for a in "xyz"]
    if tu == "ns":  # integer epoch nanoseconds, as a ROS or Android logger writes them
        stamps = (np.rint(t * 1e9) + 1_700_000_000_000_000_000).astype(np.int64).astype(str)
    else:
        stamps = np.char.mod("%.6f", t)
    body = np.char.mod("%.9g", np.column_stack([w, f]))
    rows = [",".join([s, *r]) for s, r in zip(stamps, body, strict=True)]
    path.write_text(",".join(header) + "\n" + "\n".join(rows) + "\n")


def write_sensor(path: Path, sensor: str, t, values, unit: str) -> None:
    """One sensor's CSV file: integer epoch nanoseconds and its three axes."""
    stamps = (np.rint(t * 1e9) + 1_700_000_000_000_000_000).astype(np.int64).astype(str)
    body = np.char.mod("%.9g", values)
    rows = [",".join([s, *r]) for s, r in zip(stamps, body, strict=True)]
    header = ["time_ns"] + [f"{sensor}_{a}_{unit}" for a in "xyz"]
    path.write_text(",".join(header) + "\n" + "\n".join(rows) + "\n")


def summed(t, w, f, k: int):
    """Every ``k`` samples as one (rates and forces averaged, stamped at the last one's end)."""
    n = len(t) // k * k
    return t[k - 1 : n : k], w[:n].reshape(-1, k, 3).mean(axis=1), f[:n].reshape(-1, k, 3).mean(axis=1)


def variants(run, tmp: Path, name: str, reading: dict) -> list:
    """(label, args) for each way of writing the recording."""
    period = run.dt_nominal
    t = run.time_s - run.time_s[0] + period
    w, f = run.dtheta_rad / period, run.dv_mps / period
    half = len(t) // 2
    out = []

    def csv(label, *arrays, units=("s", "radps", "mps2")):
        path = tmp / f"{name}-{label.replace(' ', '_').replace('/', '')}.csv"
        write_csv(path, *arrays, units=units)
        out.append((label, [str(path)]))

    csv("base", t, w, f)
    csv("50 Hz", *summed(t, w, f, 2))
    csv("25 Hz", *summed(t, w, f, 4))
    csv("epoch ns", t, w, f, units=("ns", "radps", "mps2"))
    csv("g, deg/s", t, np.degrees(w), f / G0, units=("s", "dps", "g"))
    turn = [1, 2, 0]
    csv("axes turned", t, w[:, turn], f[:, turn])
    csv("first half", t[:half], w[:half], f[:half])
    csv("second half", t[half:], w[half:], f[half:])
    csv("halves swapped", t, np.vstack([w[half:], w[:half]]), np.vstack([f[half:], f[:half]]))
    if run.conversion is not None:  # imu_tk's text files: the accelerometer at half rate, its own stamps
        acc_t, _, acc_f = summed(t, w, f, 2)
        acc = np.column_stack([acc_t + 0.003, run.conversion.to_counts(acc_f, "accel")])
        gyro = np.column_stack([t, run.conversion.to_counts(w, "gyro")])
        np.savetxt(tmp / f"{name}-acc.txt", acc, fmt="%.9e")
        np.savetxt(tmp / f"{name}-gyro.txt", gyro, fmt="%.9e")
        out.append(
            (
                "acc 1/2 rate, own stamps",
                [str(tmp / f"{name}-acc.txt"), "--gyro-file", str(tmp / f"{name}-gyro.txt")]
                + ["--conversion", str(reading["conversion"])],
            )
        )
    # A phone's or a driver's logger: each sensor its own CSV file, the gyro in deg/s on epoch-ns
    # stamps jittering by up to 3 ms, the accelerometer in g at half rate, stamped 4 ms late.
    jitter = np.random.default_rng(1).uniform(0.0, 0.003, len(t))
    acc_t, _, acc_f = summed(t, w, f, 2)
    gyro_csv, acc_csv = tmp / f"{name}-Gyroscope.csv", tmp / f"{name}-Accelerometer.csv"
    write_sensor(gyro_csv, "gyro", t + jitter, np.degrees(w), "dps")
    write_sensor(acc_csv, "accel", acc_t + 0.004, acc_f / G0, "g")
    out.append(("two CSV files", [str(acc_csv), "--gyro-file", str(gyro_csv)]))
    csv("mistake: accel in g as m/s^2", t, w, f / G0)
    csv("mistake: gyro x flipped", t, w * [-1.0, 1.0, 1.0], f)
    return out


def calibrate(args: list, site: list, out: Path) -> tuple[int, dict, str, float]:
    cmd = [str(BIN), "calibrate", *args, "--by-hand", "--profile", "mems", *site, "-o", str(out), "--json"]
    start = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - start
    doc = json.loads(done.stdout) if done.returncode == 0 else {}
    error = done.stderr.strip().splitlines()[-1] if done.returncode else ""
    return done.returncode, doc, error, wall


def main() -> None:
    print("| recording | written as | exit | chi2/dof | rests | moves used | g-sens. | loose blocks | "
          "max \\|diff\\| / sigma vs base | wall s |")  # fmt: skip
    print("|---|---|---:|---:|---:|---:|---|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        only = os.environ.get("ONLY", "")
        for k, (name, (reading, site)) in enumerate(recordings().items()):
            if only not in name:
                continue
            options = {key: value for key, value in reading.items() if key != "path"}
            lat, height = float(site[1]), float(site[3])
            run = read_run(reading["path"], latitude_deg=lat, height_m=height, **options)
            base = None
            for label, args in variants(run, tmp, f"r{k}", reading):
                code, doc, error, wall = calibrate(args, site, tmp / f"r{k}.result.toml")
                if code:
                    print(f"| {name} | {label} | {code} | refused: {error[:150]} | | | | | | {wall:.1f} |")
                    continue
                fit, hand = doc["fit"], doc["by_hand"]
                params = doc["parameters"]
                if label == "base":
                    base = params
                diff = "-"
                if base is not None and label in COMPARABLE:
                    worst = max(abs(params[p]["value"] - b["value"]) / b["sigma"] for p, b in base.items())
                    diff = f"{worst:.2f}"
                print(
                    f"| {name} | {label} | 0 | {fit['chi2_per_dof']:.3f} | {len(hand['rests'])} | "
                    f"{sum(m['used'] for m in hand['moves'])} of {len(hand['moves'])} | "
                    f"{'yes' if 'g-sensitivity' in fit['extras'] else 'no'} | "
                    f"{len(hand.get('loose_rests', []))} | "
                    f"{diff} | {wall:.1f} |"
                )


if __name__ == "__main__":
    main()
