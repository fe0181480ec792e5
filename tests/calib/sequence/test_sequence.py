"""Sequences: the paper's Table 1 from the shipped file, the flip rule, files in and out, refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import DWELL_S, FLIP_S, N_POS, attitude, rest_window, rot_about, table1_gimbal, table1_positions

from calib.errors import CalibError
from calib.gimbal.encoders import rest_positions
from calib.sequence.definition import (
    Sequence,
    Step,
    load_sequence,
    nominal_attitude,
    save_sequence,
    timeline,
)

# Grid attitudes are products of 0/+-1 matrices and cos/sin of multiples of 90 deg
# (cos(pi/2) = 6e-17): entries are exact to ~1e-15 -> 1e-12 tolerance.
EXACT = 1e-12


def test_paper_sequence_steps_match_table1(paper_seq):
    rows = table1_positions()
    assert len(paper_seq.steps) == N_POS - 1
    assert paper_seq.start == (rows[0]["pre_x"], rows[0]["pre_y"], rows[0]["pre_z"])
    for step, row in zip(paper_seq.steps, rows[:-1], strict=True):
        assert step.axis == row["axis"]
        assert step.angle_deg == float(row["angle_deg"])


def test_rest_positions_reproduce_table1(paper_seq):
    rows = table1_positions()
    pos = rest_positions(paper_seq)
    assert [p.number for p in pos] == list(range(1, N_POS + 1))
    for k, row in enumerate(rows):
        pre = (row["pre_x"], row["pre_y"], row["pre_z"])
        assert pos[k].directions == pre, f"position {k + 1}"
        np.testing.assert_allclose(pos[k].C_b_n, attitude(*pre), atol=EXACT)
        if row["post_x"]:  # rows 1..8: the flip leads to the next position
            post = (row["post_x"], row["post_y"], row["post_z"])
            assert pos[k + 1].directions == post, f"after flip {k + 1}"
            np.testing.assert_allclose(pos[k + 1].C_b_n, attitude(*post), atol=EXACT)


def test_rest_positions_gimbal_angles_match_table(paper_seq):
    pos = rest_positions(paper_seq)
    rows = table1_gimbal()
    assert len(rows) == len(pos)
    for p, row in zip(pos, rows, strict=True):
        want = [float(row["outer_deg"]), float(row["middle_deg"]), float(row["inner_deg"])]
        # Angles are rounded to 1e-9 deg by the code; the table is integral -> 1e-6 deg.
        np.testing.assert_allclose(p.gimbal_deg, want, rtol=0, atol=1e-6, err_msg=f"position {p.number}")
        assert not p.gimbal_lock


def test_gimbal_table_obeys_gimbal_rule():
    # The copied table itself: C_start R_Z(outer) R_X(middle) R_Y(inner) = Table 1's attitude,
    # and every flip moves exactly the gimbal named in 'moved'.
    C_start = attitude("east", "up", "south")
    prev = None
    for row, pos in zip(table1_gimbal(), table1_positions(), strict=True):
        o, m, i = (math.radians(float(row[c])) for c in ("outer_deg", "middle_deg", "inner_deg"))
        C = C_start @ rot_about("Z", o) @ rot_about("X", m) @ rot_about("Y", i)
        np.testing.assert_allclose(C, attitude(pos["pre_x"], pos["pre_y"], pos["pre_z"]), atol=EXACT)
        angles = [float(row[c]) for c in ("outer_deg", "middle_deg", "inner_deg")]
        if prev is not None:
            moved = [n for n, a, b in zip(("outer", "middle", "inner"), prev, angles, strict=True) if a != b]
            assert moved == [row["moved"]]
            assert abs(sum(b - a for a, b in zip(prev, angles, strict=True))) == 90.0
        prev = angles


def test_flip_rule_independent_construction(paper_seq):
    # C_new = C_old R_axis(angle), R built by Rodrigues about the *body* axis.
    C = attitude(*paper_seq.start)
    want = [C]
    for s in paper_seq.steps:
        C_new = C @ rot_about(s.axis, math.radians(s.angle_deg))
        # The flip axis keeps its direction in n; the right-hand rule for +90 about Z sends
        # body X to where body Y was (checked on the first flip, Table 1 row 1).
        ax = "XYZ".index(s.axis)
        np.testing.assert_allclose(C_new[:, ax], C[:, ax], atol=EXACT)
        C = C_new
        want.append(C)
    got = [p.C_b_n for p in rest_positions(paper_seq)]
    np.testing.assert_allclose(np.array(got), np.array(want), atol=EXACT)
    C0 = attitude("east", "up", "south")
    np.testing.assert_allclose((C0 @ rot_about("Z", math.pi / 2))[:, 0], C0[:, 1], atol=EXACT)
    np.testing.assert_allclose(timeline(paper_seq).C_end, want[-1], atol=EXACT)


def test_nominal_attitude_mid_flip_is_half_the_rotation(paper_seq):
    tl = timeline(paper_seq)
    C_start = attitude(*paper_seq.start)
    # Half way through flip 1 (t = 180 + 4.5 s) the body has turned 45 deg about Z.
    C = nominal_attitude(tl, np.array([DWELL_S + FLIP_S / 2]))[0]
    np.testing.assert_allclose(C, C_start @ rot_about("Z", math.radians(45.0)), atol=EXACT)
    # A quarter through flip 3 (-90 about X from position 3): -22.5 deg about X.
    C3 = attitude("north", "west", "up")
    t = 2 * (DWELL_S + FLIP_S) + DWELL_S + FLIP_S / 4
    C = nominal_attitude(tl, np.array([t]))[0]
    np.testing.assert_allclose(C, C3 @ rot_about("X", math.radians(-22.5)), atol=EXACT)


def test_paper_duration_and_rest_windows(paper_seq):
    assert paper_seq.duration_s == 9 * 180 + 8 * 9
    assert timeline(paper_seq).duration_s == 9 * 180 + 8 * 9
    for p in rest_positions(paper_seq):
        assert (p.start_s, p.end_s) == rest_window(p.number)


def test_save_load_round_trip(paper_seq, tmp_path):
    path = tmp_path / "copy.toml"
    save_sequence(paper_seq, path)
    back = load_sequence(path)
    assert back == paper_seq
    assert back.latitude_deg == 40.0 and back.height_m == 0.0
    a = rest_positions(paper_seq)
    b = rest_positions(back)
    for p, q in zip(a, b, strict=True):
        np.testing.assert_array_equal(p.C_b_n, q.C_b_n)
        np.testing.assert_array_equal(p.gimbal_deg, q.gimbal_deg)


def test_round_trip_of_odd_values(tmp_path):
    seq = Sequence(
        name="odd",
        start=("north", "east", "down"),
        steps=(Step("X", -37.5, 7.25, 0.0), Step("Z", 450.0, 20.0, 12.5)),
        initial_dwell_s=33.3,
        description='one\ntwo "quoted"',
        provenance={"objective": "worst ratio", "score": 1.25},
    )
    path = tmp_path / "odd.toml"
    save_sequence(seq, path)
    back = load_sequence(path)
    assert back == seq
    assert back.provenance == seq.provenance  # not part of ==, so checked on its own


def test_non_right_angle_loads_and_rotates(tmp_path):
    path = tmp_path / "odd.toml"
    path.write_text(
        'start = ["east", "up", "south"]\ninitial_dwell_s = 10\n'
        '[[step]]\naxis = "X"\nangle_deg = 37.5\ndwell_s = 20\n',
        "utf-8",
    )
    seq = load_sequence(path)
    assert seq.name == "odd"  # defaults to the file stem
    assert seq.steps[0].rate_dps == 10.0  # default rate of the conventions
    assert seq.duration_s == pytest.approx(10 + 37.5 / 10 + 20, abs=1e-12)
    pos = rest_positions(seq)
    assert len(pos) == 2
    want = attitude("east", "up", "south") @ rot_about("X", math.radians(37.5))
    np.testing.assert_allclose(pos[1].C_b_n, want, atol=EXACT)
    # About body X the middle gimbal turns (start: body X = middle axis).
    np.testing.assert_allclose(pos[1].gimbal_deg, [0.0, 37.5, 0.0], atol=1e-6)


GOOD_HEAD = 'name = "t"\nstart = ["east", "up", "south"]\n'
STEP = '[[step]]\naxis = "{axis}"\nangle_deg = {angle}\nrate_dps = {rate}\ndwell_s = {dwell}\n'


def step(axis="Z", angle="90", rate="10", dwell="180"):
    return STEP.format(axis=axis, angle=angle, rate=rate, dwell=dwell)


BAD = {
    "unknown_axis": (GOOD_HEAD + step() + step(axis="W"), ["step 2", "axis", "'W'"]),
    "missing_start": ('name = "t"\n' + step(), ["start"]),
    "non_orthogonal_start": ('start = ["east", "east", "up"]\n' + step(), ["start"]),
    "left_handed_start": ('start = ["east", "north", "down"]\n' + step(), ["start"]),
    "negative_dwell": (GOOD_HEAD + step(dwell="-5"), ["step 1", "dwell_s"]),
    "zero_rate": (GOOD_HEAD + step(rate="0"), ["step 1", "rate_dps"]),
    "angle_string": (GOOD_HEAD + step() + step(angle='"90"'), ["step 2", "angle_deg"]),
    "zero_angle": (GOOD_HEAD + step(angle="0"), ["step 1", "angle_deg"]),
    "not_toml": ("start = [east, up\n", ["TOML"]),
    "no_steps": (GOOD_HEAD, ["step"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_sequence_files_refused(tmp_path, case):
    text, parts = BAD[case]
    path = tmp_path / f"bad_{case}.toml"
    path.write_text(text, "utf-8")
    with pytest.raises(CalibError) as info:
        load_sequence(path)
    msg = str(info.value)
    assert path.name in msg, msg
    for part in parts:
        assert part in msg, f"{part!r} not in {msg!r}"


def test_not_utf8_refused(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(('name = "s\u00e9q"\n' + GOOD_HEAD + step()).encode("latin-1"))
    with pytest.raises(CalibError) as info:
        load_sequence(path)
    assert path.name in str(info.value) and "UTF-8" in str(info.value)


def test_unknown_sequence_name_refused():
    with pytest.raises(CalibError) as info:
        load_sequence("no-such-sequence-xyz")
    assert "no-such-sequence-xyz" in str(info.value)
    assert "paper-9pos" in str(info.value)  # lists what is available


def test_every_shipped_sequence_starts_with_a_rest_calibrate_can_align_on():
    # A designed sequence's first dwell may sit at the design's minimum; calibrate refuses a first
    # rest shorter than MIN_ALIGN_S, and motion detection takes up to FIRST_REST_MARGIN_S from its
    # end (designed-15min-gm, with a 10.0 s first rest, was once refused at a 10 s limit).
    from calib.sequence.definition import (
        FIRST_REST_MARGIN_S,
        MIN_ALIGN_S,
        builtin_sequence_dir,
        load_sequence,
    )

    for path in sorted(builtin_sequence_dir().glob("*.toml")):
        seq = load_sequence(path)
        assert seq.initial_dwell_s >= MIN_ALIGN_S + FIRST_REST_MARGIN_S, path.name


def test_design_refuses_dwells_too_short_to_align_on(tmp_path):
    from click.testing import CliRunner

    from seqdesign.cli import main

    out = tmp_path / "d.toml"
    r = CliRunner().invoke(main, ["design", "--budget-min", "5", "--min-dwell-s", "5", "-o", str(out)])
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert "--min-dwell-s" in r.output and "align" in r.output
    assert not out.exists()
