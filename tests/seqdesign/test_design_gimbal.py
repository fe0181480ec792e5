"""design --gimbal (issue 13, point 4): the search walks only moves the gimbal plays."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import REPO

from calib.gimbal.description import gimbal_from_dict, load_gimbal
from calib.gimbal.rule import check_playable, plan_sequence
from calib.nav.site import Site
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from seqdesign.cli import main
from seqdesign.search import Constraints, SearchModel, beam_search, to_sequence
from seqdesign.search.gimbal import gimbal_limits

# A tight gimbal: +-180 deg wraps make most long moves and any winding unplayable,
# and the lock margin keeps the middle gimbal still on a 90-degree grid.
TIGHT = {
    "name": "tight",
    "lock_margin_deg": 15,
    "end_at_home": True,
    "outer": {"range_deg": [-180, 180], "max_rate_dps": 20, "max_accel_dps2": 10},
    "middle": {"range_deg": [-180, 180], "max_rate_dps": 20, "max_accel_dps2": 10},
    "inner": {"range_deg": [-180, 180], "max_rate_dps": 20, "max_accel_dps2": 5},
}


def _tight_constraints(**kw) -> Constraints:
    g = gimbal_from_dict(TIGHT, "tight.toml")
    lim = gimbal_limits(g, None)
    return Constraints(max_flips=5, max_quarters=3, min_dwell_s=30.0, budget_s=480.0, gimbal=g, **lim, **kw)


def test_limits_are_the_slowest_axis():
    lim = gimbal_limits(gimbal_from_dict(TIGHT, "tight.toml"), None)
    assert lim == {"rate_dps": 20.0, "accel_dps2": 5.0, "jerk_dps3": None}


def test_search_proposes_only_playable_walks_that_end_at_home():
    c = _tight_constraints()
    model = SearchModel.build(c, 40.0, Site.at(math.radians(40.0)), load_profile("navigation"))
    finals, n = beam_search(model, "worst", beam_width=30, keep=5)
    assert finals and n > 0
    for f in finals:
        seq = to_sequence(f.walk, c, [40.0] * (len(f.walk) + 1), "t")
        plan = plan_sequence(seq, c.gimbal)
        check_playable(plan, "test")  # raises on any violation, including not ending at home
        assert np.allclose(plan.moves[-1].state_end, 0.0, atol=1e-9)
        assert all(s.accel_dps2 == 5.0 for s in seq.steps)
        # the budget counts the trapezoid: angle/rate + rate/accel per move (docs/gimbal.md)
        turns = sum(abs(m.angle_deg) / 20.0 + 20.0 / 5.0 for m in f.walk)
        assert f.time_s == pytest.approx(40.0 * (len(f.walk) + 1) + turns, abs=1e-9)
        assert f.time_s == pytest.approx(seq.duration_s, abs=1e-9)


def test_every_child_the_search_keeps_is_playable():
    # Not only the finals: every partial walk of every depth replays through plan_sequence
    # without a violation (end_at_home aside, which only complete walks must meet).
    c = _tight_constraints()
    model = SearchModel.build(c, 40.0, Site.at(math.radians(40.0)), load_profile("navigation"))
    frontier = [model.start_candidate()]
    # From home the middle gimbal holds body X, and any X move brings it within 15 deg of
    # lock: refused. Y (inner) and Z (outer) moves of 270 deg go beyond +-180: refused.
    # Kept: Y and Z, both signs, 90 and 180 deg = 8 of the 18 moves.
    assert len(model.moves) == 18
    assert len(model.extend(frontier, "worst")) == 8
    for _ in range(3):
        kids = model.extend(frontier, "worst")
        for k in kids:
            plan = plan_sequence(to_sequence(k.walk, c, [40.0] * (len(k.walk) + 1), "t"), c.gimbal)
            assert [v for v in plan.violations if v.limit != "home"] == []
            assert np.allclose(plan.moves[-1].state_end, k.enc, atol=1e-9)
        frontier = sorted(kids, key=lambda k: k.score)[:20]


def _write(tmp_path, text) -> str:
    p = tmp_path / "g.toml"
    p.write_text(text)
    return str(p)


@pytest.mark.slow
def test_design_cli_writes_a_playable_file_naming_the_gimbal(tmp_path):
    # ~10 s: a 5-minute design on the shipped cable-wrap gimbal, small beam, nominal mounting
    # only, no refinement (the figure does not matter here, only what is written).
    out = tmp_path / "d.toml"
    gimbal = REPO / "sequences" / "gimbals" / "cable-wrap.toml"
    res = CliRunner().invoke(
        main,
        [
            "design",
            "--budget-min",
            "5",
            "--max-flips",
            "4",
            "--max-quarters",
            "2",
            "--beam-width",
            "5",
            "--no-refine",
            "--tolerance-deg",
            "0",
            "--gimbal",
            str(gimbal),
            "-o",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    prov = tomllib.loads(out.read_text())["provenance"]
    assert prov["gimbal"] == "cable-wrap" and prov["gimbal_file"] == str(gimbal)
    assert len(prov["gimbal_sha256"]) == 64
    seq = load_sequence(out)
    check_playable(plan_sequence(seq, load_gimbal(gimbal)), "test")
    assert all(s.rate_dps == 20.0 and s.accel_dps2 == 10.0 for s in seq.steps)
    assert seq.duration_s <= 300.0 + 1e-6
    res = CliRunner().invoke(
        main, ["export", str(out), "--gimbal", str(gimbal), "-o", str(tmp_path / "c.csv")]
    )
    assert res.exit_code == 0, res.output


@pytest.mark.parametrize(
    "text, needle",
    [
        ("name = 'x'\n[outer\n", "TOML"),  # malformed
        ("[outer]\nrange_deg = [10, 360]\n[middle]\n[inner]\n", "excludes the start"),  # impossible
        ("[outer]\nmax_rate_dps = -5\n[middle]\n[inner]\n", "positive"),
        ("[outer]\nmax_jerk_dps3 = 50\n[middle]\n[inner]\n", "limits jerk but not acceleration"),
    ],
)
def test_bad_gimbal_is_refused_by_design(tmp_path, text, needle):
    out = tmp_path / "d.toml"
    res = CliRunner().invoke(
        main, ["design", "--budget-min", "5", "--gimbal", _write(tmp_path, text), "-o", str(out)]
    )
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0], res.output
    assert "Traceback" not in res.output and not out.exists()


def test_rate_above_the_gimbal_is_refused(tmp_path):
    out = tmp_path / "d.toml"
    res = CliRunner().invoke(
        main, ["design", "--budget-min", "5", "--gimbal", "cable-wrap", "--rate-dps", "30", "-o", str(out)]
    )
    assert res.exit_code == 2 and not out.exists()
    assert res.output.count("\n") == 1 and "above the 20 deg/s" in res.output


def test_sequence_outside_the_gimbal_is_refused_with_one_line(tmp_path):
    # designed-30min turns 450 deg at constant rate (no accel_dps2): the cable wrap's +-360 deg
    # range and 10 deg/s^2 refuse it
    out = tmp_path / "c.csv"
    res = CliRunner().invoke(main, ["export", "designed-30min", "--gimbal", "cable-wrap", "-o", str(out)])
    assert res.exit_code == 2 and not out.exists()
    assert res.output.count("\n") == 1 and "gimbal" in res.output


@pytest.mark.parametrize("name", ["designed-30min-cable-wrap", "designed-30min-slip-rings"])
def test_shipped_gimbal_designs_play_on_their_gimbal(name):
    # The file names the gimbal it was designed for (with the file's hash); every move
    # replays through plan_sequence on that gimbal, with an acceleration limit per step
    # (no instantaneous rate step), and the run lasts at most its 30-min budget.
    from calib.io.files import sha256_file

    path = REPO / "sequences" / f"{name}.toml"
    prov = tomllib.loads(path.read_text())["provenance"]
    gimbal_file = REPO / prov["gimbal_file"]
    assert sha256_file(gimbal_file) == prov["gimbal_sha256"]
    seq = load_sequence(path)
    g = load_gimbal(gimbal_file)
    check_playable(plan_sequence(seq, g), name)
    assert all(s.accel_dps2 is not None for s in seq.steps)
    assert seq.duration_s <= prov["budget_min"] * 60.0 + 1e-6
