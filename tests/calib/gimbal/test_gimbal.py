"""The gimbal (issue 13): which gimbal plays a flip, gimbal lock, limits, export, refusals."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import attitude, rodrigues

from calib.gimbal.description import DEFAULT_GIMBAL, load_gimbal
from calib.gimbal.encoders import encoder_track
from calib.gimbal.rule import plan_move, plan_sequence
from calib.sequence.definition import Sequence, Step, load_sequence, nominal_attitude, timeline
from calib.sequence.rate_profile import RateProfile
from seqdesign.cli import main
from seqdesign.cli.gimbal import read_schedule

SHIPPED = ["paper-9pos", "paper-9pos-turns", "designed-15min", "designed-30min", "designed-30min-9moves"]
D = math.radians
E = np.eye(3)


def gimbal_rule(angles_rad):
    """Conventions: R_Z(outer) R_X(middle) R_Y(inner), built here with Rodrigues' formula."""
    o, m, i = angles_rad
    return rodrigues(o * E[2]) @ rodrigues(m * E[0]) @ rodrigues(i * E[1])


def test_random_walk_of_flips_keeps_the_gimbal_rule():
    # 300 random 90/180/270-degree flips about random body axes: after every move the encoder
    # state reproduces the attitude C_old R_axis(angle), and a lock counter-rotation (when one
    # is needed) leaves the attitude unchanged. 1e-9: rounding over 300 products.
    rng = np.random.default_rng(13)
    state, C = np.zeros(3), np.eye(3)
    unlocks = 0
    for _ in range(300):
        ax, angle = int(rng.integers(3)), D(90.0 * rng.choice([-3, -2, -1, 1, 2, 3]))
        mv = plan_move(DEFAULT_GIMBAL, state, ax, angle, RateProfile(D(10)))
        assert mv.playable and mv.gimbal >= 0
        np.testing.assert_allclose(gimbal_rule(state + mv.unlock), C, atol=1e-9)
        unlocks += mv.unlock_s > 0
        C = C @ rodrigues(angle * E[ax])
        state = mv.state_end
        np.testing.assert_allclose(gimbal_rule(state), C, atol=1e-9)
    assert unlocks > 0  # the walk did meet gimbal lock


def lock_sequence(dwell=30.0, **kw):
    # X +90 brings the middle gimbal to +90 (body Y points south... along the outer axis):
    # lock. Z is then held by no gimbal (inner = 0 puts the middle axis on body X).
    return Sequence(
        name="lock",
        start=("east", "up", "south"),
        initial_dwell_s=20.0,
        steps=(Step("X", 90.0, 10.0, dwell, **kw), Step("Z", 90.0, 10.0, 20.0, **kw)),
    )


def test_flip_at_a_locked_rest_needs_a_counter_rotation():
    seq = lock_sequence()
    plan = plan_sequence(seq)
    assert plan.moves[0].gimbal == 1 and plan.moves[1].unlock_s > 0
    # Outer and inner counter-rotate by 90 deg (outer + inner constant at middle = +90).
    u = np.degrees(plan.moves[1].unlock)
    assert abs(u[2]) == pytest.approx(90.0) and u[0] == pytest.approx(-u[2]) and u[1] == 0.0
    assert plan.moves[1].unlock_s == pytest.approx(9.0)  # 90 deg at the flip's 10 deg/s
    assert plan.moves[1].gimbal == 1  # then the middle gimbal plays the Z flip
    # The encoder channels contain it, inside the rest, and the IMU stays still meanwhile.
    t = np.arange(0.0, seq.duration_s, 0.01)
    a, w = encoder_track(plan, seq, t)
    ((_, t_a, t_b, _),) = plan.unlocks
    assert t_b == pytest.approx(20.0 + 9.0 + 30.0) and t_a == pytest.approx(t_b - 9.0)
    during = (t > t_a) & (t < t_b)
    assert np.all(np.abs(np.degrees(w[during][:, [0, 2]])) > 0)
    C_nom = nominal_attitude(timeline(seq), t[during])
    C_enc = np.einsum(
        "ij,njk->nik", attitude("east", "up", "south"), np.array([gimbal_rule(x) for x in a[during]])
    )
    assert np.max(np.abs(C_enc - C_nom)) < 1e-12


def test_too_short_a_locked_rest_is_flagged():
    plan = plan_sequence(lock_sequence(dwell=5.0))
    assert [v.limit for v in plan.violations] == ["rest"]
    assert "lengthen" in str(plan.violations[0])


