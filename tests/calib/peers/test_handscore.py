"""Scores of a calibration on a run placed by hand, and the other tools' results read as corrections."""

from __future__ import annotations

import gzip
import math

import numpy as np
import pytest
from realdata import FERRARIS, XSENS

from calib.calibration.correction import Correction, SensorCorrection
from calib.errors import CalibError
from calib.hand.rests import find_rests
from calib.nav.strapdown import sample_intervals
from calib.nav.transform import rotvec_to_dcm
from calib.noise.profiles import load_profile
from calib.peers.published import imucal_correction, parse_imu_tk, read_imu_tk, read_imucal
from calib.peers.scores import RestSpans, axes_of, force_spread, pose_to_pose, score

G = 9.81
RATE_HZ = 100.0
# Each move: a body axis and an angle turned about it at a constant rate over 1 s.
MOVES = [((1.0, 0.0, 0.0), -90.0), ((0.0, 1.0, 0.0), 90.0), ((0.0, 0.0, 1.0), 90.0), ((1.0, 0.0, 0.0), 180.0)]
REST_SAMPLES, MOVE_SAMPLES = 200, 100


def synthetic_run():
    """True rates (rad/s) and specific force (m/s^2) of rests and constant-rate moves, with the rests.

    Rest 0 has body z up; each move turns the body about a fixed body axis at a
    constant rate, so every sample's increment is exact (parallel increments: no coning).
    """
    dt = 1.0 / RATE_HZ
    C = np.eye(3)  # body to a fixed (level) frame
    up = np.array([0.0, 0.0, G])
    rates, forces, start, end = [], [], [], []
    n = 0
    for k in range(len(MOVES) + 1):
        start.append(n)
        rates.append(np.zeros((REST_SAMPLES, 3)))
        forces.append(np.tile(C.T @ up, (REST_SAMPLES, 1)))
        n += REST_SAMPLES
        end.append(n)
        if k == len(MOVES):
            break
        axis, angle = MOVES[k]
        w = np.radians(angle) / (MOVE_SAMPLES * dt) * np.asarray(axis)
        f = []
        for _ in range(MOVE_SAMPLES):
            C = C @ rotvec_to_dcm(w * dt)
            f.append(C.T @ up)
        rates.append(np.tile(w, (MOVE_SAMPLES, 1)))
        forces.append(np.array(f))
        n += MOVE_SAMPLES
    time_s = dt * np.arange(1, n + 1)
    return np.vstack(rates), np.vstack(forces), time_s, np.array(start), np.array(end)


def _sensor(M, b, unit="counts") -> SensorCorrection:
    return SensorCorrection(
        np.asarray(M, float), np.asarray(b, float), np.full((3, 3), np.nan), np.full(3, np.nan), unit
    )


M_G = np.array([[2.0e-4, 1e-6, -2e-6], [3e-6, 2.1e-4, 1e-6], [0.0, -4e-6, 1.9e-4]])
M_A = np.array([[2.4e-3, 0.0, 0.0], [1e-5, 2.42e-3, 0.0], [-2e-5, 3e-5, 2.41e-3]])
B_G, B_A = np.array([32768.0, 32466.0, 32485.0]), np.array([33123.0, 33276.0, 32360.0])
G_SENS = np.array([[0.5, -0.2, 0.1], [0.0, 0.3, -0.4], [0.2, 0.1, -0.6]])  # counts per m/s^2
TRUE = Correction(_sensor(M_G, B_G), _sensor(M_A, B_A), G_SENS)


def raw_of(c: Correction, rate, force):
    """Raw samples that ``c`` turns into ``rate`` and ``force`` exactly."""
    raw_a = np.linalg.solve(c.accel.M, force.T).T + c.accel.b
    raw_g = np.linalg.solve(c.gyro.M, rate.T).T + c.gyro.b
    if c.g_sensitivity is not None:
        raw_g = raw_g + force @ c.g_sensitivity.T
    return raw_g, raw_a


def test_a_perfect_correction_scores_zero_spread_and_zero_angle():
    rate, force, t, start, end = synthetic_run()
    raw_g, raw_a = raw_of(TRUE, rate, force)
    s = score(TRUE, raw_g, raw_a, RestSpans(t, start, end))
    assert s.spread.std < 1e-12 and s.spread.range < 1e-12
    assert s.spread.mean == pytest.approx(G, abs=1e-12)
    assert s.poses.used.all()
    assert s.poses.max_deg < 1e-9
    # the moves' turns as built
    assert s.poses.turn_deg == pytest.approx([abs(a) for _, a in MOVES], abs=1e-9)


