"""``seqdesign score``: calibrations judged on another recording's still poses.

Two simulated hand recordings of one unit (the same 21 errors, other poses and noise): the
first calibrated, its correction scored on the second, as a user checks a calibration.
Each is run as a user runs it, the CLI in a process of its own.
"""

from __future__ import annotations

import json
import subprocess
import sys

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