def test_middle_move_through_90_is_continuous():
    seq = Sequence(
        name="m", start=("east", "up", "south"), initial_dwell_s=10.0, steps=(Step("X", 270.0, 10.0, 10.0),)
    )
    t = np.arange(0.0, seq.duration_s, 0.005)
    a, _ = encoder_track(plan_sequence(seq), seq, t)
    # One middle move: outer and inner never move, the middle counts 0 -> 270 deg smoothly.
    assert np.all(a[:, [0, 2]] == 0.0)
    assert np.max(np.abs(np.diff(np.degrees(a[:, 1])))) <= 10.0 * 0.005 + 1e-9
    assert np.degrees(a[-1, 1]) == pytest.approx(270.0)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_sequences_play_on_the_default_gimbal_without_jumps(name):
    # Done means: no shipped sequence needs an instantaneous move. At 200 Hz no encoder steps
    # by more than the move's rate allows over a sample.
    seq = load_sequence(name)
    plan = plan_sequence(seq)
    assert plan.playable, [str(v) for v in plan.violations]
    t = np.arange(1, int(seq.duration_s * 200) + 1) / 200.0
    a, w = encoder_track(plan, seq, t)
    max_rate = max(s.rate_dps for s in seq.steps)
    assert np.max(np.abs(np.diff(np.degrees(a), axis=0))) <= max_rate * 0.005 * (1 + 1e-9)
    assert np.max(np.abs(np.degrees(w))) <= max_rate * (1 + 1e-12)


def export(tmp_path, seq, *extra):
    out = tmp_path / "commands.csv"
    res = CliRunner().invoke(main, ["export", str(seq), "-o", str(out), *extra])
    return res, out