def test_a_scale_error_on_x_gives_its_spread():
    """|f| reads g (1 + e) only where x is vertical, g elsewhere."""
    rate, force, t, start, end = synthetic_run()
    e = 1e-3
    up = force[start] / G
    wrong = force * np.array([1.0 + e, 1.0, 1.0])
    s = force_spread(wrong, start, end)
    expected = G * np.sqrt(1.0 + (2 * e + e * e) * up[:, 0] ** 2)
    assert s.magnitude == pytest.approx(expected, rel=1e-12)
    # up at rests 0..4 is body z, -y, -y, -x, -x: two of five poses read g (1 + e)
    assert up == pytest.approx(
        np.array([[0, 0, 1], [0, -1, 0], [0, -1, 0], [-1, 0, 0], [-1, 0, 0]]), abs=1e-12
    )
    mags = G * np.array([1.0, 1.0, 1.0, 1.0 + e, 1.0 + e])
    assert s.range == pytest.approx(G * e, rel=1e-9)
    assert s.std == pytest.approx(np.std(mags), rel=1e-9)
    assert s.std == pytest.approx(G * e * math.sqrt(2 / 5 * 3 / 5), rel=1e-6)


def test_a_gyro_scale_error_turns_the_vertical_by_the_error_times_the_angle():
    """Move 0 turns -90 deg about body x with z up: a scale error e on x leaves the vertical e * 90 deg off.

    A turn about the vertical does not move it: a scale error on that axis is not seen (move 1, about y
    with -y up; so are the 360 deg turns of a Ferraris session).
    """
    rate, force, t, start, end = synthetic_run()
    e = 2e-3
    s = pose_to_pose(rate * np.array([1.0 + e, 1.0, 1.0]), force, RestSpans(t, start, end))
    assert s.angle_deg[0] == pytest.approx(e * 90.0, rel=1e-6)
    assert s.angle_deg[2] < 1e-9  # about body z: x's scale plays no part
    s = pose_to_pose(rate * np.array([1.0, 1.0 + e, 1.0]), force, RestSpans(t, start, end))
    assert s.angle_deg[1] < 1e-9


def test_moves_with_clipped_samples_are_left_out():
    rate, force, t, start, end = synthetic_run()
    clipped = np.zeros(len(t), dtype=bool)
    clipped[end[1] + 3] = True
    s = pose_to_pose(rate, force, RestSpans(t, start, end, clipped, latitude_deg=45.0))
    assert list(s.used) == [True, False, True, True]
    assert np.isnan(s.angle_deg[1]) and s.rms_deg < 1e-9
    # the Earth's turn left out over a 1 s move at 45 deg
    assert s.earth_bound_deg == pytest.approx(math.degrees(7.292115e-5 * math.cos(math.pi / 4)), rel=1e-3)


def test_sensing_axes_are_the_rows_of_M_inverse():
    """Raw = S c + b: channel i senses along row i of S = M^-1, with |s_i| raw per SI."""
    d = math.radians(0.1)
    S = np.array([[400.0, 0.0, 0.0], [410.0 * math.sin(d), 410.0 * math.cos(d), 0.0], [0.0, 0.0, 420.0]])
    a = axes_of(_sensor(np.linalg.inv(S), [1.0, 2.0, 3.0]), zero=[0.0, 0.0, 1.0])
    assert a.scale == pytest.approx([1 / 400, 1 / 410, 1 / 420], rel=1e-12)
    assert a.nonorthogonality_arcsec == pytest.approx([-360.0, 0.0, 0.0], abs=1e-6)
    assert a.bias_si == pytest.approx([1 / 400, 2 / 410, 2 / 420], rel=1e-12)
    # a rotation of the calibrated frame (M -> Q M) changes none of them
    Q = rotvec_to_dcm(np.array([0.3, -0.2, 0.5]))
    b = axes_of(_sensor(Q @ np.linalg.inv(S), [1.0, 2.0, 3.0]))
    assert b.scale == pytest.approx(a.scale, rel=1e-12)
    assert b.nonorthogonality_arcsec == pytest.approx(a.nonorthogonality_arcsec, abs=1e-6)


IMU_TK_TEXT = """# a comment
## acc (m/s^2 per count)
1 0.01 0
0 1 0
-0 0 1

2 0 0
0 3 0
0 0 4

1
2
3

## gyro
1 0 0
0 1 0
0 0 1

0.5 0 0
0 0.5 0
0 0 0.5

10
20
30
"""


def test_imu_tk_is_T_K_raw_less_b():
    c = parse_imu_tk(IMU_TK_TEXT)
    # T K = [[2, 0.03, 0], [0, 3, 0], [0, 0, 4]]; raw - b = (1, 1, 1)
    assert c.accel.M == pytest.approx(np.array([[2.0, 0.03, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 4.0]]))
    w, f = c.apply(np.array([[12.0, 20.0, 34.0]]), np.array([[2.0, 3.0, 4.0]]))
    assert f[0] == pytest.approx([2.03, 3.0, 4.0])
    assert w[0] == pytest.approx([1.0, 0.0, 2.0])
    assert c.g_sensitivity is None


def test_imu_tk_without_a_section_is_refused():
    with pytest.raises(CalibError, match="gyro"):
        parse_imu_tk(IMU_TK_TEXT.split("## gyro")[0])


