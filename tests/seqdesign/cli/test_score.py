"""``seqdesign score``: calibrations judged on another recording's still poses.

Two simulated hand recordings of one unit (the same 21 errors, other poses and noise): the
first calibrated, its correction scored on the second, as a user checks a calibration.
Each is run as a user runs it, the CLI in a process of its own.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ERRORS = """\
[errors]
bgx = 700.0
bgy = -1000.0
bgz = 400.0
sgx = 3000.0
sgy = -2000.0
sgz = 4000.0
bax = 5000.0
bay = -3000.0
baz = 8000.0
sax = 2000.0
say = 3000.0
saz = -1000.0
mgxy = 300.0
mgxz = -200.0
mgyx = 100.0
mgyz = 400.0
mgzx = -300.0
mgzy = 200.0
mayx = 600.0
mazx = -400.0
mazy = 200.0
"""


def cli(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "seqdesign.cli", *map(str, args)], capture_output=True, text=True, cwd=cwd
    )


@pytest.fixture(scope="module")
def unit(tmp_path_factory):
    """Two hand recordings of one unit and the correction the first one's calibration writes."""
    d = tmp_path_factory.mktemp("unit")
    (d / "errors.toml").write_text(ERRORS)
    for name, seed in (("a", 1), ("b", 2)):
        res = cli(
            "simulate", "--by-hand", "--poses", "16", "--profile", "mems", "--errors", d / "errors.toml",
            "--seed", seed, "-o", d / f"{name}.csv",
        )  # fmt: skip
        assert res.returncode == 0, res.stderr
    res = cli("calibrate", d / "a.csv", "--by-hand", "--profile", "mems", "-o", d / "a.result.toml",
              "--correction", d / "a.correction.toml")  # fmt: skip
    assert res.returncode == 0, res.stderr
    return d


def test_a_calibration_scored_on_another_recording_of_the_unit_leaves_the_noise(unit):
    res = cli("score", unit / "b.csv", "--correction", unit / "a.correction.toml", "--json")
    assert res.returncode == 0, res.stderr
    doc = json.loads(res.stdout)
    assert doc["rests"] == 16 and doc["moves_used"] == 15
    as_read, fitted = doc["scores"]
    assert as_read["correction"] == "as read"
    # As read, |f| at a pose u is about g + b.u + g u.S u: with biases of 3-8 mg the b.u term alone
    # spreads by |b| / sqrt(3), about 55 mm/s^2, over poses uniform on the sphere.
    assert as_read["std_mps2"] > 0.02
    # Calibrated, what is left is each rest mean's own noise, VRW / sqrt(T): 460 ug/sqrt(Hz) over
    # rests of 5-12 s, 1.3-2.0 mm/s^2, plus the calibration's sigmas (a tenth of that here);
    # 4 mm/s^2 is twice the noise.
    assert fitted["std_mps2"] < 0.004
    # The gyro's 0.2-0.4 % scale errors tilt a 90-180 deg turn's end by 0.2-0.7 deg as read;
    # calibrated, what is left is mostly the first recording's own sigmas (gyro scale factors to
    # about 1000 ppm from 16 poses: 0.1-0.2 deg a turn), a quarter of that at most.
    assert as_read["pose_rms_deg"] > 0.1
    assert fitted["pose_rms_deg"] < 0.25 * as_read["pose_rms_deg"]
    # The magnitudes' mean is local gravity (normal gravity at the simulator's 40 deg, 9.8017 m/s^2),
    # to the accelerometer scale factors' sigmas (about 150 ppm: 1.5 mm/s^2; 5 is three of them).
    assert fitted["mean_mps2"] == pytest.approx(9.8017, abs=0.005)


def test_the_table_names_each_correction_and_what_was_scored(unit):
    res = cli("score", unit / "b.csv", "--correction", unit / "a.correction.toml")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0].split()[0] == "correction" and lines[1].startswith("as read")
    assert "a.correction.toml" in lines[2]
    assert "scoring on" in res.stderr and "16 rests, 15 of 15 moves" in res.stderr


