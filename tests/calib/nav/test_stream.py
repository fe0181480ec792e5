"""Long runs (issue 18): the streamed pass is the same navigation, the streamed fit the same fit,
the streamed simulator the same simulator."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from calib.errors import CalibError
from calib.fit.estimator import fit_run
from calib.fit.options import FitOptions
from calib.fit.start import coarse_alignment
from calib.model import optional_terms as X
from calib.model.error_model import ErrorModel
from calib.nav import chunk_pass as stream, earth
from calib.nav.jacobian import default_grid, extra_inputs, sample_layout, trajectory_moments
from calib.nav.site import Site
from calib.nav.strapdown import navigate, sample_intervals
from calib.nav.transform import quat_mult
from calib.noise.profiles import load_profile
from calib.runlog import read_run
from calib.sequence.definition import load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sequence.motion import detect_motion
from calib.sim.gimbal_run import SimOptions, simulate
from calib.sim.to_disk import simulate_to_file
from seqdesign.cli import main

LAT = math.radians(40.0)
SETUP = np.radians([1.0, -2.0, 3.0])
# A real unit's terms, each well above its sigma, so that every compensation path is exercised.
EXTRA = X.OptionalTermValues.from_units({"rxx": 3.0, "ryy": -2.0, "k2z": 20.0, "dt_ga": 0.5})


@pytest.fixture(scope="module")
def paper():
    return load_sequence("paper-9pos")


def _run(paper, rate_hz, noise, extra=None, seed=11):
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=rate_hz)
    run, _ = simulate(
        paper,
        cfg,
        ErrorModel.from_table2(),
        load_profile("navigation"),
        options=SimOptions(setup_rotvec=SETUP, noise=noise, seed=seed),
        extra=extra,
    )
    return run, cfg


def test_blocked_scan_is_the_sequential_product():
    # Quaternion products are associative: any bracketing gives the same product up to
    # rounding, ~1e-16 per product, so 1e-12 over 1000 products is generous.
    rng = np.random.default_rng(0)
    q = rng.standard_normal((1000, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    expected = q.copy()
    for k in range(1, len(q)):
        expected[k] = quat_mult(expected[k - 1], q[k])
    assert np.allclose(stream.quat_scan(q), expected, rtol=0, atol=1e-12)


def test_streamed_pass_is_the_whole_run_navigation(paper):
    # Chunks of ~300 samples cut the run into 200+ pieces, so the attitude, velocity, coning
    # and lever-arm context are carried across chunk ends hundreds of times. The pass is
    # the same arithmetic re-associated: differences are rounding, ~n eps of each quantity.
    run, cfg = _run(paper, 50.0, noise=True, extra=EXTRA)
    extras = X.OptionalTerms(X.parse_groups("all"))
    dt = sample_intervals(run.time_s)
    seg = detect_motion(run.dtheta_rad, dt)
    grid = default_grid(seg.moving, 50.0)
    first = slice(0, seg.first_rest_end)
    C0 = coarse_alignment(run.dtheta_rad[first], run.dv_mps[first], dt[first])
    t0 = run.time_s[0] - dt[0]
    nav = navigate(run.dtheta_rad, run.dv_mps, run.time_s, C0, Site(LAT, cfg.gravity), t0=t0)
    t_nav = np.concatenate([[t0], run.time_s])
    layout = sample_layout(nav.C_b_n, t_nav, grid)
    moments = trajectory_moments(nav.C_b_n, run.dtheta_rad, run.dv_mps, t_nav, grid, layout)
    extra = extra_inputs(run.dtheta_rad, run.dv_mps, layout, extras, Site(LAT, cfg.gravity))
    C_mid = 0.5 * (nav.C_b_n[1:] + nav.C_b_n[:-1])
    turn = X.earth_turn(C_mid, earth.omega_ie_n(LAT), dt)

    cuts = stream.chunk_cuts(grid, 300)
    passes = stream.Passes(
        lambda: stream.array_chunks(run.time_s, run.dtheta_rad, run.dv_mps, t0, cuts), grid, t0
    )
    estimate = stream.Estimate(np.zeros(21), C0, extras, np.zeros(extras.n), turn)
    out = stream.navigate_pass(passes, Site(LAT, cfg.gravity), estimate)

    def rel(a, b):
        return np.abs(a - b).max() / np.abs(b).max()

    assert rel(out.y, nav.v_n[grid.bounds]) < 1e-11
    assert rel(out.t_bounds, t_nav[grid.bounds]) < 1e-15
    assert rel(out.moments, moments) < 1e-12
    assert rel(out.extra, extra) < 1e-12
    assert rel(out.C_mid, nav.C_b_n[(grid.bounds[:-1] + grid.bounds[1:]) // 2]) < 1e-12
    assert rel(out.turn, turn) < 1e-12


@pytest.mark.slow
@pytest.mark.parametrize("noise", [False, True], ids=["noise-free", "noisy"])
def test_streamed_fit_equals_renavigating_fit(paper, noise):
    # The reference loop re-navigates the whole run at every iteration until a step is below
    # tol_sigma; the streamed loop stops navigating once the next step is bounded below it.
    # Each then sits within tol_sigma of the same fixed point, so they agree to tol_sigma.
    run, cfg = _run(paper, 50.0, noise)
    prof = load_profile("navigation")
    args = (run, Site(LAT, cfg.gravity), prof)
    ref = fit_run(*args, options=FitOptions(renavigate="always"))
    fit = fit_run(*args)
    assert ref.converged and fit.converged
    assert np.all(np.abs(fit.values - ref.values) <= 1e-3 * ref.sigma)
    # Same Jacobians along the same trajectories: the sigmas agree to rounding.
    assert np.allclose(fit.sigma, ref.sigma, rtol=1e-9)
    assert fit.iterations <= ref.iterations


@pytest.mark.slow
def test_streamed_fit_with_a_real_units_terms_equals_renavigating_fit(paper):
    run, cfg = _run(paper, 50.0, noise=True, extra=EXTRA)
    prof, extras = load_profile("navigation"), X.OptionalTerms(X.parse_groups("all"))
    args = (run, Site(LAT, cfg.gravity), prof)
    ref = fit_run(*args, options=FitOptions(extras=extras, renavigate="always"))
    fit = fit_run(*args, options=FitOptions(extras=extras))
    assert ref.converged and fit.converged
    assert np.all(np.abs(fit.values - ref.values) <= 1e-3 * ref.sigma)
    assert np.all(np.abs(fit.extra_values - ref.extra_values) <= 1e-3 * ref.extra_sigma)


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_streamed_simulation_is_the_simulation(paper, tmp_path, suffix):
    # Without noise both evaluate the same closed-form integrals on the same sample ends:
    # bit for bit, whatever the window (here 1000 samples: windows end inside flips).
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=20.0)
    prof = load_profile("navigation")
    run, _ = simulate(
        paper, cfg, ErrorModel.from_table2(), prof, options=SimOptions(setup_rotvec=SETUP, noise=False)
    )
    path = tmp_path / f"run{suffix}"
    n, truth = simulate_to_file(
        path,
        paper,
        cfg,
        ErrorModel.from_table2(),
        prof,
        SimOptions(setup_rotvec=SETUP, noise=False),
        window=1000,
    )
    back = read_run(path)
    assert n == len(run.time_s)
    assert np.array_equal(back.time_s, run.time_s)
    assert np.array_equal(back.dtheta_rad, run.dtheta_rad)
    assert np.array_equal(back.dv_mps, run.dv_mps)
    assert back.meta == run.meta
    assert not list(tmp_path.glob(".*tmp"))


def test_streamed_simulation_noise_has_the_profiles_density(paper, tmp_path):
    # The noise is ARW sqrt(dt) and VRW sqrt(dt) per sample. With 3 x 34k samples per sensor
    # the sample standard deviation has a relative spread of 1/sqrt(2 n) = 0.2 %: 2 % is
    # ten of those.
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=20.0)
    prof = load_profile("tactical")
    clean, _ = simulate(
        paper, cfg, ErrorModel.from_table2(), prof, options=SimOptions(setup_rotvec=SETUP, noise=False)
    )
    path = tmp_path / "run.npz"
    draw = SimOptions(setup_rotvec=SETUP, noise=True, seed=3)
    simulate_to_file(path, paper, cfg, ErrorModel.from_table2(), prof, draw, window=5000)
    run = read_run(path)
    dt = 1.0 / cfg.sample_rate_hz
    gyro = np.std(run.dtheta_rad - clean.dtheta_rad) / (prof.arw * math.sqrt(dt))
    accel = np.std(run.dv_mps - clean.dv_mps) / (prof.vrw * math.sqrt(dt))
    assert abs(gyro - 1.0) < 0.02 and abs(accel - 1.0) < 0.02


def test_cli_simulate_stream_refuses_gauss_markov_and_unknown_suffix(tmp_path):
    runner = CliRunner()
    out = tmp_path / "run.npz"
    r = runner.invoke(main, ["simulate-stream", "paper-9pos", "-o", str(out), "--profile", "navigation-gm"])
    assert r.exit_code == 2
    assert "Gauss-Markov" in r.output and "Traceback" not in r.output
    assert not out.exists() and not list(tmp_path.iterdir())
    r = runner.invoke(main, ["simulate-stream", "paper-9pos", "-o", str(tmp_path / "run.txt")])
    assert r.exit_code == 2
    assert "unknown run format" in r.output
    assert not list(tmp_path.iterdir())


def test_cli_simulate_stream_writes_run_and_truth(tmp_path):
    out = tmp_path / "run.npz"
    r = CliRunner().invoke(
        main,
        [
            "simulate-stream",
            "paper-9pos",
            "-o",
            str(out),
            "--table2",
            "--sample-rate-hz",
            "10",
            "--seed",
            "1",
            "--json",
        ],
    )
    assert r.exit_code == 0, r.output
    run = read_run(out)
    # 1692 s at 10 Hz.
    assert run.n_samples == 16920 and (tmp_path / "run.truth.toml").exists()


@pytest.fixture(scope="module")
def short_files(paper, tmp_path_factory):
    """A 50 Hz noisy run as NPZ and CSV, and its in-memory fit."""
    folder = tmp_path_factory.mktemp("chunks")
    run, cfg = _run(paper, 50.0, noise=True)
    from calib.runlog import write_run

    paths = [folder / "run.npz", folder / "run.csv"]
    for p in paths:
        write_run(run, p)
    fit = fit_run(run, Site(LAT, cfg.gravity), load_profile("navigation"))
    return paths, fit, cfg


@pytest.mark.slow
def test_calibrating_from_disk_in_chunks_equals_calibrating_in_memory(short_files):
    # Same samples, same chunk cuts at interval ends, same passes: the same numbers,
    # whatever the reading block (here 7777 rows, which never falls on a cut).
    from calib.fit.chunked import fit_file
    from calib.nav.site import Site

    paths, fit, cfg = short_files
    for p in paths:
        streamed = fit_file(p, Site(LAT, cfg.gravity), load_profile("navigation"), rows=7777)
        assert np.array_equal(streamed.values, fit.values)
        assert np.array_equal(streamed.sigma, fit.sigma)


@pytest.mark.slow
def test_cli_calibrate_stream_agrees_with_calibrate_and_takes_a_sequence(short_files, tmp_path):
    # One entry (calib.calibration.entry.calibrate) for both readings: the same estimator on the same
    # samples gives the same estimates, to 1e-9 sigma, with or without a sequence file (whose
    # flips then mark where the run turns, in chunks as in memory).
    paths, _, _ = short_files
    runner = CliRunner()
    for sequence in ([], ["--sequence", "paper-9pos"]):
        out = {}
        for mode in ("--no-stream", "--stream"):
            r = runner.invoke(
                main, ["calibrate", str(paths[0]), *sequence, mode, "--json", "-o", str(tmp_path / "r.toml")]
            )
            assert r.exit_code == 0, r.output
            out[mode] = json.loads(r.stdout)
        assert "clock" in out["--no-stream"] and "clock" not in out["--stream"]
        for name, p in out["--no-stream"]["parameters"].items():
            streamed = out["--stream"]["parameters"][name]
            assert abs(streamed["value"] - p["value"]) <= 1e-9 * p["sigma"], name
            assert streamed["sigma"] == pytest.approx(p["sigma"], rel=1e-9), name


def test_cli_calibrate_stream_refuses_what_it_cannot_read_in_chunks(short_files, tmp_path):
    # Gaps need the whole time column fitted: one line naming why, exit 2, nothing written.
    paths, _, _ = short_files
    r = CliRunner().invoke(
        main, ["calibrate", str(paths[0]), "--stream", "--allow-gaps", "-o", str(tmp_path / "r.toml")]
    )
    assert r.exit_code == 2 and "(the CLI's --allow-gaps) cannot be read chunk by chunk" in r.output
    assert "Traceback" not in r.output and not (tmp_path / "r.toml").exists()


def test_chunks_read_back_the_samples(short_files):
    from calib.runlog import read_chunks

    paths, _, _ = short_files
    whole = read_run(paths[0])
    for p in paths:
        blocks = list(read_chunks(p, rows=1000))
        assert all(len(b[0]) <= 1000 for b in blocks)
        for i, arr in enumerate((whole.time_s, whole.dtheta_rad, whole.dv_mps)):
            assert np.array_equal(np.concatenate([b[i] for b in blocks]), arr)


def test_cli_calibrate_stream_refuses_a_gap_and_a_log_without_rotation(paper, tmp_path):
    from calib.runlog import write_run

    run, cfg = _run(paper, 10.0, noise=False)
    keep = np.ones(run.n_samples, dtype=bool)
    keep[500:510] = False  # 1 s missing at 10 Hz
    gappy = type(run)(run.time_s[keep], run.dtheta_rad[keep], run.dv_mps[keep], run.meta)
    write_run(gappy, tmp_path / "gap.npz")
    r = CliRunner().invoke(main, ["calibrate-stream", str(tmp_path / "gap.npz")])
    assert r.exit_code == 2 and "time steps by 1.1 s at sample 500" in r.output
    assert "Traceback" not in r.output and not (tmp_path / "gap.result.toml").exists()
    still = type(run)(run.time_s[:3000], run.dtheta_rad[:3000] * 0.0, run.dv_mps[:3000], run.meta)
    write_run(still, tmp_path / "still.csv")
    r = CliRunner().invoke(main, ["calibrate-stream", str(tmp_path / "still.csv")])
    assert r.exit_code == 2 and "no rotation found" in r.output
    r = CliRunner().invoke(main, ["calibrate-stream", str(tmp_path / "missing.npz")])
    assert r.exit_code == 2 and "no such file" in r.output


def test_cli_calibrate_stream_refuses_a_damaged_archive_and_a_missing_rate(paper, tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"PK\x03\x04 not really a zip")
    r = CliRunner().invoke(main, ["calibrate-stream", str(bad)])
    assert r.exit_code == 2 and "not a readable NPZ run log" in r.output
    assert "Traceback" not in r.output
    from calib.runlog import write_run

    run, _ = _run(paper, 10.0, noise=False)
    write_run(run, tmp_path / "run.csv")
    text = (tmp_path / "run.csv").read_text().replace("# sample_rate_hz: 10.0\n", "")
    (tmp_path / "norate.csv").write_text(text)
    r = CliRunner().invoke(main, ["calibrate-stream", str(tmp_path / "norate.csv")])
    assert r.exit_code == 2 and "sample_rate_hz" in r.output
    assert not (tmp_path / "norate.result.toml").exists()


def test_streamed_simulation_refuses_the_draws_it_does_not_write(paper, tmp_path):
    # Flip errors and a drawn mounting need the whole run: refused, and no file is left behind.
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=20.0)
    for draw in (SimOptions(flip_error_deg=0.5), SimOptions(random_setup_deg=3.0)):
        with pytest.raises(CalibError, match="window at a time"):
            simulate_to_file(
                tmp_path / "run.npz", paper, cfg, ErrorModel.zero(), load_profile("navigation"), draw
            )
    assert not list(tmp_path.iterdir())
