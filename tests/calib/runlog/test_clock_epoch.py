"""A logger's time column from an epoch (UNIX time, 1.7e9 s) calibrates as one from 0.

A clean simulated navigation run is written as a logger CSV without a
``sample_rate_hz`` line, its time column from 0 in s, from 1.7e9 s printed
to 1 us, and in integer ms (from 0 and from the epoch). The rate then comes
from the stamps (:func:`calib.runlog.clock.stamps_rate`) and epoch stamps are
re-based to their first (:func:`calib.runlog.clock.uniform_time`). Before
both, the 1.7e9 s file was read at 100.000095 Hz (the median step) on a time
base whose intervals carried 24 ppm of float rounding, and its estimates moved
by 2.8 sigma.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from calib.calibration.entry import calibrate
from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.runlog import read_run
from calib.runlog.clock import EPOCH_S, stamps_rate
from calib.sequence.definition import load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate

RATE_HZ = 100.0
EPOCH = 1_700_000_000
PREAMBLE = "# latitude_deg: 45\n# height_m: 100\n"
COLUMNS = "gyro_x_radps,gyro_y_radps,gyro_z_radps,accel_x_mps2,accel_y_mps2,accel_z_mps2"
# Each case: the time column's name and how a sample count k (the stamp of k / rate s) is printed.
CASES = {
    "s from 0": ("time_s", lambda k: f"{k / RATE_HZ:.9f}"),
    "s from 1.7e9": ("time_s", lambda k: f"{EPOCH + k / RATE_HZ:.6f}"),
    "ms from 0": ("time_ms", lambda k: str(10 * k)),
    "ms from 1.7e12": ("time_ms", lambda k: str(1000 * EPOCH + 10 * k)),
}


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    """The clean paper-9pos run (noise on, seed 7) as a logger CSV, once per time column."""
    run, _ = simulate(
        load_sequence("paper-9pos"),
        SimConfig(latitude_rad=math.radians(45.0), height_m=100.0, sample_rate_hz=RATE_HZ),
        ErrorModel.from_table2(),
        load_profile("navigation"),
        options=SimOptions(noise=True, seed=7),
    )
    dt = 1.0 / RATE_HZ
    body = [",".join(map(repr, r)) for r in np.hstack([run.dtheta_rad / dt, run.dv_mps / dt]).tolist()]
    count = np.rint(run.time_s * RATE_HZ).astype(np.int64).tolist()
    folder = tmp_path_factory.mktemp("epoch")
    out = {}
    for i, (case, (name, stamp)) in enumerate(CASES.items()):
        rows = (f"{stamp(k)},{b}" for k, b in zip(count, body, strict=True))
        path = folder / f"case{i}.csv"
        path.write_text(PREAMBLE + f"{name},{COLUMNS}\n" + "\n".join(rows) + "\n")
        out[case] = path
    return out


@pytest.fixture(scope="module")
def results(files) -> dict:
    return {case: calibrate(path, "navigation", stream=False) for case, path in files.items()}


@pytest.mark.parametrize("case", list(CASES)[1:])
def test_estimates_do_not_depend_on_where_the_time_column_starts(results, case):
    ref = results["s from 0"]
    moved = np.abs(results[case].values - ref.values) / ref.sigma
    assert moved.max() < 0.1, f"{case}: {moved.max():.3g} sigma"


@pytest.mark.parametrize("case", list(CASES))
def test_the_stamps_rate_is_the_nominal_rate(files, case):
    run = read_run(files[case])
    assert float(run.meta["sample_rate_hz"]) == RATE_HZ
    # The run's time base has exact intervals, whatever the column's magnitude.
    step = np.diff(run.time_s)
    assert np.ptp(step) < 1e-9 * step[0]
    epoch = case.endswith(("1.7e9", "1.7e12"))
    assert (run.clock.origin_s > EPOCH_S) == epoch
    assert ("re-based" in run.clock.summary()) == epoch
    assert abs(run.time_s[0] - (0.0 if epoch else 0.01)) < 1e-6


def test_stamps_rate_counts_drops_and_fits_a_clock_off_by_ppm():
    rate = 200.0 * (1 + 30e-6)  # a logger clock 30 ppm fast
    k = np.delete(np.arange(100_000), [500, 501, 9000])  # three samples lost
    stamps = np.round(EPOCH + k / rate, 6)  # printed to 1 us
    assert stamps_rate(stamps) == pytest.approx(rate, rel=1e-9)
    # The median step alone is off by the rounding of the stamps.
    assert abs(1.0 / np.median(np.diff(stamps)) / rate - 1) > 1e-6
