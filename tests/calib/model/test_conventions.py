"""Conventions: gravity, Earth rate, the 21-parameter table, the sensor error model, paper tables."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import (
    ARCSEC,
    DATA,
    DEG,
    SHARED_PAPER,
    SPEC_NAMES,
    UG,
    W_EARTH,
    read_table,
    sensor_model,
    table_column_si,
    table_column_units,
)

from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.nav import earth

# ---------------------------------------------------------------------------
# Gravity and Earth rate


def test_normal_gravity_test_value():
    # conventions.md: g(40 deg, 0 m) = 9.8016969 m/s^2, printed to 7 decimals -> +-0.5e-7.
    assert earth.gravity(math.radians(40.0), 0.0) == pytest.approx(9.8016969, abs=0.5e-7)


def test_normal_gravity_equator_and_pole():
    # WGS-84 defining values: gamma_e = 9.7803253359, gamma_p = 9.8321849378 m/s^2
    # (the pole value is printed to 10 decimals -> tolerance 1e-9).
    assert earth.gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-12)
    assert earth.gravity(math.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-9)


def test_free_air_gradient_near_surface():
    lat = math.radians(40.0)
    # Over 100 m the quadratic term changes g by 3 h^2/a^2 g ~ 7e-9 m/s^2, i.e. 2e-5 of the
    # 3.1e-4 m/s^2 change, so the finite difference equals the free-air gradient 2 g/a
    # (1 + f + m - 2 f sin^2 L) = 3.0859e-6 /s^2 at 40 deg; "~ -3.086e-6" is given to 4 digits
    # -> 0.05 % tolerance.
    grad = (earth.gravity(lat, 100.0) - earth.gravity(lat, 0.0)) / 100.0
    assert grad == pytest.approx(-3.086e-6, rel=5e-4)


def test_gravity_second_order_height_term():
    # Second difference over h = 10 km isolates the +3 h^2/a^2 term: g0 * 6 h^2 / a^2
    # (1.45e-4 m/s^2). Rounding of three ~9.8 values contributes ~1e-15 -> rel 1e-6 is ample
    # and would still catch a missing factor or a wrong sign.
    lat = math.radians(40.0)
    h, a = 10_000.0, 6378137.0
    g0 = earth.gravity(lat, 0.0)
    second = earth.gravity(lat, 2 * h) - 2 * earth.gravity(lat, h) + g0
    assert second == pytest.approx(g0 * 6 * h * h / (a * a), rel=1e-6)


@pytest.mark.parametrize("lat_deg", [-60.0, 0.0, 40.0, 89.0])
def test_earth_rate_enu(lat_deg):
    L = math.radians(lat_deg)
    w = earth.omega_ie_n(L)
    # ENU: no east component; north W cos L, up W sin L (exact formula -> rounding-level tolerance).
    np.testing.assert_allclose(w, [0.0, W_EARTH * math.cos(L), W_EARTH * math.sin(L)], rtol=0, atol=1e-20)
    assert np.linalg.norm(w) == pytest.approx(W_EARTH, rel=1e-15)


def test_specific_force_at_rest_points_up():
    np.testing.assert_array_equal(earth.specific_force_n(9.8), [0.0, 0.0, 9.8])


# ---------------------------------------------------------------------------
# The 21-parameter table

UNITS = ["deg/h"] * 3 + ["ppm"] * 3 + ["arcsec"] * 6 + ["ug"] * 3 + ["ppm"] * 3 + ["arcsec"] * 3
REQUIREMENTS = [0.03] * 3 + [1.0] * 3 + [15.0] * 6 + [50.0] * 3 + [1.0] * 3 + [10.0] * 3
PAPER_NAMES = (
    ["D0x", "D0y", "D0z", "Wgxx", "Wgyy", "Wgzz"]
    + [None] * 6
    + ["E0x", "E0y", "E0z", "Kaxx", "Kayy", "Kazz"]
    + [None] * 3
)


def test_parameter_names_and_order():
    assert list(P.NAMES) == SPEC_NAMES
    assert P.N_PARAMS == 21
    assert [p.index for p in P.PARAMETERS] == list(range(21))
    assert all(P.INDEX[n] == i for i, n in enumerate(SPEC_NAMES))


def test_parameter_units_requirements_and_paper_names():
    assert [p.unit for p in P.PARAMETERS] == UNITS
    assert [p.requirement for p in P.PARAMETERS] == REQUIREMENTS
    for p, paper in zip(P.PARAMETERS, PAPER_NAMES, strict=True):
        if paper is not None:
            assert p.paper_name == paper


def test_si_factors():
    # conventions.md: 1 arcsec -> M = 4.8481e-6 (printed to 5 digits), 1 ug = 9.80665e-6 m/s^2
    # (exact by definition of standard gravity), 1 deg/h = pi/180/3600 rad/s (exact).
    expect = {"deg/h": math.pi / 180 / 3600, "ppm": 1e-6, "arcsec": math.pi / 180 / 3600, "ug": 9.80665e-6}
    for p in P.PARAMETERS:
        assert p.si_per_unit == pytest.approx(expect[p.unit], rel=1e-14)
    arcsec = P.PARAMETERS[P.INDEX["mgxy"]].si_per_unit
    assert arcsec == pytest.approx(4.8481e-6, abs=0.5e-10)
    # Round trip of the vector conversion (x * s / s differs from x by rounding only).
    x = np.arange(1.0, 22.0)
    np.testing.assert_allclose(P.from_si(P.to_si(x)), x, rtol=1e-15)
    np.testing.assert_allclose(P.to_si(x), x * np.array([expect[u] for u in UNITS]), rtol=1e-15)


def test_parameter_rows_and_columns_follow_names():
    for p in P.PARAMETERS:
        assert p.sensor == ("gyro" if p.name[1] == "g" else "accel")
        assert p.row == "xyz".index(p.name[2])
        if p.name[0] == "m":
            assert p.kind == "misalignment" and p.col == "xyz".index(p.name[3])
            if p.sensor == "accel":
                assert p.row > p.col, "M_a must be lower-triangular"
        elif p.name[0] == "s":
            assert p.kind == "scale" and p.col == p.row


def test_ratio_is_three_sigma_over_requirement():
    # sigma exactly at requirement/3 gives ratio 1 for every parameter.
    req_si = np.array(REQUIREMENTS) * np.array(
        [{"deg/h": DEG / 3600, "ppm": 1e-6, "arcsec": ARCSEC, "ug": UG}[u] for u in UNITS]
    )
    np.testing.assert_allclose(P.ratio(req_si / 3.0), np.ones(21), rtol=1e-12)


# ---------------------------------------------------------------------------
# The sensor error model


def realistic_values_si(seed: int) -> dict[str, float]:
    """Table 3's real-unit magnitudes with random signs and +-50 % spread."""
    rng = np.random.default_rng(seed)
    ref = table_column_si("table3_experiment", "reference_19pos")
    return {n: ref[n] * rng.uniform(0.5, 1.5) * rng.choice([-1.0, 1.0]) for n in SPEC_NAMES}