def test_too_few_still_poses_are_refused_saying_what_to_record(unit):
    res = cli(
        "simulate", "--by-hand", "--poses", "2", "--profile", "mems", "--seed", "3", "-o", unit / "two.csv"
    )
    assert res.returncode == 0, res.stderr
    res = cli("score", unit / "two.csv", "--correction", unit / "a.correction.toml")
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "found 2 still pose(s)" in res.stderr and "3 or more still poses" in res.stderr


def test_a_correction_that_is_not_there_is_refused(unit):
    res = cli("score", unit / "b.csv", "--correction", unit / "nope.toml")
    assert res.returncode != 0 and "Traceback" not in res.stderr
    assert "nope.toml" in res.stderr


REALDATA = Path(__file__).resolve().parents[2] / "data" / "realdata"  # copied with their licences
FERRARIS_COLUMNS = (
    "n_samples=counter,gyr_x=gyro_x_dps,gyr_y=gyro_y_dps,gyr_z=gyro_z_dps,"
    "acc_x=accel_x_mps2,acc_y=accel_y_mps2,acc_z=accel_z_mps2"
)


def _scores(*args) -> list[dict]:
    res = cli("score", *args, "--json")
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout)["scores"]


def test_imucal_s_result_is_scored_on_its_own_recording_in_its_raw_units():
    # imucal's correction takes the log's deg/s; it was fitted to g = 9.81 (its authors' value), so
    # its |f| over the poses centres there, to its accelerometer's own residuals (a few mm/s^2).
    d = REALDATA / "imucal-ferraris"
    as_read, imucal = _scores(
        d / "example_ferraris_session.csv", "--sample-rate-hz", "102.4", "--columns", FERRARIS_COLUMNS,
        "--latitude", "49.6", "--height", "300",
        "--correction", d / "example_ferraris_session-imucal-result.json",
    )  # fmt: skip
    assert imucal["mean_mps2"] == pytest.approx(9.81, abs=0.005)
    # As read the unit's accelerometer is off by percents (|f| spreads by decimetres per s^2);
    # calibrated, by millimetres: a hundredth of it at most.
    assert imucal["std_mps2"] < 0.01 * as_read["std_mps2"]
    assert imucal["pose_rms_deg"] < 0.25 * as_read["pose_rms_deg"]


def test_imu_tk_s_result_is_scored_on_its_own_recording_in_counts():
    # imu_tk's correction takes raw counts: the log is read with its conversion and told back in
    # counts. It was fitted to the authors' local gravity, 9.81744 m/s^2.
    d = REALDATA / "imu_tk-xsens"
    as_read, imu_tk = _scores(
        d / "xsens_acc.mat.gz", "--gyro-file", d / "xsens_gyro.mat.gz", "--conversion",
        d / "xsens-nominal-values.txt", "--latitude", "45.4", "--height", "0",
        "--correction", d / "imu_tk-result.txt",
    )  # fmt: skip
    assert imu_tk["mean_mps2"] == pytest.approx(9.81744, abs=0.003)
    assert imu_tk["std_mps2"] < 0.1 * as_read["std_mps2"]


def test_a_file_that_is_no_calibration_is_refused_saying_which_are(unit):
    (unit / "notes.txt").write_text("calibrated on Tuesday\n")
    res = cli("score", unit / "b.csv", "--correction", unit / "notes.txt")
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "notes.txt" in res.stderr and "## acc" in res.stderr


def test_a_correction_written_without_sigmas_scores_as_the_one_with_them(unit):
    # A correction copied by hand from another tool's result knows no sigmas; the score uses
    # M, b (and G) alone, so it is the same.
    text = (unit / "a.correction.toml").read_text()
    lines, skipping = [], False
    for line in text.splitlines():  # each sigma an array over lines, "sigma_M = [" to "]"
        skipping = skipping or line.startswith(("sigma_M", "sigma_b", "sigma_G"))
        if not skipping:
            lines.append(line)
        elif line.rstrip().endswith("]") and not line.rstrip().endswith("],"):
            skipping = False
    assert "sigma" in text and "sigma" not in "\n".join(lines)
    (unit / "bare.correction.toml").write_text("\n".join(lines) + "\n")
    _, full = _scores(unit / "b.csv", "--correction", unit / "a.correction.toml")
    _, bare = _scores(unit / "b.csv", "--correction", unit / "bare.correction.toml")
    for key in ("mean_mps2", "std_mps2", "pose_rms_deg"):
        assert bare[key] == full[key]
