"""Optional terms of a real unit (issue 8): lever arms, K2, time offset.

Physics of the simulated terms against hand-derived values, then the
noise-free exactness of the estimator with every term switched on.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.errors import CalibError
from calib.fit.estimator import fit_run
from calib.fit.options import FitOptions
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.model.optional_terms import GROUP_NAMES, OptionalTerms, OptionalTermValues, parse_groups
from calib.nav import earth
from calib.nav.site import Site
from calib.nav.transform import dcm_to_rotvec, rotvec_to_dcm
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence, timeline
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate
from calib.sim.truth import read_truth, write_truth

LAT = math.radians(40.0)
CFG = SimConfig(latitude_rad=LAT, sample_rate_hz=50.0)
PROFILE = load_profile("navigation")
# Every term on, at sizes a real navigation unit could have.
ALL_ON = {
    "rxx": 3.0,
    "rxy": -2.0,
    "rxz": 1.5,
    "ryx": 1.0,
    "ryy": -4.0,
    "ryz": 2.0,
    "rzx": -1.0,
    "rzy": 2.5,
    "rzz": 3.5,
    "k2x": 20.0,
    "k2y": -15.0,
    "k2z": 30.0,
    "dt_ga": 0.5,
}


def _run(extra=None, cfg=CFG, errors=None, setup=(0.0, 0.0, 0.0)):
    return simulate(
        load_sequence("paper-9pos"),
        cfg,
        errors or ErrorModel.zero(),
        PROFILE,
        options=SimOptions(setup_rotvec=setup, noise=False),
        extra=extra,
    )


def test_k2_adds_k2_g_squared_on_the_vertical_axis_at_rest():
    # First rest: Y up (f_y = g), X and Z level (f = 0). k2 in ug/g^2 -> k2 * 1e-6 * g^2 / g0.
    k2 = np.array([100.0, 200.0, 300.0])
    base, _ = _run()
    run, _ = _run(OptionalTermValues.from_units(dict(zip(["k2x", "k2y", "k2z"], k2, strict=True))))
    g = earth.gravity(LAT)
    rest = slice(10, int(170 * CFG.sample_rate_hz))
    dt = 1.0 / CFG.sample_rate_hz
    extra = (run.dv_mps[rest] - base.dv_mps[rest]).mean(axis=0) / dt
    assert extra[1] == pytest.approx(k2[1] * 1e-6 / 9.80665 * g**2, rel=1e-9)
    # Level axes see only the Earth's turn in f (1e-20 m/s^2): nothing measurable.
    assert abs(extra[0]) < 1e-12 and abs(extra[2]) < 1e-12


def test_time_offset_shifts_the_accelerometer_windows():
    # Over a flip, shifting every accelerometer window back by d changes the summed dv by
    # d (f_before - f_after) in the body frame (the windows telescope); at rest nothing moves.
    d = 1e-3
    base, _ = _run()
    run, _ = _run(OptionalTermValues.from_units({"dt_ga": d * 1e3}))
    tl = timeline(load_sequence("paper-9pos"))
    fs = CFG.sample_rate_hz
    f_n = np.array([0.0, 0.0, earth.gravity(LAT)])
    for k in range(len(tl.t0)):
        if tl.rate[k] == 0.0:
            continue
        a, b = int((tl.t0[k] - 2) * fs), int((tl.t1[k] + 2) * fs)
        diff = (run.dv_mps[a:b] - base.dv_mps[a:b]).sum(axis=0)
        # The Earth's turn adds ~g * w_ie * d ~ 7e-10 m/s: 1e-8 is far above it, far below g d.
        assert np.allclose(diff, d * (tl.C0[k].T @ f_n - tl.C0[k + 1].T @ f_n), atol=1e-8)
    # At rest, including the first sample (the IMU rested before the run): nothing changes.
    rest = slice(0, int(170 * fs))
    assert np.allclose(run.dv_mps[rest], base.dv_mps[rest], atol=1e-12)


def test_lever_arms_centripetal_and_tangential():
    # The first flip turns about body Z at w = 10 deg/s, starting at t = 180 s on a sample
    # boundary. An accelerometer at r from the rotation centre senses
    # e_i . (w x (w x r) + w_dot x r):
    #  - x accelerometer with r = rxx e_x: -w^2 rxx throughout the flip (centripetal);
    #  - y accelerometer with r = ryx e_x: e_y . (w e_z x ryx e_x) = +w ryx as a velocity
    #    step in the flip's first sample, and -w ryx in the first sample after it.
    rxx, ryx = 0.03, 0.02
    base, _ = _run()
    run, _ = _run(OptionalTermValues.from_units({"rxx": rxx * 100, "ryx": ryx * 100}))
    d = run.dv_mps - base.dv_mps
    fs = CFG.sample_rate_hz
    w = math.radians(10.0)
    start, stop = int(180 * fs), int(189 * fs)
    h = 1.0 / fs
    # Earth rate adds 2 w w_ie / w^2 ~ 1e-4 relative to the centripetal term.
    assert np.allclose(d[start + 1 : stop - 1, 0], -(w**2) * rxx * h, rtol=2e-4)
    # Earth rate turning in the body adds w w_ie h r ~ 2e-10 m/s to the steps.
    assert d[start, 1] == pytest.approx(w * ryx, abs=1e-9)
    assert d[stop, 1] == pytest.approx(-w * ryx, abs=1e-9)
    assert np.all(np.abs(d[start + 1 : stop, 1]) < 1e-9)
    # At rest only the Earth's rate acts: w_ie^2 rxx h = 3.2e-12 m/s per sample.
    assert np.all(np.abs(d[:start]) < 1e-11)


def test_truth_records_the_extra_terms(tmp_path):
    _, truth = _run(OptionalTermValues.from_units(ALL_ON))
    write_truth(tmp_path / "t.toml", truth)
    back = read_truth(tmp_path / "t.toml").extra
    assert {k: v for k, v in back.in_units().items()} == pytest.approx(ALL_ON)
    _, plain = _run()
    write_truth(tmp_path / "p.toml", plain)
    assert read_truth(tmp_path / "p.toml").extra is None


def test_bad_extra_names_and_sizes_are_refused():
    with pytest.raises(CalibError, match="unknown extra term"):
        parse_groups("lever-arm,k3")
    assert parse_groups("time-offset,k2") == ("k2", "time-offset")  # canonical order
    assert parse_groups("all") == GROUP_NAMES
    with pytest.raises(CalibError, match="unknown extra parameter"):
        OptionalTermValues.from_units({"rxq": 1.0})
    with pytest.raises(CalibError, match="beyond the plausible"):
        OptionalTermValues.from_units({"rxx": 500.0})


@pytest.fixture(scope="module")
def all_on_fit():
    cfg = SimConfig(latitude_rad=LAT)  # 200 Hz: the estimator's grid as in real use
    truth = ErrorModel.from_table2()
    extra = OptionalTermValues.from_units(ALL_ON)
    setup = np.radians([1.0, -2.0, 3.0])
    run, _ = _run(extra, cfg, truth, setup)
    fit = fit_run(run, Site(LAT, cfg.gravity), PROFILE, options=FitOptions(extras=OptionalTerms(GROUP_NAMES)))
    return fit, truth, extra, setup


def test_noise_free_recovery_with_every_extra_term_on(all_on_fit):
    # The calibrate issue's criterion, every term simulated and estimated: the 21 within
    # 1/20 of their requirements. The one approximation left is the first-order time-offset
    # compensation: its error d^2 w^2 g T_flip / 2 ~ 3e-7 m/s per flip (d = 0.5 ms) is
    # ~5e-3 of a requirement's signature.
    fit, truth, extra, setup = all_on_fit
    assert fit.converged
    err = np.abs(fit.values - truth.values) / P.REQUIREMENTS_SI
    assert err.max() < 1.0 / 20.0, P.NAMES[int(np.argmax(err))]
    # OptionalTerms back to 1/20 of the sizes that scale them (1 cm, 10 ug/g^2, 0.1 ms).
    ex = OptionalTerms(GROUP_NAMES)
    got = (fit.extra_values - ex.pack(extra)) / ex.scale_si
    assert np.abs(got).max() < 1.0 / 20.0, ex.names[int(np.argmax(np.abs(got)))]
    C_true = rotvec_to_dcm(setup) @ load_sequence("paper-9pos").C_start
    assert np.linalg.norm(dcm_to_rotvec(fit.C_b_n0 @ C_true.T)) < 1e-7
    # The second-order time-offset term (3e-7 m/s per flip, spread over a flip's ~90
    # intervals) bounds the residual: 1e-8 m/s RMS; without it 1e-10 (strapdown only).
    assert fit.residual_rms_mps < 3e-8


def test_ignoring_the_extra_terms_biases_the_fit():
    # The same run fitted with the 21 only: a lever arm of a few cm must bias something by
    # more than its requirement (the "~90 ug at 10 deg/s for 3 cm").
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=50.0)
    run, _ = _run(OptionalTermValues.from_units({"rxx": 3.0, "ryy": 3.0, "rzz": 3.0}), cfg)
    fit = fit_run(run, Site(LAT, cfg.gravity), PROFILE)
    assert np.max(np.abs(fit.values) / P.REQUIREMENTS_SI) > 1.0


def test_extra_columns_match_central_finite_difference():
    """Each extra column of H equals a central difference of simulate -> navigate (1e-3 rel)."""
    from calib.analysis.nominal import nominal_run
    from calib.nav.jacobian import N_UNKNOWN, ObservationGrid, Trajectory, observation_jacobian, state_matrix
    from calib.nav.strapdown import navigate
    from calib.noise.whitening import noise_model

    seq = load_sequence("paper-9pos")
    rate = 50.0
    g = earth.gravity(LAT)
    setup = np.radians([1.0, -2.0, 3.0])
    nom = nominal_run(seq, Site.at(LAT), setup)
    t_obs = nom.time_nav[nom.grid.bounds]
    Phi_vv = noise_model(state_matrix(Site(LAT, g)), np.diff(t_obs), PROFILE).Phi_vv
    extras = OptionalTerms(GROUP_NAMES)
    cfg = SimConfig(latitude_rad=LAT, sample_rate_hz=rate)
    C0 = rotvec_to_dcm(setup) @ seq.C_start
    # H along the 50 Hz run itself, as the estimator evaluates it. (Along the analyser's
    # coarser sampling the lever arms' velocity steps sit in 0.05 s samples instead of
    # 0.02 s ones: their nav direction differs by w (0.05 - 0.02) / 2 = 2.6e-3 rad.)
    ref, _ = simulate(
        seq, cfg, ErrorModel.zero(), PROFILE, options=SimOptions(setup_rotvec=setup, noise=False)
    )
    nav = navigate(ref.dtheta_rad, ref.dv_mps, ref.time_s, C0, Site(LAT, cfg.gravity), t0=0.0)
    grid = ObservationGrid(np.round(t_obs * rate).astype(int))
    H = observation_jacobian(
        Trajectory(nav.time_s, nav.C_b_n, ref.dtheta_rad, ref.dv_mps, grid), Site(LAT, g), Phi_vv, extras
    )
    assert H.shape[-1] == N_UNKNOWN + extras.n

    def z(values):
        run, _ = simulate(
            seq,
            cfg,
            ErrorModel.zero(),
            PROFILE,
            options=SimOptions(setup_rotvec=setup, noise=False),
            extra=extras.unpack(values),
        )
        nav = navigate(run.dtheta_rad, run.dv_mps, run.time_s, C0, Site(LAT, cfg.gravity), t0=0.0)
        y = nav.v_n[np.round(t_obs * rate).astype(int)]
        return y[1:] - np.einsum("kij,kj->ki", Phi_vv, y[:-1])

    # Steps of 1/10 of each term's typical size: the terms are linear but for the
    # time offset's second order (d^2 w^2 g T, 1e-4 relative at 0.01 ms), which
    # central differences cancel anyway. The simulator's tangential steps land on
    # sample boundaries at 50 Hz as at the analyser's sampling.
    bad = {}
    for k, p in enumerate(extras.parameters):
        step = np.zeros(extras.n)
        step[k] = 0.1 * p.scale_si
        fd = (z(step) - z(-step)) / (2 * step[k])
        rel = np.linalg.norm(H[:, :, N_UNKNOWN + k] - fd) / np.linalg.norm(fd)
        if rel > 1e-3:
            bad[p.name] = rel
    assert not bad, bad


def test_analyser_with_extras_predicts_the_estimators_sigma(all_on_fit):
    # The analyser (coarse nominal sampling, 5 s rest intervals) and the estimator (200 Hz,
    # 1 s) evaluate the same model at the same mounting; the 21-parameter case agrees to
    # 0.2 %, so 1 % leaves room for the extra columns' coarser sampling.
    from calib.analysis.nominal import information_along, nominal_run

    fit, _, _, setup = all_on_fit
    nom = nominal_run(load_sequence("paper-9pos"), Site.at(LAT), setup)
    info = information_along(nom, PROFILE, Site.at(LAT), OptionalTerms(GROUP_NAMES))
    predicted = np.sqrt(np.diag(np.linalg.inv(info)))
    reported = np.sqrt(np.diag(fit.covariance))
    assert np.allclose(predicted, reported, rtol=0.01), np.max(np.abs(predicted / reported - 1))


def test_fitting_more_terms_never_shrinks_a_sigma():
    # Marginal variances can only grow when unknowns are added (Schur complement).
    from calib.analysis.worst_case import analyze_extras

    cost = analyze_extras(
        load_sequence("paper-9pos"), PROFILE, Site.at(LAT), OptionalTerms(("k2",)), tolerance_deg=0.0
    )
    assert np.all(cost.sigma_with >= cost.sigma_without * (1 - 1e-9))
    # K2 on the paper's sequence: y is up or down in 6 of 9 rests and level in 3, so k2y
    # trades with bay and saz/say only through the level rests: it must cost bay most.
    assert P.NAMES[int(np.argmax(cost.sigma_with / cost.sigma_without))] == "bay"