def test_apply_matches_sensor_formula():
    vals = realistic_values_si(11)
    em = ErrorModel(np.array([vals[n] for n in SPEC_NAMES]))
    Eg, bg = sensor_model(vals, "gyro")
    Ea, ba = sensor_model(vals, "accel")
    rng = np.random.default_rng(12)
    n = 500
    dtheta = rng.normal(scale=1e-3, size=(n, 3))
    dv = rng.normal(scale=0.05, size=(n, 3))
    dt = rng.uniform(0.004, 0.006, size=n)
    got_t, got_v = em.apply(dtheta, dv, dt)
    # Same linear formula evaluated differently: agreement to a few ulps of the inputs.
    np.testing.assert_allclose(got_t, dtheta @ Eg.T + bg * dt[:, None], rtol=0, atol=1e-17)
    np.testing.assert_allclose(got_v, dv @ Ea.T + ba * dt[:, None], rtol=0, atol=1e-15)
    # Scalar dt works the same way.
    got_t1, got_v1 = em.apply(dtheta, dv, 0.005)
    np.testing.assert_allclose(got_v1, dv @ Ea.T + ba * 0.005, rtol=0, atol=1e-15)


def test_misalignment_meaning_row_sensor_col_body_axis():
    # Only mayx set: a specific force purely along body x shows up on the y accelerometer.
    vals = dict.fromkeys(SPEC_NAMES, 0.0)
    vals["mayx"] = 100 * ARCSEC
    vals["mgzy"] = 50 * ARCSEC
    em = ErrorModel(np.array([vals[n] for n in SPEC_NAMES]))
    dth, dv = em.apply(np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]), 1.0)
    np.testing.assert_allclose(dv[0], [1.0, 100 * ARCSEC, 0.0], rtol=1e-15)
    np.testing.assert_allclose(dth[0], [0.0, 1.0, 50 * ARCSEC], rtol=1e-15)
    # M_a lower-triangular: whatever the values, the x accelerometer senses nothing of y or z.
    Ea = ErrorModel(np.array([realistic_values_si(3)[n] for n in SPEC_NAMES])).accel_matrix
    assert Ea[0, 1] == 0.0 and Ea[0, 2] == 0.0 and Ea[1, 2] == 0.0


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_compensate_is_exact_inverse_of_apply(seed):
    vals = realistic_values_si(seed)
    em = ErrorModel(np.array([vals[n] for n in SPEC_NAMES]))
    rng = np.random.default_rng(100 + seed)
    n = 1000
    dtheta = rng.normal(scale=1e-3, size=(n, 3))
    dv = rng.normal(scale=0.05, size=(n, 3))
    dt = np.full(n, 0.005)
    mt, mv = em.apply(dtheta, dv, dt)
    assert np.max(np.abs(mv - dv)) > 1e-7  # the errors really act
    ct, cv = em.compensate(mt, mv, dt)
    # I + S + M is within 1e-3 of identity (condition ~1), so the inverse recovers the
    # inputs to a few ulps: 1e-15 relative to the increments' scale.
    np.testing.assert_allclose(ct, dtheta, rtol=0, atol=1e-15 * 1e-3 * 10)
    np.testing.assert_allclose(cv, dv, rtol=0, atol=1e-15 * 0.05 * 10)
    # And the other way round.
    at, av = em.apply(*em.compensate(dtheta, dv, dt), dt)
    np.testing.assert_allclose(at, dtheta, rtol=0, atol=1e-17)
    np.testing.assert_allclose(av, dv, rtol=0, atol=1e-15)


