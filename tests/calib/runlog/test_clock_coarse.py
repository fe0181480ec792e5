"""Stamps written coarser than the samples come: a 200 Hz IMU stamped to 10 ms.

Half such stamps repeat the one before and the rest step by two periods, while every
sample is there. The rows are then counted (:mod:`calib.runlog.coarse`): no sample is
read as repeated or lost, a hole longer than the stamps' resolution is still found, and
the same samples calibrate as they do under exact stamps.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from calib.hand.plan import random_hand_plan
from calib.hand.simulate import simulate_by_hand
from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.runlog import read_run
from calib.runlog.clock import sample_clock, stamps_rate
from calib.runlog.coarse import duplicate_rows
from calib.sequence.kinematics import SimConfig
from seqdesign.cli import main

RATE_HZ = 200.0
PERIOD = 1.0 / RATE_HZ
TICK = 0.01  # the stamps' resolution: two periods


def coarse(true_s: np.ndarray) -> np.ndarray:
    """Stamps printed to 10 ms (rounded down, as a host's %.2f of its clock in s)."""
    return np.floor(true_s / TICK + 1e-9) * TICK


def _true_times(n: int, ppm: float) -> np.ndarray:
    # An IMU clock `ppm` slow against the host's, from an epoch of 1.67e9 s (a UNIX time).
    return 1.67e9 + np.arange(n) * PERIOD * (1.0 + ppm * 1e-6)


def test_stamps_coarser_than_the_period_count_every_row_as_a_sample():
    n = 60_000  # five minutes
    stamps = coarse(_true_times(n, 925.0))
    assert np.mean(np.diff(stamps) == 0.0) > 0.4  # half the stamps repeat: the old step rule refused them
    clock = sample_clock(stamps, RATE_HZ)
    assert not clock.dropped and not clock.duplicates
    np.testing.assert_array_equal(clock.index, np.arange(n))
    assert clock.rule == "count" and math.isclose(clock.resolution_s, TICK, rel_tol=1e-6)
    assert "stamps written to 10 ms" in clock.summary()
    assert math.isclose(clock.as_dict()["resolution_s"], TICK, rel_tol=1e-6)
    # The rate from the stamps alone: the rows' slope, within the 10 ms tick over 300 s (33 ppm).
    true_rate = RATE_HZ / (1.0 + 925e-6)
    assert abs(stamps_rate(stamps) / true_rate - 1.0) < 5e-5


@pytest.mark.parametrize("lost", [4, 10])
def test_a_hole_longer_than_the_stamps_resolution_is_found(lost):
    n = 20_000
    true_s = _true_times(n + lost, 0.0)
    keep = np.delete(np.arange(n + lost), np.arange(9_000, 9_000 + lost))
    clock = sample_clock(coarse(true_s[keep]), RATE_HZ)
    assert len(clock.dropped) == 1
    at_s, count = clock.dropped[0]
    # Stamps to two periods place the hole to one period either way, its start to a tick.
    assert abs(count - lost) <= 1
    assert abs((at_s + clock.origin_s) - true_s[9_000]) <= TICK + 2 * PERIOD


def test_a_quantised_sample_equal_to_the_one_before_is_a_sample_a_logger_s_copy_is_not():
    rng = np.random.default_rng(4)
    n = 20_000
    stamps = coarse(_true_times(n, 0.0))
    # A quantised unit at rest: one count of noise, so whole rows repeat now and then.
    dtheta = np.rint(rng.normal(0.0, 0.6, (n, 3))) * 1e-6
    dv = np.rint(rng.normal(0.0, 0.6, (n, 3))) * 1e-4
    chance = duplicate_rows(stamps, dtheta, dv, PERIOD)
    assert not chance.any()
    # Noise that never repeats, 30 rows written twice by the logger (the copy at the same stamp).
    dtheta, dv = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    copies = np.flatnonzero(np.diff(stamps) == 0.0)[::300][:30] + 1
    dtheta[copies], dv[copies] = dtheta[copies - 1], dv[copies - 1]
    found = duplicate_rows(stamps, dtheta, dv, PERIOD)
    np.testing.assert_array_equal(np.flatnonzero(found), copies)


def _imutk_files(tmp_path, stamps, rate, force, time_format: str = "%.2f") -> tuple[str, str]:
    """imu_tk's two files, ``t x y z`` in SI, the time written with ``time_format``."""
    acc, gyro = tmp_path / "acc.txt", tmp_path / "gyro.txt"
    for path, values in ((acc, force), (gyro, rate)):
        np.savetxt(path, np.column_stack([stamps, values]), fmt=[time_format] + ["%.9e"] * 3)
    return str(acc), str(gyro)


def test_imu_tk_files_in_si_with_coarse_stamps_calibrate_as_with_exact_ones(tmp_path):
    plan = random_hand_plan(14, np.random.default_rng(6))
    values = np.zeros(21)
    values[:3], values[12:15] = np.radians(0.3), 0.05  # MEMS-sized gyro and accelerometer biases
    cfg = SimConfig(latitude_rad=math.radians(45.0), height_m=0.0, sample_rate_hz=RATE_HZ)
    run, _ = simulate_by_hand(plan, cfg, ErrorModel(values), load_profile("mems"), seed=3)
    rate, force = run.dtheta_rad / PERIOD, run.dv_mps / PERIOD
    true_s = 1.67e9 + run.time_s
    outputs = {}
    for name, stamps, written in (("exact", true_s, "%.6f"), ("coarse", coarse(true_s), "%.2f")):
        folder = tmp_path / name
        folder.mkdir()
        acc, gyro = _imutk_files(folder, stamps, rate, force, written)
        args = [acc, "--gyro-file", gyro, "--conversion", "si", "--by-hand", "--profile", "mems"]
        args += ["--latitude", "45", "--height", "0", "--json", "-o", str(folder / "r.toml")]
        got = CliRunner().invoke(main, ["calibrate", *args])
        assert got.exit_code == 0, got.output
        outputs[name] = got.stdout
    exact, rough = (json.loads(outputs[k])["parameters"] for k in ("exact", "coarse"))
    e = np.array([p["value"] for p in exact.values()])
    c = np.array([rough[name]["value"] for name in exact])
    s = np.array([p["sigma"] for p in exact.values()])
    # The same samples, counted alike: the same estimates within the 0.01 sigma.
    assert np.max(np.abs(c - e) / s) < 0.01


def test_imu_tk_files_already_in_si_without_a_conversion_are_told_the_word_si(tmp_path):
    t = np.arange(1, 201) * 0.01
    force = np.tile([0.1, -0.2, 9.8], (200, 1))
    acc, gyro = _imutk_files(tmp_path, t, np.zeros((200, 3)), force)
    got = CliRunner().invoke(
        main,
        [
            "calibrate",
            acc,
            "--gyro-file",
            gyro,
            "--by-hand",
            "--profile",
            "mems",
            "--latitude",
            "45",
            "--height",
            "0",
        ],
    )
    assert got.exit_code != 0 and "Traceback" not in got.output
    assert "as if already in m/s^2" in got.output and "--conversion si" in got.output


@pytest.mark.parametrize(("unit", "per_second", "written"), [("ms", 1e3, "%.3f"), ("ns", 1e9, "%.0f")])
def test_imu_tk_files_whose_time_counts_ms_or_ns_are_read_in_seconds(tmp_path, unit, per_second, written):
    # A ROS stamp in ns, a logger's millis(): 100 Hz is then 1e-7 or 0.1 "Hz" in seconds, no IMU's
    # rate, and only one unit of the four puts it at 1 Hz or more.
    rng = np.random.default_rng(2)
    n = 2_000
    seconds = 1.69e9 + 0.01 * np.arange(n) + rng.uniform(0.0, 2e-4, n)  # host stamps, 0.2 ms jitter
    rate, force = rng.normal(0.0, 0.01, (n, 3)), np.tile([0.1, -0.2, 9.8], (n, 1))
    acc, gyro = _imutk_files(tmp_path, seconds, rate, force, "%.6f")
    base = read_run(acc, gyro_path=gyro, conversion="si", latitude_deg=45.0, height_m=0.0)
    other = tmp_path / unit
    other.mkdir()
    acc, gyro = _imutk_files(other, seconds * per_second, rate, force, written)
    with pytest.warns(UserWarning, match=f"read as {unit}"):
        run = read_run(acc, gyro_path=gyro, conversion="si", latitude_deg=45.0, height_m=0.0)
    # The same samples: the same increments (each over the period the stamps' rate gives, which
    # their rounding to 1 us or 1 ns moves by parts per billion), times within that rounding.
    np.testing.assert_allclose(run.dtheta_rad, base.dtheta_rad, rtol=1e-7)
    np.testing.assert_allclose(run.time_s, base.time_s, atol=2e-6)
    assert abs(run.sample_rate_hz - base.sample_rate_hz) < 1e-6 * base.sample_rate_hz
