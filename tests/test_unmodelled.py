"""Simulated unmodelled terms of a real unit (issue 8, partial): K2 and the time offset."""
from __future__ import annotations

import math

import numpy as np
import pytest

from calib import earth
from calib.errormodel import ErrorModel
from calib.profiles import load_profile
from calib.sequence import load_sequence, timeline
from calib.sim import SimConfig, UnmodelledTerms, simulate
from calib.truth import read_truth, write_truth

LAT = math.radians(40.0)
CFG = SimConfig(latitude_rad=LAT, sample_rate_hz=50.0)
PROFILE = load_profile("navigation")


def _run(unmodelled=None):
    run, truth = simulate(load_sequence("paper-9pos"), CFG, ErrorModel.zero(), PROFILE,
                          noise=False, unmodelled=unmodelled)
    return run, truth


def test_k2_adds_k2_g_squared_on_the_vertical_axis_at_rest():
    # First rest: Y up (f_y = g), X and Z level (f = 0). k2 in ug/g^2 -> k2 * 1e-6 * g^2 / g0.
    k2 = np.array([100.0, 200.0, 300.0])
    base, _ = _run()
    run, _ = _run(UnmodelledTerms.from_units(k2, 0.0))
    g = earth.gravity(LAT)
    rest = slice(10, int(170 * CFG.sample_rate_hz))
    dt = 1.0 / CFG.sample_rate_hz
    extra = (run.dv_mps[rest] - base.dv_mps[rest]).mean(axis=0) / dt
    expected_y = k2[1] * 1e-6 / 9.80665 * g ** 2
    assert extra[1] == pytest.approx(expected_y, rel=1e-9)
    # Level axes see only the Earth's turn in f (1e-20 m/s^2): nothing measurable.
    assert abs(extra[0]) < 1e-12 and abs(extra[2]) < 1e-12


def test_time_offset_shifts_the_accelerometer_windows():
    # Over a flip, shifting every accelerometer window back by d changes the summed dv by
    # d (f_before - f_after) in the body frame (the windows telescope); at rest nothing moves.
    d = 1e-3
    base, _ = _run()
    run, _ = _run(UnmodelledTerms.from_units((0.0, 0.0, 0.0), d * 1e3))
    tl = timeline(load_sequence("paper-9pos"))
    fs = CFG.sample_rate_hz
    g = earth.gravity(LAT)
    f_n = np.array([0.0, 0.0, g])
    for k in range(len(tl.t0)):
        if tl.rate[k] == 0.0:
            continue
        a, b = int((tl.t0[k] - 2) * fs), int((tl.t1[k] + 2) * fs)
        diff = (run.dv_mps[a:b] - base.dv_mps[a:b]).sum(axis=0)
        f_before = tl.C0[k].T @ f_n
        f_after = tl.C0[k + 1].T @ f_n
        # The Earth's turn adds ~g * w_ie * d ~ 7e-10 m/s: 1e-8 is far above it, far below g d.
        assert np.allclose(diff, d * (f_before - f_after), atol=1e-8)
    rest = slice(int(20 * fs), int(170 * fs))
    assert np.allclose(run.dv_mps[rest], base.dv_mps[rest], atol=1e-12)


def test_truth_records_the_unmodelled_terms(tmp_path):
    _, truth = _run(UnmodelledTerms.from_units((20.0, -10.0, 5.0), 0.5))
    write_truth(tmp_path / "t.toml", truth)
    back = read_truth(tmp_path / "t.toml").unmodelled
    assert back.to_units() == {"k2_ug_per_g2": [20.0, -10.0, 5.0], "time_offset_ms": 0.5}
    _, plain = _run()
    write_truth(tmp_path / "p.toml", plain)
    assert read_truth(tmp_path / "p.toml").unmodelled is None
