"""Analysis: the casadi Jacobian against finite differences, rank, CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from calib.analysis.mounting import analyze
from calib.analysis.nominal import nominal_run
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.nav import earth
from calib.nav.jacobian import N_UNKNOWN, observation_jacobian, state_matrix
from calib.nav.site import Site
from calib.nav.strapdown import navigate
from calib.nav.transform import rotvec_to_dcm
from calib.noise.profiles import load_profile
from calib.noise.whitening import noise_model
from calib.sequence.definition import load_sequence, sequence_from_dict
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate
from seqdesign.cli import main

LAT = math.radians(40.0)
SITE = Site.at(LAT)
SETUP = np.radians([1.0, -2.0, 3.0])
RATE = 50.0  # Hz: the finite difference runs the whole pipeline 48 times


def _observations(seq, values, phi0, t_obs, Phi_vv):
    """Full nonlinear pipeline: simulate (errors injected) -> navigate raw data -> z."""
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=RATE)
    run, _ = simulate(
        seq,
        cfg,
        ErrorModel(values),
        load_profile("navigation"),
        options=SimOptions(setup_rotvec=SETUP, noise=False),
    )
    C_true = rotvec_to_dcm(SETUP) @ seq.C_start
    # C~ = (I - [phi x]) C  <=>  C~ = exp(-[phi x]) C to first order.
    C0 = rotvec_to_dcm(-phi0) @ C_true
    nav = navigate(run.dtheta_rad, run.dv_mps, run.time_s, C0, Site(LAT, cfg.gravity), t0=0.0)
    y = nav.v_n[np.round(t_obs * RATE).astype(int)]
    return y[1:] - np.einsum("kij,kj->ki", Phi_vv, y[:-1])


def test_casadi_jacobian_matches_central_finite_difference():
    """Every column of H equals a central difference of simulate -> navigate to 1e-3 relative."""
    seq = load_sequence("paper-9pos")
    nom = nominal_run(seq, SITE, SETUP)  # the analyser's own sampling and intervals
    t_obs = nom.time_nav[nom.grid.bounds]
    # Every interval end is a multiple of 0.02 s, so the 50 Hz pipeline samples it exactly.
    assert np.allclose(t_obs * RATE, np.round(t_obs * RATE), atol=1e-6)
    Phi_vv = noise_model(state_matrix(SITE), np.diff(t_obs), load_profile("navigation")).Phi_vv
    H = observation_jacobian(nom, SITE, Phi_vv)
    # Steps: the requirement of each parameter (the scale the fit resolves) and
    # 1e-5 rad of initial attitude. Central differences cancel the second order;
    # third-order terms are ~(1e-4 rad)^2 relative, rounding ~1e-16 / 1e-9 m/s.
    steps = np.concatenate([P.REQUIREMENTS_SI, np.full(3, 1e-5)])
    bad = {}
    for j in range(N_UNKNOWN):
        dp = np.zeros(N_UNKNOWN)
        dp[j] = steps[j]
        z_plus = _observations(seq, dp[:21], dp[21:], t_obs, Phi_vv)
        z_minus = _observations(seq, -dp[:21], -dp[21:], t_obs, Phi_vv)
        fd = (z_plus - z_minus) / (2 * steps[j])
        rel = np.linalg.norm(H[:, :, j] - fd) / np.linalg.norm(fd)
        if rel > 1e-3:
            bad[j] = rel
    assert not bad, bad


def test_paper_sequence_is_full_rank_and_matches_physical_bound():
    seq = load_sequence("paper-9pos")
    prof = load_profile("navigation")
    obs = analyze(seq, prof, SITE)
    assert obs.rank == 21 and not obs.unobservable
    # Accelerometer scale factors cannot beat the gravity-only bound of conventions.md:
    # sigma >= VRW sqrt(3/T)/g for the best-served axis of the three together.
    from calib.analysis.bounds import accel_scale_bound

    bound = accel_scale_bound(seq.duration_s, prof, earth.gravity(LAT))
    assert max(obs.ratio[P.ACCEL_SCALE]) >= bound * 0.999
    # Information adds: the sum over the three of 1/sigma^2 is at most g^2 T / VRW^2.
    info_sum = np.sum(1.0 / obs.sigma[P.ACCEL_SCALE] ** 2)
    assert info_sum <= earth.gravity(LAT) ** 2 * seq.duration_s / prof.vrw**2 * 1.0001


def test_gauss_markov_density_integrates_to_its_variance_and_has_the_right_limits():
    # S(f) = 2 sigma^2 tau / (1 + (2 pi f tau)^2) is the two-sided PSD of a first-order GM
    # process: its integral over all f is the stationary variance sigma^2 (quadrature
    # on a log grid to 1e-4; the tails beyond 1e4/tau hold < 1e-4 of it).
    from calib.analysis.bounds import accel_density_at_rate

    prof = load_profile("navigation-gm")
    tau, var = prof.accel_bias_correlation_s, prof.accel_gm_sigma**2
    f = np.logspace(-8, 4, 20001) / tau
    rate_dps = np.degrees(2 * np.pi * f)
    excess = np.array([accel_density_at_rate(prof, r) for r in rate_dps]) - prof.vrw**2
    assert 2 * np.trapezoid(excess, f) == pytest.approx(var, rel=1e-4)
    # at zero frequency the bias is a constant of variance sigma^2 held for tau: 2 sigma^2 tau
    assert excess[0] == pytest.approx(2 * var * tau, rel=1e-6)
    # a white profile has no excess at any rate
    white = load_profile("navigation")
    assert accel_density_at_rate(white, 10.0) == white.vrw**2


@pytest.mark.parametrize("name", ["designed-30min-gm", "designed-15min-gm"])
def test_gauss_markov_sequences_do_not_beat_the_rate_bound(name):
    # The coloured-noise bound (docs/gm-bound.md) is the best a gimbal turning at the
    # sequence's rate can do for the accelerometer scale factors under navigation-gm: no
    # sequence's sigma may fall below it. Nominal mounting (the bound holds for any).
    from calib.analysis.bounds import accel_scale_bound
    from seqdesign.search import design_rate_dps

    seq = load_sequence(name)
    prof = load_profile("navigation-gm")
    obs = analyze(seq, prof, SITE)
    bound = accel_scale_bound(seq.duration_s, prof, earth.gravity(LAT), rate_dps=design_rate_dps(seq))
    white = accel_scale_bound(seq.duration_s, prof, earth.gravity(LAT))
    assert bound > white  # the GM bias costs information at any finite rate
    assert max(obs.ratio[P.ACCEL_SCALE]) >= bound


def test_sigma_scales_with_noise():
    # Halving both noise densities halves every sigma (information is 1/noise^2).
    seq = load_sequence("paper-9pos")
    from calib.noise.profiles import NoiseProfile

    a = analyze(seq, NoiseProfile("a", 0.002, 20.0), SITE)
    b = analyze(seq, NoiseProfile("b", 0.001, 10.0), SITE)
    assert np.allclose(a.sigma / b.sigma, 2.0, rtol=1e-6)


def test_single_axis_sequence_is_rank_deficient_and_names_directions():
    # Only turning about the vertical Z axis: X and Y stay level, so their
    # accelerometers never see gravity (sax, say unexcited), and the z
    # accelerometer always sees +g, so its bias and scale factor appear only as
    # baz + g * saz.
    doc = {
        "name": "spin",
        "start": ["east", "north", "up"],
        "initial_dwell_s": 60.0,
        "step": [{"axis": "Z", "angle_deg": 90.0, "dwell_s": 60.0} for _ in range(4)],
    }
    seq = sequence_from_dict(doc, "spin")
    obs = analyze(seq, load_profile("navigation"), SITE)
    assert obs.rank < 21
    text = " ".join(obs.unobservable)
    for name in ("sax", "say", "saz"):
        assert name in text
    # The physical null direction: +g in baz cancels -1 in saz (SI).
    v = np.zeros(21)
    v[P.INDEX["baz"]], v[P.INDEX["saz"]] = earth.gravity(LAT), -1.0
    M = obs.information[:21, :21]
    w = np.zeros(21)
    w[P.INDEX["baz"]] = earth.gravity(LAT)  # same size, not a null direction
    # Rounding leaves ~1e-9 of the information a non-null direction of that size has.
    assert v @ M @ v < 1e-6 * (w @ M @ w)


def test_cli_analyze_json_layout_and_tolerance():
    r = CliRunner().invoke(main, ["analyze", "paper-9pos", "--tolerance-deg", "0", "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert list(doc["parameters"]) == list(P.NAMES)
    for e in doc["parameters"].values():
        assert e["ratio"] == pytest.approx(3 * e["sigma"] / e["requirement"])
    assert doc["worst"]["ratio"] == max(e["ratio"] for e in doc["parameters"].values())
    assert doc["setups_evaluated"] == 1


def test_cli_analyze_worst_case_is_not_better_than_nominal():
    r0 = CliRunner().invoke(main, ["analyze", "paper-9pos", "--tolerance-deg", "0", "--json"])
    r3 = CliRunner().invoke(main, ["analyze", "paper-9pos", "--tolerance-deg", "3", "--json"])
    d0, d3 = json.loads(r0.stdout), json.loads(r3.stdout)
    assert d3["setups_evaluated"] == 27
    for n in P.NAMES:
        assert d3["parameters"][n]["ratio"] >= d0["parameters"][n]["ratio"] * (1 - 1e-12)


def test_cli_analyze_bad_input():
    r = CliRunner().invoke(main, ["analyze", "nope-seq"])
    assert r.exit_code != 0 and "nope-seq" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(main, ["analyze", "paper-9pos", "--tolerance-deg", "45"])
    assert r.exit_code != 0 and "tolerance" in r.output


def test_mounting_basis_model_equals_direct_evaluation():
    # The analyser's SequenceModel writes H for any mounting as a fixed combination of
    # 63 basis terms; it must equal the model evaluated directly along that mounting's
    # trajectory (same arithmetic reordered: agreement to rounding, 1e-10).
    from calib.analysis.mounting import sequence_model
    from calib.analysis.nominal import information_along

    seq = load_sequence("paper-9pos")
    prof = load_profile("navigation")
    model = sequence_model(seq, prof, SITE)
    for setup in ([0.0, 0.0, 0.0], [1.0, -2.0, 3.0], [-3.0, 3.0, -3.0]):
        rv = np.radians(setup)
        direct = information_along(nominal_run(seq, SITE, rv), prof, SITE)
        assert np.allclose(model.information(rv), direct, rtol=1e-10, atol=1e-10 * np.abs(direct).max())


def test_cli_analyze_view_writes_a_recording_of_the_analysis(tmp_path, monkeypatch):
    # rerun writes analytics under HOME: keep it in the test's folder.
    for var in ("HOME", "XDG_CONFIG_HOME", "XDG_DATA_HOME", "XDG_CACHE_HOME"):
        monkeypatch.setenv(var, str(tmp_path / "home"))
    from recordings import bars  # rerun's BarChart values read back from the recording

    from viz.rrd import read_recording

    out = tmp_path / "a.rrd"
    r = CliRunner().invoke(
        main, ["analyze", "paper-9pos", "--tolerance-deg", "0", "--view", str(out), "--json"]
    )
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["recording"] == str(out)
    chunks = read_recording(out)
    assert "analysis/correlation" in chunks and "analysis/ratio" in chunks
    # The bars hold the 21 ratios the JSON reports (nominal mounting here).
    expected = [doc["parameters"][n]["ratio"] for n in P.NAMES]
    assert np.allclose(bars(chunks, "analysis/ratio"), expected, rtol=1e-9)
    r = CliRunner().invoke(main, ["analyze", "paper-9pos", "--view", str(tmp_path / "x.txt")])
    assert r.exit_code == 2 and "must end in .rrd" in r.output


def test_cli_analyze_json_on_a_rank_deficient_sequence_names_it_without_traceback(tmp_path):
    # JSON has no inf: an unobservable parameter's sigma and ratio are null, and the
    # unobservable directions are listed by name.
    seq = tmp_path / "onez.toml"
    seq.write_text(
        'name = "onez"\nstart = ["east", "up", "south"]\ninitial_dwell_s = 60\n'
        '[[step]]\naxis = "Z"\nangle_deg = 90\ndwell_s = 60\n'
    )
    for args in (
        ["analyze", str(seq), "--tolerance-deg", "0", "--json"],
        ["compare", str(seq), "paper-9pos", "--tolerance-deg", "0", "--json"],
    ):
        r = CliRunner().invoke(main, args)
        assert r.exit_code == 0, r.output
        doc = json.loads(r.stdout)
        first = doc if "parameters" in doc else doc["sequences"][0]
        assert first["rank"] < 21 and first["unobservable"]
        assert any(e["sigma"] is None and e["ratio"] is None for e in first["parameters"].values())


def test_cli_show_marks_off_grid_axes(tmp_path):
    seq = tmp_path / "odd.toml"
    seq.write_text(
        'name = "odd"\nstart = ["east", "up", "south"]\ninitial_dwell_s = 60\n'
        '[[step]]\naxis = "Z"\nangle_deg = 135\ndwell_s = 60\n'
    )
    doc = json.loads(CliRunner().invoke(main, ["show", str(seq), "--json"]).stdout)
    p2 = doc["positions"][1]
    assert not p2["on_grid"] and p2["z"] == "south"
    # Body X after +135 deg about Z (south) from east: east*cos135 + up*sin135 (independent).
    c, s = math.cos(math.radians(135)), math.sin(math.radians(135))
    assert p2["x"] == f"[{c:+.3f} {0.0:+.3f} {s:+.3f}]"


def test_mounting_model_is_the_same_built_in_any_chunking(monkeypatch):
    # The model is accumulated interval-chunk by chunk, carrying the propagation and
    # the whitening filter across chunks: 7-interval chunks must give the one-chunk
    # information (same sums in another order: rounding, 1e-11).
    import calib.analysis.mounting as O

    seq, prof = load_sequence("paper-9pos"), load_profile("navigation")
    rv = np.radians([1.0, -2.0, 3.0])
    monkeypatch.setattr(O, "CHUNK_INTERVALS", 10**6)
    whole = O.sequence_model.__wrapped__(seq, prof, SITE).information(rv)
    monkeypatch.setattr(O, "CHUNK_INTERVALS", 7)
    chunked = O.sequence_model.__wrapped__(seq, prof, SITE).information(rv)
    assert np.allclose(chunked, whole, rtol=1e-11, atol=1e-11 * np.abs(whole).max())


def test_direct_search_finds_an_interior_maximum_the_box_misses():
    # A sigma peaked inside the box, smooth as the real ones are (over a few degrees a
    # sigma is close to quadratic in the mounting): the forward-difference-steered IPOPT
    # must reach the peak from the worst box point within its iteration cap. The 1e-3 deg
    # forward step biases the gradient by half a step: 0.01 deg is ample.
    from calib.analysis.worst_case import search_worst_direct

    peak = np.radians([1.2, -0.7, 2.1])

    def sigma_of(rotvec):
        return 2.0 - 0.01 * np.sum(np.degrees(rotvec - peak) ** 2)

    start = np.array([3.0, 0.0, 3.0])
    rotvec, value = search_worst_direct(sigma_of, start, 3.0)
    assert np.allclose(np.degrees(rotvec), np.degrees(peak), atol=0.01)
    assert value == pytest.approx(sigma_of(rotvec), rel=1e-15)
    assert value > sigma_of(np.radians(start))


@pytest.mark.slow
def test_gm_and_extras_worst_case_searches_are_exact_and_never_below_the_box():
    # Issue 12, point 4: under Gauss-Markov bias instability, and with --with terms, the
    # worst case over the box is searched by IPOPT over direct evaluations beyond the 27
    # points: it can only raise each worst sigma (the box points are kept), and the
    # worst mounting it reports is an exact evaluation there.
    from calib.analysis.nominal import information_along
    from calib.analysis.observability import from_information
    from calib.analysis.worst_case import analyze_extras, analyze_tolerance
    from calib.model.optional_terms import load_optional_terms

    seq, gm = load_sequence("paper-9pos"), load_profile("navigation-gm")
    box = analyze_tolerance(seq, gm, SITE, search=False)
    found = analyze_tolerance(seq, gm, SITE, search=True)
    assert found.searched and not box.searched
    assert np.all(found.per_parameter_worst_sigma >= box.per_parameter_worst_sigma * (1 - 1e-12))
    assert found.worst.worst[1] >= box.worst.worst[1] * (1 - 1e-12)
    rv = found.worst.setup_rotvec
    direct = from_information(
        information_along(nominal_run(seq, SITE, rv), gm, SITE),
        seq.duration_s,
        gm.name,
        rv,
    )
    assert np.allclose(found.worst.sigma, direct.sigma, rtol=1e-12)
    extras = load_optional_terms("all")
    c_box = analyze_extras(seq, gm, SITE, extras, search=False)
    c_found = analyze_extras(seq, gm, SITE, extras, search=True)
    assert c_found.searched and not c_box.searched
    for a, b in (
        (c_found.sigma_with, c_box.sigma_with),
        (c_found.extra_sigma, c_box.extra_sigma),
        (c_found.sigma_without, c_box.sigma_without),
    ):
        assert np.all(a >= b * (1 - 1e-12))
