"""Two files on two clocks (calib.runlog.streams): the accelerometer carried onto the gyro's samples.

The physics held: the carried increments integrate to the accelerometer's own integral over any
stretch (a rest's mean specific force is unchanged), a force held constant comes out exact at any
pair of rates, and a recording written as two files at two rates calibrates as the same recording
written row for row.
"""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from calib.runlog import read_run
from calib.runlog.streams import carry_onto, inside
from seqdesign.cli import main

REALDATA = Path(__file__).resolve().parents[2] / "data" / "realdata" / "imu_tk-xsens"
SITE = {"latitude_deg": 45.4, "height_m": 0.0}


def test_a_constant_force_is_carried_exactly_between_any_rates():
    f = np.array([0.3, -0.2, 9.8])
    a_period, g_period = 1 / 63.0, 1 / 200.0  # a camera IMU's accelerometer and gyro rates
    a_end = 0.0123 + a_period * np.arange(1, 400)
    g_end = 0.0371 + g_period * np.arange(1, 1200)
    keep = inside(a_end, a_period, g_end)
    dv = carry_onto(a_end, np.tile(f * a_period, (len(a_end), 1)), a_period, g_end[keep])
    # Each target increment is f times the gyro's period, to rounding of the running sum
    # (400 sums of 0.15 m/s: 1e-13 m/s).
    np.testing.assert_allclose(dv, np.tile(f * g_period, (keep.sum(), 1)), rtol=0, atol=1e-12)


def test_the_carried_increments_integrate_to_the_sources_own_integral():
    # Gyro samples at 3x the accelerometer's rate, a third of its period late: every third gyro end
    # is 2/3 into an accelerometer sample, so no sum can hide behind aligned ends.
    rng = np.random.default_rng(3)
    a_period = 0.03
    g_period = a_period / 3
    a_end = a_period * np.arange(1, 301)
    g_end = g_period / 3 + g_period * np.arange(1, 880)
    dv_a = rng.normal(size=(300, 3)) * a_period
    keep = inside(a_end, a_period, g_end)
    dv = carry_onto(a_end, dv_a, a_period, g_end[keep])
    # The gyro intervals from the one ending just after accelerometer end j to the one before end m
    # cover (a_end[j] - 2g/3, a_end[m] - 2g/3] (g the gyro's period): the accelerometer's samples
    # j+1..m, less the last 2g/3 = 2/9 of sample m, plus the same part of sample j. Exact for a
    # force held over each accelerometer interval.
    for j, m in ((5, 50), (17, 200), (3, 290)):
        first = int(np.searchsorted(g_end[keep], a_end[j]))  # the gyro end just after a_end[j]
        last = int(np.searchsorted(g_end[keep], a_end[m]))
        carried = dv[first:last].sum(axis=0)
        own = dv_a[j + 1 : m + 1].sum(axis=0) - 2.0 / 9.0 * (dv_a[m] - dv_a[j])
        np.testing.assert_allclose(carried, own, rtol=0, atol=1e-12)


def _xsens_tables():
    acc = np.loadtxt(gzip.open(REALDATA / "xsens_acc.mat.gz"))
    gyro = np.loadtxt(gzip.open(REALDATA / "xsens_gyro.mat.gz"))
    return acc, gyro


def test_a_recording_at_two_rates_calibrates_as_the_same_recording_row_for_row(tmp_path):
    # imu_tk's Xsens recording (tests/data/realdata, BSD) with its accelerometer averaged to 50 Hz
    # and stamped 3 ms late, and the gyro file cut short at both ends: another logger's two files.
    acc, gyro = _xsens_tables()
    n = len(acc) // 2 * 2
    slow = acc[:n].reshape(-1, 2, 4).mean(axis=1)
    slow[:, 0] = acc[1:n:2, 0] + 0.003
    np.savetxt(tmp_path / "acc50.txt", slow, fmt="%.7e")
    np.savetxt(tmp_path / "gyro.txt", gyro[150:-80], fmt="%.7e")
    conversion = REALDATA / "xsens-nominal-values.txt"
    run = read_run(tmp_path / "acc50.txt", gyro_path=tmp_path / "gyro.txt", conversion=conversion, **SITE)
    same = read_run(
        REALDATA / "xsens_acc.mat.gz", gyro_path=REALDATA / "xsens_gyro.mat.gz", conversion=conversion, **SITE
    )
    assert "two clocks" in run.meta["streams"] and "50.0" in run.meta["streams"]
    assert run.sample_rate_hz == pytest.approx(same.sample_rate_hz, rel=1e-6)
    # The gyro's rows are its own (150 left out at the start, the accelerometer's span at the end),
    # times a period estimated from other stamps (the cut file's: a part in 1e8).
    np.testing.assert_allclose(run.dtheta_rad, same.dtheta_rad[150 : 150 + run.n_samples], rtol=1e-7)
    # At rest (the first 50 s) the mean specific force is the same to a part in 1e5 of g: the
    # running sum keeps every stretch's integral; only a stretch's ends move by the 3 ms stamp.
    t = run.time_s - run.time_s[0]
    rest = t < 45.0
    k = np.searchsorted(same.time_s, run.time_s[rest][[0, -1]])
    mean = run.dv_mps[rest].sum(axis=0) / rest.sum()
    ref = same.dv_mps[k[0] : k[1] + 1].sum(axis=0) / (k[1] - k[0] + 1)
    assert np.all(np.abs(mean - ref) < 1e-5 * 9.8 * run.dt_nominal)


@pytest.mark.slow
def test_the_cli_calibrates_two_files_at_two_rates_and_says_so(tmp_path):
    acc, gyro = _xsens_tables()
    n = len(acc) // 2 * 2
    slow = acc[:n].reshape(-1, 2, 4).mean(axis=1)
    slow[:, 0] = acc[1:n:2, 0] + 0.003
    np.savetxt(tmp_path / "acc50.txt", slow, fmt="%.7e")
    common = ["--conversion", str(REALDATA / "xsens-nominal-values.txt"), "--by-hand", "--profile", "mems"]
    common += ["--latitude", "45.4", "--height", "0", "--json"]
    runner = CliRunner()
    two = runner.invoke(
        main,
        [
            "calibrate",
            str(tmp_path / "acc50.txt"),
            "--gyro-file",
            str(REALDATA / "xsens_gyro.mat.gz"),
            "-o",
            str(tmp_path / "two.toml"),
            *common,
        ],
    )
    one = runner.invoke(
        main,
        [
            "calibrate",
            str(REALDATA / "xsens_acc.mat.gz"),
            "--gyro-file",
            str(REALDATA / "xsens_gyro.mat.gz"),
            "-o",
            str(tmp_path / "one.toml"),
            *common,
        ],
    )
    assert two.exit_code == 0 and one.exit_code == 0, (two.output, one.output)
    assert "two clocks" in two.stderr
    import json

    a, b = json.loads(two.stdout)["parameters"], json.loads(one.stdout)["parameters"]
    # The same samples but the accelerometer's halved rate: every estimate within a fifth of its
    # sigma (the gyro's rows are identical; the rests' ends move by a sample, their noise by
    # averaging pairs).
    for name, p in b.items():
        assert abs(a[name]["value"] - p["value"]) < 0.2 * p["sigma"], (name, a[name], p)