def test_imucal_is_R_inverse_K_inverse_raw_less_b():
    """K = diag(2, 4, 5), R = 90 deg about z: M = R^T K^-1 = [[0, 1/4, 0], [-1/2, 0, 0], [0, 0, 1/5]]."""
    R = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    K = [[2.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 5.0]]
    doc = {
        "acc_unit": "m/s^2",
        "gyr_unit": "deg/s",
        "from_acc_unit": "m/s^2",
        "from_gyr_unit": "deg/s",
        "cal_type": "Ferraris",
        "K_a": K,
        "R_a": R,
        "b_a": [1.0, 1.0, 1.0],
        "K_g": K,
        "R_g": R,
        "b_g": [0.5, 0.0, 0.0],
        "K_ga": [[0.1, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
    }
    c = imucal_correction(doc)
    M = np.array([[0.0, 0.25, 0.0], [-0.5, 0.0, 0.0], [0.0, 0.0, 0.2]])
    assert c.accel.M == pytest.approx(M)
    assert c.gyro.M == pytest.approx(M * math.pi / 180.0)
    # acc: raw (3, 5, 6) - b = (2, 4, 5) -> (1, -1, 1) m/s^2
    # gyr: raw (4.6, 8, 10) - K_ga acc (0.1, 0, 0) - b_g (0.5, 0, 0) = (4, 8, 10) -> (2, -2, 2) deg/s
    w, f = c.apply(np.array([[4.6, 8.0, 10.0]]), np.array([[3.0, 5.0, 6.0]]))
    assert f[0] == pytest.approx([1.0, -1.0, 1.0])
    assert w[0] == pytest.approx(np.radians([2.0, -2.0, 2.0]))
    with pytest.raises(CalibError, match="units"):
        imucal_correction({**doc, "acc_unit": "g"})


def test_imu_tk_result_on_its_log_reads_gravity():
    d = XSENS
    c = read_imu_tk(d / "imu_tk-result.txt")
    acc = np.loadtxt(gzip.open(d / "xsens_acc.mat.gz"), max_rows=4000)
    gyr = np.loadtxt(gzip.open(d / "xsens_gyro.mat.gz"), max_rows=4000)
    w, f = c.apply(gyr[:, 1:], acc[:, 1:])
    # the initial static stretch: |f| near local gravity, the rate near zero (imu_tk's bias is its mean)
    assert np.linalg.norm(f[200:], axis=1).mean() == pytest.approx(9.81744, abs=0.01)
    assert np.degrees(np.linalg.norm(w[200:].mean(0))) * 3600 < 60


def test_imucal_result_on_its_log_reads_each_face():
    d = FERRARIS
    c = read_imucal(d / "example_ferraris_session-imucal-result.json")
    a = np.loadtxt(d / "example_ferraris_session.csv", delimiter=",", skiprows=1)
    w, f = c.apply(a[:, 1:4], a[:, 4:7])
    faces = {"x_p": (0, 1), "x_a": (0, -1), "y_p": (1, 1), "y_a": (1, -1), "z_p": (2, 1), "z_a": (2, -1)}
    sections = {"x_p": (540, 1271), "x_a": (1620, 2361), "y_p": (2814, 3298)}
    sections |= {"y_a": (3740, 4152), "z_p": (4522, 4975), "z_a": (5376, 5983)}
    for face, (axis, sign) in faces.items():
        lo, hi = sections[face]
        expected = np.zeros(3)
        expected[axis] = sign * 9.81
        assert f[lo:hi].mean(0) == pytest.approx(expected, abs=0.05)  # a face within 0.3 deg
        assert np.degrees(np.abs(w[lo:hi].mean(0))).max() < 0.02  # deg/s


def test_imu_tk_scored_on_its_log():
    """imu_tk's result on its log's rests: |f| 9.81744 within mm/s^2, the vertical carried within 1 deg."""
    d = XSENS
    acc = np.loadtxt(gzip.open(d / "xsens_acc.mat.gz"))
    gyr = np.loadtxt(gzip.open(d / "xsens_gyro.mat.gz"))
    t = acc[:, 0]
    nominal = (acc[:, 1:] - [33123.0, 33276.0, 32360.0]) / [415.0, 413.0, 415.0]
    rate = (gyr[:, 1:] - [32768.0, 32466.0, 32485.0]) / [4778.0, 4758.0, 4766.0]
    dt = sample_intervals(t)
    p = load_profile("mems")
    rests = find_rests(rate * dt[:, None], nominal * dt[:, None], dt, p.arw, p.vrw)
    s = score(
        read_imu_tk(d / "imu_tk-result.txt"), gyr[:, 1:], acc[:, 1:], RestSpans(t, rests.start, rests.end)
    )
    assert rests.count > 30
    assert s.spread.mean == pytest.approx(9.81744, abs=0.002)
    assert s.spread.std < 0.002
    assert s.poses.rms_deg < 1.0