def test_from_table2_equals_copied_table():
    std = table_column_units("table2_simulation", "standard")
    em = ErrorModel.from_table2()
    # Units -> SI -> units: rounding only.
    np.testing.assert_allclose(em.in_units(), [std[n] for n in SPEC_NAMES], rtol=1e-14)
    si = table_column_si("table2_simulation", "standard")
    np.testing.assert_allclose(em.values, [si[n] for n in SPEC_NAMES], rtol=1e-14)
    # Spot-check against the paper's numbers: 3 deg/h, 50 ppm, 100", 3000 ug, 30 ppm, 50".
    assert em.values[0] == pytest.approx(3 * math.pi / 180 / 3600, rel=1e-14)
    assert em.values[12] == pytest.approx(3000 * 9.80665e-6, rel=1e-14)
    assert em.values[20] == pytest.approx(50 * math.pi / 180 / 3600, rel=1e-14)


def test_table2_requirements_match_parameter_table():
    rows = {r["name"]: r for r in read_table(DATA / "table2_simulation.csv")}
    for p in P.PARAMETERS:
        assert float(rows[p.name]["requirement"]) == p.requirement
        assert rows[p.name]["unit"] == p.unit


@pytest.mark.parametrize(
    "name", ["table1_positions", "table1_gimbal_angles", "table2_simulation", "table3_experiment"]
)
def test_copied_tables_equal_shared_paper(name):
    shared = SHARED_PAPER / f"{name}.csv"
    if not shared.exists():
        pytest.skip("no ../shared/paper on this machine (a user's clone)")
    assert read_table(DATA / f"{name}.csv") == read_table(shared)
