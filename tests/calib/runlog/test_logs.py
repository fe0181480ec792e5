"""Logs as they come: PSINS text logs, jittering clocks, dropped samples, noise-free runs.

Each damaged run is a good simulated run damaged the way loggers damage
them; the figures compared are the issue's (estimates within 0.1 sigma of
the clean run under jitter, within 0.3 sigma with dropped samples filled,
noise-free within 1/20 of every requirement).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import ARCSEC, W_EARTH
from realdata import PSINS, needs

from calib.fit.sanity import check_saturation
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.runlog import Run, read_run, write_run
from calib.runlog.clock import sample_clock
from calib.sequence.definition import sequence_from_dict
from calib.sequence.kinematics import SimConfig
from calib.sequence.motion import sequence_motion
from calib.sim.gimbal_run import SimOptions, simulate
from calib.sim.truth import write_truth
from seqdesign.cli import main

LAT = math.radians(40.0)
RATE = 200.0  # Hz, the run
DWELL = 40.0  # s; rests 0-40, 49-89, ... (90 deg flips at 10 deg/s take 9 s)
STEPS = [("Z", 90), ("Y", 90), ("X", -90), ("Y", -90), ("Y", -90), ("X", -90), ("Y", -90), ("Z", 90)]


def short_sequence():
    doc = {
        "name": "short",
        "start": ["east", "up", "south"],
        "initial_dwell_s": DWELL,
        "step": [{"axis": a, "angle_deg": g, "dwell_s": DWELL} for a, g in STEPS],
    }
    return sequence_from_dict(doc, "short")


def _simulate(noise: bool, rate: float = RATE, errors: ErrorModel | None = None, setup_deg=(1.0, -2.0, 3.0)):
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=rate)
    errors = ErrorModel.from_table2() if errors is None else errors
    return simulate(
        short_sequence(),
        cfg,
        errors,
        load_profile("navigation"),
        options=SimOptions(setup_rotvec=np.radians(setup_deg), noise=noise, seed=11),
    )


def _calibrate(path: Path, *flags: str) -> tuple[int, str, dict | None]:
    r = CliRunner().invoke(main, ["calibrate", str(path), "-o", str(path) + ".result.toml", "--json", *flags])
    assert "Traceback" not in r.output
    doc = json.loads(r.stdout) if r.exit_code == 0 else None
    return r.exit_code, r.output, doc


def _estimates(doc: dict) -> tuple[np.ndarray, np.ndarray]:
    values = np.array([doc["parameters"][n]["value"] for n in P.NAMES])
    sigma = np.array([doc["parameters"][n]["sigma"] for n in P.NAMES])
    return values, sigma


def _variant(run: Run, **arrays) -> Run:
    fields = dict(
        time_s=run.time_s, dtheta_rad=run.dtheta_rad, dv_mps=run.dv_mps, meta=dict(run.meta), gimbal_deg=None
    )
    fields.update(arrays)
    return Run(**fields)


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    """The clean noisy run, written as NPZ, and its CLI calibration."""
    d = tmp_path_factory.mktemp("noisy")
    run, _ = _simulate(noise=True)
    write_run(run, d / "clean.npz")
    code, out, doc = _calibrate(d / "clean.npz")
    assert code == 0, out
    return run, d, doc


# --------------------------------------------------------------------------
# Clock


def test_sample_clock_measures_uniform_jitter():
    # Jitter uniform in +-a has RMS a / sqrt(3); 20000 samples pin it to 1 %.
    rng = np.random.default_rng(2)
    k = np.arange(20000)
    a = 2e-4
    clock = sample_clock(0.3 + (k + 1) / RATE + rng.uniform(-a, a, k.size), RATE)
    assert np.array_equal(clock.index, k)
    assert clock.jitter_rms_s == pytest.approx(a / math.sqrt(3.0), rel=0.01)
    # The fitted offset and rate err by ~a / sqrt(3 n) = 0.4 % of a: the max lands within 1 %.
    assert 0.99 * a < clock.jitter_max_s <= 1.01 * a
    assert not clock.dropped and not clock.duplicates


def test_sample_clock_separates_a_logger_clock_rate_from_jitter():
    # A host clock 50 ppm slow against the IMU stretches every step by 50 ppm: a trend of
    # 0.25 ms per 1000 s, fitted as a rate; the jitter left is the added +-a (RMS a / sqrt(3)).
    rng = np.random.default_rng(6)
    k = np.arange(100000)
    a = 2e-4
    clock = sample_clock((k + 1) / RATE * (1 + 50e-6) + rng.uniform(-a, a, k.size), RATE)
    assert clock.rate_error_ppm == pytest.approx(50.0, abs=0.1)  # a/sqrt(3)/(T*n^1.5/sqrt(12))
    assert clock.jitter_rms_s == pytest.approx(a / math.sqrt(3.0), rel=0.01)
    assert "+50 ppm" in clock.summary()


def test_sample_clock_names_each_dropped_sample_despite_jitter():
    rng = np.random.default_rng(3)
    k = np.delete(np.arange(1000), [250, 700, 701])
    t = k / RATE + rng.uniform(-2e-4, 2e-4, k.size)
    clock = sample_clock(t, RATE)
    assert [c for _, c in clock.dropped] == [1, 2]
    assert [round(s * RATE) for s, _ in clock.dropped] == [250, 700]


def test_jittering_clock_gives_the_clean_estimates_and_is_reported(noisy):
    run, d, clean = noisy
    rng = np.random.default_rng(4)
    jittered = _variant(run, time_s=run.time_s + rng.uniform(-2e-4, 2e-4, run.n_samples))
    write_run(jittered, d / "jitter.csv")
    code, out, doc = _calibrate(d / "jitter.csv")
    assert code == 0, out
    v0, s0 = _estimates(clean)
    v1, _ = _estimates(doc)
    # The increments are untouched and the time base is rebuilt from the sample count:
    # only the offset (mean of the jitter, ~1e-6 s) differs, far below 0.1 sigma.
    assert np.max(np.abs(v1 - v0) / s0) < 0.1
    assert doc["clock"]["jitter_max_s"] == pytest.approx(2e-4, rel=0.01)
    assert doc["clock"]["jitter_rms_s"] == pytest.approx(2e-4 / math.sqrt(3), rel=0.02)
    assert f"jitters by {1e3 * doc['clock']['jitter_rms_s']:.3g} ms RMS" in out


# --------------------------------------------------------------------------
# Dropped samples


@pytest.fixture(scope="module")
def dropped(noisy):
    run, d, _ = noisy
    # Two single samples lost at rest, in the first and second rests (0-40 s, 49-89 s).
    lost = [int(20.0 * RATE), int(70.0 * RATE)]
    keep = np.ones(run.n_samples, dtype=bool)
    keep[lost] = False
    damaged = _variant(run, time_s=run.time_s[keep], dtheta_rad=run.dtheta_rad[keep], dv_mps=run.dv_mps[keep])
    write_run(damaged, d / "dropped.csv")
    return d / "dropped.csv", run.time_s[lost]


def test_dropped_samples_are_refused_naming_both(dropped):
    path, lost_t = dropped
    code, out, _ = _calibrate(path)
    assert code == 2
    assert "2 sample(s) dropped" in out and "--allow-gaps" in out
    assert "every one where the IMU is still" in out  # both lost at rest: the flag will do
    for t in lost_t:  # each named by the time of the lost sample
        assert f"1 at t = {t:.6g} s" in out


def test_allow_gaps_fills_samples_lost_at_rest(noisy, dropped):
    _, _, clean = noisy
    code, out, doc = _calibrate(dropped[0], "--allow-gaps")
    assert code == 0, out
    v0, s0 = _estimates(clean)
    v1, _ = _estimates(doc)
    # A filled sample differs from the lost one by one sample's noise (the mean of its
    # neighbours is the Earth rate and gravity through the IMU errors): the 0.3 sigma.
    assert np.max(np.abs(v1 - v0) / s0) < 0.3
    assert doc["fit"]["chi2_per_dof"] < 1.2
    assert len(doc["clock"]["dropped"]) == 2


def test_allow_gaps_refuses_a_sample_lost_in_a_flip(noisy, tmp_path):
    run, _, _ = noisy
    k = int(44.0 * RATE)  # inside the first flip (40-49 s)
    keep = np.ones(run.n_samples, dtype=bool)
    keep[k] = False
    write_run(
        _variant(run, time_s=run.time_s[keep], dtheta_rad=run.dtheta_rad[keep], dv_mps=run.dv_mps[keep]),
        tmp_path / "flip.npz",
    )
    code, out, _ = _calibrate(tmp_path / "flip.npz", "--allow-gaps")
    assert code == 2 and "while the IMU turns" in out and "t = 44" in out
    assert not (tmp_path / "flip.npz.result.toml").exists()


# --------------------------------------------------------------------------
# Noise-free runs and saturation


def _exact_simulator_log(run: Run) -> Run:
    """What an exact simulator writes: 10 significant digits, every sample of a rest the same bits.

    At rest the body is fixed to the Earth, so the true increments are constant;
    ours differ from sample to sample by float rounding (1e-16 relative), and
    10 digits change them by 5e-11 relative: both far below 1/20 of any
    requirement, so the truth still holds.
    """
    dt = np.diff(np.concatenate([[0.0], run.time_s]))
    moving = sequence_motion(short_sequence(), run.time_s, dt)
    dtheta = np.array([float(f"{v:.10g}") for v in run.dtheta_rad.ravel()]).reshape(-1, 3)
    dv = np.array([float(f"{v:.10g}") for v in run.dv_mps.ravel()]).reshape(-1, 3)
    edges = np.flatnonzero(np.diff(np.concatenate([[1], moving.astype(np.int8), [1]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        dtheta[a:b] = dtheta[a]
        dv[a:b] = dv[a]
    return _variant(run, dtheta_rad=dtheta, dv_mps=dv)


def _longest_run_at_extreme(x: np.ndarray) -> int:
    at = np.abs(x) == np.max(np.abs(x))
    edges = np.flatnonzero(np.diff(np.concatenate([[0], at.astype(np.int8), [0]])))
    return int(np.max(edges[1::2] - edges[::2]))


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
@pytest.mark.parametrize("case", ["simulated", "exact-table2", "exact-level"])
def test_noise_free_run_calibrates_through_the_cli(tmp_path, suffix, case):
    if case == "exact-level":  # no mounting error, no errors: Y exactly vertical at rest
        run, truth = _simulate(noise=False, rate=50.0, errors=ErrorModel.zero(), setup_deg=(0.0, 0.0, 0.0))
    else:
        run, truth = _simulate(noise=False, rate=50.0)
    if case != "simulated":
        run = _exact_simulator_log(run)
        assert np.all(run.dv_mps[100] == run.dv_mps[101])
    if case == "exact-level":
        # The log: a channel repeats its extreme for a whole rest (2000 samples).
        assert max(_longest_run_at_extreme(run.dv_mps[:, i]) for i in range(3)) >= 2000
    path = tmp_path / f"run{suffix}"
    write_run(run, path)
    write_truth(path.with_name("run.truth.toml"), truth)
    code, out, doc = _calibrate(path)
    assert code == 0, out
    # Without noise the residual vanishes at the truth: the 1/20 of each requirement.
    for name, e in doc["parameters"].items():
        assert abs(e["error"]) < e["requirement"] / 20.0, name


def test_quantised_channel_repeating_its_rest_value_is_not_saturation():
    # A coarse accelerometer at rest: z reads the same count (its extreme) throughout,
    # x and y toggle between counts. Not clipped: z reads what it always reads.
    rng = np.random.default_rng(5)
    q = 125e-6 * 9.78  # PSINS's 125 ug*s count
    dv = np.round(rng.normal([0.0, 0.0, 9.78 * 0.01], 3e-4, (5000, 3)) / q) * q
    dv[:, 2] = 80 * q
    check_saturation(np.zeros((5000, 3)), dv, "run")


def test_gyro_clipped_in_a_flip_is_saturation():
    run, _ = _simulate(noise=True, rate=50.0)
    dtheta = run.dtheta_rad.copy()
    x = dtheta[:, 0]
    limit = 0.95 * np.max(np.abs(x))
    np.clip(x, -limit, limit, out=x)  # a range below the flip rate (plus its noise)
    from calib.errors import CalibError

    with pytest.raises(CalibError, match="dtheta_x is stuck at .* its extreme"):
        check_saturation(dtheta, run.dv_mps, "run")


# --------------------------------------------------------------------------
# PSINS text logs


def _psins_text(rows: list[str], header2: str = "34.2 108.9 380 0 10 9.78") -> str:
    return (
        "\n".join(
            [
                "% PSINS-format SIMU log file.",
                "% comment",
                "",
                "0 0 -90.6 0 0 0",
                header2,
                "0.1 0.1 0.1 125 125 125",
                *rows,
            ]
        )
        + "\n"
    )


def test_psins_counts_are_scaled_to_si(tmp_path):
    path = tmp_path / "log.imu"
    path.write_text(_psins_text(["10 0 -5 3 0 80", "0 2 0 0 -1 81", "1 1 1 0 0 80"]))
    run = read_run(path)
    # 0.1 arcsec and 125 ug*s (ug = 1e-6 of the header's g) per count; 10 ms samples.
    assert run.dtheta_rad[0] == pytest.approx(np.array([1.0, 0.0, -0.5]) * ARCSEC)
    assert run.dv_mps[0] == pytest.approx(np.array([3, 0, 80]) * 125e-6 * 9.78)
    assert run.time_s == pytest.approx([0.01, 0.02, 0.03])
    assert (run.latitude_deg, run.height_m, run.sample_rate_hz, run.gravity_mps2) == pytest.approx(
        (34.2, 380.0, 100.0, 9.78)
    )


@pytest.mark.parametrize(
    "text, parts",
    [
        (_psins_text(["1 2 3 4 5 6", "1 2 3 4 5"]), ["line 8", "not six counts"]),
        (_psins_text(["1 2 3 4 5 6", "1 2 3 4 5 6.5"]), ["line 8", "not an integer count"]),
        (
            _psins_text(["1 2 3 4 5 6", "1 2 3 4 5 6"], header2="34.2 108.9 380 0 10"),
            ["line 5", "header row", "6 numbers"],
        ),
        (
            _psins_text(["1 2 3 4 5 6", "1 2 3 4 5 6"], header2="34.2 108.9 380 0 0 9.78"),
            ["line 5", "must be positive"],
        ),
    ],
)
def test_psins_malformed_logs_are_refused_through_the_cli(tmp_path, text, parts):
    path = tmp_path / "bad.imu"
    path.write_text(text)
    r = CliRunner().invoke(main, ["calibrate", str(path), "-o", str(tmp_path / "r.toml")])
    assert r.exit_code == 2 and "Traceback" not in r.output
    for part in ["bad.imu", *parts]:
        assert part in r.output, (part, r.output)
    assert not (tmp_path / "r.toml").exists()


@needs(PSINS)
def test_psins_laser_gyro_log_sees_the_earth_rate_within_its_sway():
    run = read_run(PSINS)
    assert run.n_samples == 184718 and run.sample_rate_hz == 100.0
    T = run.duration_s
    w = run.dtheta_rad.sum(axis=0) / T
    up = run.dv_mps.sum(axis=0) / np.linalg.norm(run.dv_mps.sum(axis=0))
    vertical = w @ up
    horizontal = np.linalg.norm(w - vertical * up)
    # The mean rate is the Earth rate plus (sway angle at the end - at the start) / T;
    # that angle change is at most the peak-to-peak of the angle about the mean-rate line.
    t = np.cumsum(np.full(run.n_samples, run.dt_nominal))
    sway = np.cumsum(run.dtheta_rad, axis=0) - np.outer(t, w)
    bound = np.linalg.norm(np.ptp(sway, axis=0)) / T
    bias = 0.01 * math.pi / 180 / 3600  # a navigation-grade gyro bias, 0.01 deg/h
    L = math.radians(run.latitude_deg)
    assert abs(vertical - W_EARTH * math.sin(L)) < bound + bias
    assert abs(horizontal - W_EARTH * math.cos(L)) < bound + bias


@needs(PSINS)
def test_psins_laser_gyro_log_is_refused_as_never_rotating(tmp_path):
    r = CliRunner().invoke(main, ["calibrate", str(PSINS), "-o", str(tmp_path / "r.toml")])
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert "never rotates" in r.output and "sways by" in r.output and "arcsec" in r.output
    assert "too short to align" not in r.output
    assert not (tmp_path / "r.toml").exists()
