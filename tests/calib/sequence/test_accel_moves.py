"""Accelerating moves (issue 13): rate profiles, their exact simulation, and calibration on them."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import quad

from calib.fit.estimator import fit_run
from calib.fit.options import FitOptions
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.nav.site import Site
from calib.nav.strapdown import navigate
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence, nominal_attitude, sequence_from_dict, timeline
from calib.sequence.kinematics import SimConfig, true_increments
from calib.sequence.rate_profile import RateProfile
from calib.sim.gimbal_run import SimOptions, simulate

LAT = math.radians(40.0)
D = math.radians


def accelerating(seq, accel_dps2=5.0, jerk_dps3=None):
    """The same sequence with every move a trapezoid (or S-curve)."""
    return replace(
        seq, steps=tuple(replace(s, accel_dps2=accel_dps2, jerk_dps3=jerk_dps3) for s in seq.steps)
    )


@pytest.mark.parametrize("A_deg", [90.0, 450.0, 3.0])
@pytest.mark.parametrize(
    "prof", [RateProfile(D(10), D(5)), RateProfile(D(20), D(10), D(8)), RateProfile(D(20), D(10), D(200))]
)
def test_profile_turns_the_angle_within_its_limits(prof, A_deg):
    # The rate integrates (numerically, independently of the pieces' closed form) to the
    # angle; the rate and acceleration stay within the limits; rest at both ends.
    A = D(A_deg)
    pc = prof.pieces(A)
    ends = np.cumsum(pc.duration)

    def rate(t):
        i = min(int(np.searchsorted(ends, t)), len(ends) - 1)
        return float(pc.rate(i, t - (ends[i] - pc.duration[i])))

    turned = sum(quad(rate, a, b)[0] for a, b in zip(ends - pc.duration, ends, strict=True))
    assert turned == pytest.approx(A, rel=1e-12)
    assert rate(0.0) == 0.0 and abs(rate(ends[-1])) < 1e-12 * prof.rate
    assert pc.peak_rate <= prof.rate * (1 + 1e-12)
    assert pc.peak_accel <= prof.accel * (1 + 1e-12)
    # Rate continuous across pieces (no instantaneous step anywhere).
    i = np.arange(len(ends) - 1)
    assert np.allclose(pc.rate(i, pc.duration[:-1]), pc.rate0[1:], atol=1e-12)


def test_profile_durations_follow_from_the_limits():
    # Trapezoid reaching the cruise rate: A/v + v/a. S-curve reaching both: A/v + v/a + a/j.
    v, a, j, A = D(20), D(10), D(5), D(450)
    assert RateProfile(v, a).duration_s(A) == pytest.approx(450 / 20 + 20 / 10, rel=1e-12)
    assert RateProfile(v, a, j).duration_s(A) == pytest.approx(450 / 20 + 20 / 10 + 10 / 5, rel=1e-12)
    # Triangle (never reaches the cruise rate): 2 sqrt(A / a).
    assert RateProfile(v, a).duration_s(D(10)) == pytest.approx(2 * math.sqrt(10 / 10), rel=1e-12)


def test_sequence_file_keys_default_and_per_step():
    doc = {
        "start": ["east", "up", "south"],
        "accel_dps2": 4.0,
        "step": [
            {"axis": "Z", "angle_deg": 90},
            {"axis": "Y", "angle_deg": 90, "accel_dps2": 8.0, "jerk_dps3": 16.0},
        ],
    }
    seq = sequence_from_dict(doc, "t.toml")
    assert seq.steps[0].accel_dps2 == 4.0 and seq.steps[0].jerk_dps3 is None
    assert seq.steps[1].profile.kind == "s-curve"
    assert seq.steps[0].duration_s == pytest.approx(90 / 10 + 10 / 4)
    # Old files mean what they meant: constant rate, angle / rate.
    old = load_sequence("paper-9pos")
    assert all(s.accel_dps2 is None and s.duration_s == 9.0 for s in old.steps)
    back = sequence_from_dict(seq.to_toml_dict(), "t.toml")
    assert back.steps == seq.steps


@pytest.mark.parametrize("jerk", [None, 20.0])
def test_simulated_increments_match_quadrature(jerk):
    # Independent check of the closed form / Gauss-Legendre increments: adaptive quadrature of
    # C_nom(t)^T f over samples in the acceleration, jerk and cruise phases of the first move.
    from calib.nav import earth

    seq = accelerating(load_sequence("paper-9pos"), 5.0, jerk)
    tl = timeline(seq)
    cfg = SimConfig(latitude_rad=LAT)
    t, dtheta, dv = true_increments(tl, np.eye(3), cfg)
    f = earth.specific_force_n(cfg.gravity)
    w = earth.omega_ie_n(LAT)
    for j in (36001, 36050, 36300, 36399, 36401, 37000):  # 180 s + 0.005 ... in the first move
        a, b = t[j - 1], t[j]

        def integral(fn, c, a=a, b=b):
            return quad(lambda s: fn(s)[c], a, b, epsabs=1e-17, epsrel=1e-13)[0]

        Cf = [integral(lambda s: nominal_attitude(tl, np.array([s]))[0].T @ f, c) for c in range(3)]
        # Gyro: the flip's rate about body Z integrates to the angle difference of the profile.
        seg = np.searchsorted(tl.t1, [a, b], side="left")
        flip = (
            tl.angle(seg[1], b - tl.t0[seg[1]]) - tl.angle(seg[0], a - tl.t0[seg[0]])
            if seg[0] == seg[1]
            else None
        )
        # 1e-15 m/s: rounding of a 0.05 m/s increment.
        assert np.max(np.abs(np.array(Cf) - dv[j])) < 1e-15
        if flip is not None:
            earth_part = integral(lambda s: nominal_attitude(tl, np.array([s]))[0].T @ w, 2)
            assert dtheta[j, 2] == pytest.approx(flip + earth_part, abs=1e-16)


def test_navigating_an_accelerating_run_holds_zero_velocity():
    # Noise-free, error-free. At every rest the velocity is back within 1e-7 m/s (constant-rate
    # runs: 2e-8). During a move the strapdown's Delta-v rotation compensation, exact for a
    # constant rate, leaves a transient that grows with the angular acceleration and as h^2:
    # 3.6e-6 m/s at 5 deg/s^2 and 200 Hz (3.6e-8 at 2000 Hz), cancelling between acceleration
    # and deceleration. The spec's bound is 1e-4 m/s.
    seq = accelerating(load_sequence("paper-9pos"), 5.0, 20.0)
    tl = timeline(seq)
    cfg = SimConfig(latitude_rad=LAT)
    t, dtheta, dv = true_increments(tl, np.eye(3), cfg)
    nav = navigate(dtheta, dv, t, seq.C_start, Site(LAT, cfg.gravity), t0=0.0)
    rest_ends = np.searchsorted(nav.time_s, tl.t1[tl.rest] - 1e-9)
    assert np.max(np.abs(nav.v_n[rest_ends])) < 1e-7
    assert np.max(np.abs(nav.v_n)) < 1e-5


def test_real_angular_acceleration_reaches_the_lever_arm_term():
    # Tangential lever-arm term: over a trapezoid's acceleration phase the accelerometer at
    # r senses alpha x r for v/a seconds: a velocity step (alpha x r) v/a = (v x r) in total.
    from calib.model import optional_terms as X

    seq = accelerating(load_sequence("paper-9pos"), 5.0)
    tl = timeline(seq)
    t, dtheta, _ = true_increments(tl, np.eye(3), SimConfig(latitude_rad=LAT))
    h = np.diff(np.concatenate([[0.0], t]))
    r = np.array([[0.0, 0.03, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # x accel 3 cm along y
    lev = X.lever(r, dtheta, h)
    # First flip: about Z at +10 deg/s, accelerating for 2 s from t = 180 s.
    # The term uses sample-mean rates, which lag the rate by half a sample, so the acceleration
    # phase's step ends in the sample after it (the sum telescopes): sum one sample further.
    acc = (t > 180.0) & (t <= 182.0 + 0.005 + 1e-9)
    # e_x . (omega_dot x r) with omega_dot = +a e_z, r = 0.03 e_y: -a * 0.03 per second.
    expected = -D(5.0) * 0.03 * 2.0
    centripetal = np.sum(lev[acc, 0]) - expected
    # The centripetal part (omega^2 r, along y for the x accel: zero) leaves only Earth-rate
    # cross terms, below omega_ie * omega * r * T = 7e-5 * 0.17 * 0.03 * 2 = 7e-7 m/s (1.4e-4).
    assert abs(centripetal) < 1.4e-4 * abs(expected)


SETUP = np.radians([1.0, -2.0, 3.0])


@pytest.fixture(scope="module")
def noise_free_accel_fit():
    seq = accelerating(load_sequence("paper-9pos"), 5.0, 10.0)
    cfg = SimConfig(latitude_rad=LAT)
    truth = ErrorModel.from_table2()
    run, _ = simulate(
        seq, cfg, truth, load_profile("navigation"), options=SimOptions(setup_rotvec=SETUP, noise=False)
    )
    fit = fit_run(run, Site(LAT, cfg.gravity), load_profile("navigation"))
    return fit, truth, run


@pytest.mark.slow  # simulate + calibrate a 28-min run: ~5 s
def test_noise_free_recovery_on_accelerating_moves(noise_free_accel_fit):
    # The criterion: every parameter within 1/20 of its requirement. The estimator
    # navigates the measured increments, so the profile of the moves must not matter.
    fit, truth, _ = noise_free_accel_fit
    assert fit.converged
    err = np.abs(fit.values - truth.values)
    bad = [
        f"{n}: {e / p.si_per_unit:.3g} {p.unit}"
        for n, e, lim, p in zip(P.NAMES, err, P.REQUIREMENTS_SI / 20.0, P.PARAMETERS, strict=True)
        if e > lim
    ]
    assert not bad, bad
    assert fit.residual_rms_mps < 1e-7  # as on constant-rate runs: no model error left


@pytest.mark.slow
def test_encoder_steps_within_the_moves_rate(noise_free_accel_fit):
    # Every sample's encoder step is within what the move's peak rate allows over a sample.
    _, _, run = noise_free_accel_fit
    step = np.abs(np.diff(run.gimbal_deg, axis=0))
    dt = np.diff(run.time_s)
    assert np.all(step <= 10.0 * dt[:, None] * (1 + 1e-9) + 1e-9)


@pytest.mark.slow
def test_analyser_models_accelerating_moves_as_the_estimator_sees_them(noise_free_accel_fit):
    # The analyser builds its model from the same timeline (with the profile's pieces); its
    # sigmas must match the estimator's on the accelerating run as on constant-rate ones (1 %).
    from calib.analysis.mounting import analyze

    fit, _, _ = noise_free_accel_fit
    seq = accelerating(load_sequence("paper-9pos"), 5.0, 10.0)
    obs = analyze(seq, load_profile("navigation"), Site.at(LAT), SETUP)
    assert np.allclose(obs.sigma, fit.sigma, rtol=0.01), np.round(obs.sigma / fit.sigma, 4)


@pytest.mark.slow  # simulate + calibrate with the lever-arm columns: ~10 s
def test_lever_arms_recovered_on_accelerating_moves():
    # The lever arms' tangential term now acts over the S-curve's ramps instead of in a single
    # sample: simulated and fitted with the same term, a noise-free run must come back within
    # 1/20 of each requirement and of 1 cm per lever-arm component.
    from calib.model.optional_terms import OptionalTerms, OptionalTermValues

    lever = {
        "rxx": 3.0,
        "rxy": -2.0,
        "rxz": 1.5,
        "ryx": 1.0,
        "ryy": -4.0,
        "ryz": 2.0,
        "rzx": -1.0,
        "rzy": 2.5,
        "rzz": 3.5,
    }  # cm
    extra = OptionalTermValues.from_units(lever)
    seq = accelerating(load_sequence("paper-9pos"), 5.0, 10.0)
    cfg = SimConfig(latitude_rad=LAT)
    truth = ErrorModel.from_table2()
    run, _ = simulate(
        seq,
        cfg,
        truth,
        load_profile("navigation"),
        options=SimOptions(setup_rotvec=SETUP, noise=False),
        extra=extra,
    )
    ex = OptionalTerms(("lever-arm",))
    fit = fit_run(run, Site(LAT, cfg.gravity), load_profile("navigation"), options=FitOptions(extras=ex))
    assert fit.converged
    err = np.abs(fit.values - truth.values) / P.REQUIREMENTS_SI
    assert err.max() < 1.0 / 20.0, P.NAMES[int(np.argmax(err))]
    got = np.abs(fit.extra_values - ex.pack(extra)) / ex.scale_si
    assert got.max() < 1.0 / 20.0, ex.names[int(np.argmax(got))]