@pytest.mark.parametrize("name", SHIPPED)
def test_export_replays_to_the_show_attitudes(tmp_path, name):
    res, out = export(tmp_path, name, "--rate-hz", "100")
    assert res.exit_code == 0, res.output
    header, rows = read_schedule(out)
    assert header["sequence"] == name and header["rate_hz"] == "100"
    shown = json.loads(CliRunner().invoke(main, ["show", name, "--json"]).stdout)
    C_start = attitude("east", "up", "south")
    for p in shown["positions"]:
        C_show = attitude(p["x"], p["y"], p["z"])
        inside = rows[(rows[:, 0] >= p["start_s"]) & (rows[:, 0] <= p["end_s"])]
        assert len(inside) > 0
        for r in inside[:: max(1, len(inside) // 20)]:
            C = C_start @ gimbal_rule(np.radians(r[1:4]))
            # 1e-9 rad: the schedule's angles carry 1e-10 deg.
            assert np.max(np.abs(C - C_show)) < 1e-9


def cable_wrap_sequence(tmp_path) -> Path:
    # Outer and inner moves only (a 90-degree middle move would reach the 15-deg lock margin),
    # a trapezoid within 20 deg/s and 10 deg/s^2, back at home at the end.
    p = tmp_path / "cw.toml"
    p.write_text(
        'name = "cw"\nstart = ["east", "up", "south"]\ninitial_dwell_s = 30\n'
        "accel_dps2 = 10\n"
        + "".join(
            f'[[step]]\naxis = "{a}"\nangle_deg = {g}\nrate_dps = 20\ndwell_s = 30\n'
            for a, g in [("Z", 90), ("Y", 90), ("X", 90), ("Y", -180), ("Y", 90)]
        )
    )
    return p


def test_cable_wrap_export_respects_every_limit(tmp_path):
    seq_path = cable_wrap_sequence(tmp_path)
    res, out = export(tmp_path, seq_path, "--gimbal", "cable-wrap", "--rate-hz", "200")
    assert res.exit_code == 0, res.output
    _, rows = read_schedule(out)
    t, a, w = rows[:, 0], rows[:, 1:4], rows[:, 4:7]
    assert np.max(np.abs(a)) <= 360.0 and np.max(np.abs(w)) <= 20.0 * (1 + 1e-9)
    # Acceleration from the commanded rates: finite differences of a trapezoid's rate are
    # exact except across its corners, where they average; never above the limit.
    acc = np.abs(np.diff(w, axis=0)) / np.diff(t)[:, None]
    assert np.max(acc) <= 10.0 * (1 + 1e-6)
    r = np.remainder(a[:, 1] - 90.0, 180.0)  # distance to the nearest 90 + k 180 deg: lock
    assert np.min(np.minimum(r, 180.0 - r)) >= 15.0
    np.testing.assert_allclose(a[-1], 0.0, atol=1e-9)  # home


# ---------------------------------------------------------------------------
# Refusals: one line, exit 2, nothing written


def refuse(tmp_path, args, *needles):
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2, res.output
    msg = res.output.strip().splitlines()
    assert len(msg) == 1 and msg[0].startswith("error: "), res.output
    for n in needles:
        assert n in msg[0], msg[0]
    assert not (tmp_path / "commands.csv").exists() and not (tmp_path / "run.npz").exists()
    return msg[0]


def gimbal_file(tmp_path, text):
    p = tmp_path / "g.toml"
    p.write_text(text)
    return str(p)


AXES = "[outer]\n[middle]\n[inner]\n"


@pytest.mark.parametrize(
    "text,needles",
    [
        ("name = \n", ["not valid TOML"]),
        ("[outer]\n[middle]\n", ["no [inner] table"]),
        ("[outer]\nmax_rate_dps = -5\n[middle]\n[inner]\n", ["[outer]", "max_rate_dps", "positive"]),
        ("[outer]\n[middle]\nrange_deg = [10, 360]\n[inner]\n", ["[middle]", "excludes the start"]),
        ("lock_margin_deg = 95\n" + AXES, ["lock_margin_deg"]),
        ('[outer]\n[middle]\n[inner]\nmax_accel_dps2 = "fast"\n', ["max_accel_dps2"]),
    ],
)
def test_bad_gimbal_file_is_refused(tmp_path, text, needles):
    g = gimbal_file(tmp_path, text)
    refuse(
        tmp_path,
        ["export", "paper-9pos", "--gimbal", g, "-o", str(tmp_path / "commands.csv")],
        "g.toml",
        *needles,
    )


LOCKING_QUARTER_TURN = """format_version = 1
name = "lock"
start = ["east", "up", "south"]
initial_dwell_s = 60.0
step = [{ axis = "X", angle_deg = -90.0, rate_dps = 10.0, accel_dps2 = 10.0, dwell_s = 60.0 }]
"""


def test_sequence_outside_the_gimbal_is_refused_by_export_and_simulate(tmp_path):
    # From the start attitude, a quarter turn about body X takes the middle gimbal to 90 deg
    # (docs/gimbal.md): gimbal lock, which the cable wrap keeps 15 deg away from.
    seq = tmp_path / "lock.toml"
    seq.write_text(LOCKING_QUARTER_TURN)
    msg = refuse(
        tmp_path,
        ["export", str(seq), "--gimbal", "cable-wrap", "-o", str(tmp_path / "commands.csv")],
        "step 1",
        "middle gimbal",
        "cable-wrap",
    )
    assert "gimbal lock" in msg and "15 deg" in msg
    msg = refuse(
        tmp_path,
        ["export", "paper-9pos", "--gimbal", "cable-wrap", "-o", str(tmp_path / "commands.csv")],
        "step 1",
        "outer gimbal",
    )
    assert "accelerates at most 10 deg/s^2" in msg
    refuse(
        tmp_path,
        [
            "simulate",
            "designed-30min",
            "--gimbal",
            "cable-wrap",
            "--noise-free",
            "-o",
            str(tmp_path / "run.npz"),
        ],
        "step 1",
        "cable-wrap",
    )


def test_show_flags_the_same_violations_without_refusing(tmp_path):
    res = CliRunner().invoke(main, ["show", "designed-30min", "--gimbal", "cable-wrap", "--json"])
    assert res.exit_code == 0
    doc = json.loads(res.output)
    assert not doc["playable"]  # 450 deg turns on a +-360 deg cable wrap
    assert any("range" in v or "beyond its range" in v for v in doc["violations"])
    seq = tmp_path / "lock.toml"
    seq.write_text(LOCKING_QUARTER_TURN)
    res = CliRunner().invoke(main, ["show", str(seq), "--gimbal", "cable-wrap", "--json"])
    assert res.exit_code == 0
    doc = json.loads(res.output)
    assert any("gimbal lock" in v for v in doc["violations"])
    assert any("home" in v for v in doc["violations"])  # it ends a quarter turn away
    text = CliRunner().invoke(main, ["show", "designed-15min"]).output
    assert "GIMBAL LOCK:" in text and "every move playable" in text


def test_export_bad_options(tmp_path):
    refuse(
        tmp_path,
        ["export", "paper-9pos", "-o", str(tmp_path / "commands.csv"), "--rate-hz", "0"],
        "--rate-hz",
    )
    refuse(tmp_path, ["export", "paper-9pos", "-o", str(tmp_path / "commands.txt")], ".csv")
    refuse(
        tmp_path,
        ["export", "paper-9pos", "--gimbal", "nope", "-o", str(tmp_path / "commands.csv")],
        "no gimbal file",
        "cable-wrap",
    )


def test_shipped_gimbal_files_load():
    cw = load_gimbal("cable-wrap")
    assert cw.end_at_home and cw.lock_margin == pytest.approx(D(15))
    assert all(
        a.min_angle == pytest.approx(D(-360))
        and a.max_rate == pytest.approx(D(20))
        and a.max_accel == pytest.approx(D(10))
        for a in cw.axes
    )
    sr = load_gimbal("slip-rings")
    assert all(math.isinf(a.max_angle) for a in sr.axes) and sr.lock_margin == 0.0


def test_simulator_encoder_channels_contain_the_counter_rotation():
    # simulate: during the counter-rotation the encoders turn (outer and inner opposite) while
    # the gyros see only the Earth rate: the IMU stays still.
    from calib.model.error_model import ErrorModel
    from calib.noise.profiles import load_profile
    from calib.sequence.kinematics import SimConfig
    from calib.sim.gimbal_run import SimOptions, simulate

    seq = lock_sequence()
    run, _ = simulate(
        seq,
        SimConfig(latitude_rad=D(40)),
        ErrorModel.zero(),
        load_profile("navigation"),
        options=SimOptions(noise=False),
    )
    ((_, t_a, t_b, _),) = plan_sequence(seq).unlocks
    inside = (run.time_s >= t_a - 1e-9) & (run.time_s <= t_b + 1e-9)  # 29..38 s: on samples
    g = run.gimbal_deg[inside]
    assert np.ptp(g[:, 0]) == pytest.approx(90.0, abs=1e-9)
    assert np.ptp(g[:, 2]) == pytest.approx(90.0, abs=1e-9)
    np.testing.assert_allclose(g[:, 0] + g[:, 2], g[0, 0] + g[0, 2], atol=1e-9)  # middle = +90
    # 7.3e-5 rad/s Earth rate * 5 ms = 3.6e-7 rad per sample at most.
    assert np.max(np.abs(run.dtheta_rad[inside])) < 4e-7


@pytest.mark.slow  # a 15-min 200 Hz simulation
def test_encoders_with_flip_errors_step_no_faster_than_the_moves():
    # With flip errors the encoders follow the nominal plan's gimbals, each turned by the
    # real angle: still no jump anywhere (the 90-degree jumps at 559.8 s).
    from calib.model.error_model import ErrorModel
    from calib.noise.profiles import load_profile
    from calib.sequence.kinematics import SimConfig
    from calib.sim.gimbal_run import SimOptions, simulate

    run, _ = simulate(
        load_sequence("designed-15min"),
        SimConfig(latitude_rad=D(40)),
        ErrorModel.zero(),
        load_profile("navigation"),
        options=SimOptions(flip_error_deg=0.5, noise=False, seed=3),
    )
    step = np.abs(np.diff(run.gimbal_deg, axis=0))
    assert np.max(step) <= 10.0 * 0.005 * (1 + 1e-9)


@pytest.mark.parametrize(
    "keys,needles",
    [
        ("accel_dps2 = -1\n", ["accel_dps2", "> 0"]),
        ("jerk_dps3 = 20\n", ["jerk_dps3", "without 'accel_dps2'"]),
        ('accel_dps2 = "fast"\n', ["accel_dps2", "number"]),
    ],
)
def test_bad_rate_profile_keys_are_refused(tmp_path, keys, needles):
    p = tmp_path / "s.toml"
    p.write_text('start = ["east", "up", "south"]\n[[step]]\naxis = "Z"\nangle_deg = 90\n' + keys)
    refuse(tmp_path, ["export", str(p), "-o", str(tmp_path / "commands.csv")], "step 1", *needles)
    refuse(tmp_path, ["show", str(p)], "step 1", *needles)
