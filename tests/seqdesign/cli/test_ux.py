"""What trips a new user: design names, sites mixed by compare, progress of a design, the export refusal."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest
from click.testing import CliRunner

from calib.runlog import read_run
from calib.sequence.definition import load_sequence, save_sequence
from seqdesign.cli import main
from seqdesign.cli.design import ProgressLines
from seqdesign.search import Progress

# A design of seconds: three quarter turns, a narrow beam, no refinement, nominal mounting.
TINY = [
    "design",
    "--budget-min",
    "2",
    "--max-flips",
    "3",
    "--max-quarters",
    "1",
    "--beam-width",
    "8",
    "--no-refine",
    "--tolerance-deg",
    "0",
]


def _run(args, ok=True):
    r = CliRunner().invoke(main, [str(a) for a in args])
    if ok:
        assert r.exit_code == 0, r.output
    return r


@pytest.fixture(scope="module")
def two_designs(tmp_path_factory):
    """Two designs of the same search written to different files (mine.toml, yours.toml)."""
    d = tmp_path_factory.mktemp("designs")
    _run([*TINY, "-o", d / "mine.toml"])
    _run([*TINY, "--min-dwell-s", "15", "-o", d / "yours.toml"])
    return d


# ---------------------------------------------------------------------------
# Names


def test_output_file_names_the_design(two_designs):
    assert load_sequence(two_designs / "mine.toml").name == "mine"
    assert load_sequence(two_designs / "yours.toml").name == "yours"


def test_two_designs_compare_as_two_columns(two_designs):
    r = _run(["compare", two_designs / "mine.toml", two_designs / "yours.toml", "--tolerance-deg", "0"])
    header = r.stdout.splitlines()[0].split()
    assert header == ["mine", "yours"]
    doc = json.loads(
        _run(
            [
                "compare",
                two_designs / "mine.toml",
                two_designs / "yours.toml",
                "--tolerance-deg",
                "0",
                "--json",
            ]
        ).stdout
    )
    assert [s["sequence"] for s in doc["sequences"]] == ["mine", "yours"]


def test_name_option_overrides_and_default_name_stays(tmp_path, monkeypatch):
    _run([*TINY, "-o", tmp_path / "file.toml", "--name", "lab-a"])
    assert load_sequence(tmp_path / "file.toml").name == "lab-a"
    monkeypatch.chdir(tmp_path)  # without -o/--name: designed-<budget>min.toml, named so
    _run(TINY)
    assert load_sequence(tmp_path / "designed-2min.toml").name == "designed-2min"


def test_pareto_names_each_budget_after_the_output_stem(tmp_path):
    args = [a for a in TINY if a not in ("--budget-min", "2")]
    _run([*args, "--pareto", "--budgets", "2,3", "-o", tmp_path / "front"])
    for b in (2, 3):
        assert load_sequence(tmp_path / f"front-{b}min.toml").name == f"front-{b}min"
    assert (tmp_path / "front.csv").exists()


def test_refuses_an_empty_name_before_searching(tmp_path):
    r = _run([*TINY, "-o", tmp_path / "x.toml", "--name", " "], ok=False)
    assert r.exit_code == 2 and "--name" in r.stderr and "Traceback" not in r.output
    assert not (tmp_path / "x.toml").exists()


def test_run_of_a_named_design_calibrates_without_a_warning_about_its_sequence(two_designs, tmp_path):
    run = tmp_path / "run.npz"
    _run(["simulate", two_designs / "mine.toml", "-o", run, "--seed", "1"])
    r = _run(["calibrate", run, "--sequence", two_designs / "mine.toml", "-o", tmp_path / "r.toml"])
    assert "not used" not in r.stderr
    assert read_run(run).sequence_name == "mine"  # the run names the design it followed


# ---------------------------------------------------------------------------
# compare at mixed sites


@pytest.fixture(scope="module")
def calgary(tmp_path_factory):
    """paper-9pos, as designed for Calgary (51.08 deg, 1045 m)."""
    path = tmp_path_factory.mktemp("site") / "calgary.toml"
    seq = load_sequence("paper-9pos")
    save_sequence(replace(seq, name="calgary", latitude_deg=51.08, height_m=1045.0), path)
    return path


def test_compare_warns_when_the_sequences_have_different_sites(calgary):
    r = _run(["compare", "paper-9pos", calgary, "--tolerance-deg", "0"])
    warning = [line for line in r.stderr.splitlines() if line.startswith("warning:")]
    assert len(warning) == 1
    assert "paper-9pos at 40 deg" in warning[0] and "calgary at 51.08 deg, 1045 m" in warning[0]
    assert "--latitude" in warning[0] and "--height" in warning[0]
    doc = json.loads(_run(["compare", "paper-9pos", calgary, "--tolerance-deg", "0", "--json"]).stdout)
    assert len(doc["warnings"]) == 1 and "--latitude" in doc["warnings"][0]
    # the sites really differ: each sequence analysed at its own
    assert [s["latitude_deg"] for s in doc["sequences"]] == [40.0, 51.08]


def test_compare_at_one_site_does_not_warn(calgary):
    r = _run(["compare", "paper-9pos", calgary, "--tolerance-deg", "0", "--latitude", "51.08", "--json"])
    doc = json.loads(r.stdout)  # the latitude is one; the heights still differ: --height alone
    assert "--height" in doc["warnings"][0] and "--latitude" not in doc["warnings"][0]
    args = [
        "compare",
        "paper-9pos",
        calgary,
        "--tolerance-deg",
        "0",
        "--latitude",
        "51.08",
        "--height",
        "1045",
    ]
    r = _run([*args, "--json"])
    assert "warning" not in r.stderr and "warnings" not in json.loads(r.stdout)
    assert {s["latitude_deg"] for s in json.loads(r.stdout)["sequences"]} == {51.08}


# ---------------------------------------------------------------------------
# Progress


def test_design_progress_goes_to_stderr_and_json_stays_one_document(tmp_path):
    args = [a for a in TINY if a != "--no-refine"]
    r = _run([*args, "-o", tmp_path / "p.toml", "--json"])
    doc = json.loads(r.stdout)  # stdout is the document and nothing else
    assert doc["designs"][0]["budget_min"] == 2.0
    for phase in ("searching", "screening", "worst-case re-scoring", "refin", "final check", "best of"):
        assert phase in r.stderr, phase
    assert "searching" not in r.stdout and "[2 min]" not in r.stdout


def _feed(lines, clock, reports):
    for t, r in reports:
        clock[0] = t
        lines(10.0, r)


def test_progress_lines_say_each_phase_and_are_rate_limited(capsys):
    clock = [0.0]
    lines = ProgressLines(clock=lambda: clock[0], every_s=2.0)
    _feed(
        lines,
        clock,
        [
            (0.0, Progress("search", "searching 4 beams", 0, 40)),
            (10.0, Progress("search", "beam 1 of 4", 10, 40, 5000, 2.5)),
            (11.0, Progress("search", "beam 2 of 4", 20, 40, 9000, 2.4)),  # within 2 s: not said
            (20.0, Progress("search", "beam 3 of 4", 30, 40, 12000, 2.3)),
            (20.5, Progress("screen", "screening 8 candidates", 0, 8)),  # a new phase: always said
        ],
    )
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 4 and "beam 2 of 4" not in " ".join(err)
    assert err[0].startswith("[10 min] searching 4 beams")
    # after 10 s, a quarter of the work: three quarters left at the same pace
    assert "500 candidates/s" in err[1] and "about 30 s left in this phase" in err[1]
    assert "best so far 2.500 (search score)" in err[1]
    assert "then screening, worst-case re-scoring, refinement, final check" in err[1]
    # after 20 s, three quarters done: a quarter left, a third of the time taken so far
    assert "about 7 s left" in err[2] and "600 candidates/s" in err[2]
    assert err[3].startswith("[10 min] screening 8 candidates (at 20 s)")


def test_slow_candidates_are_said_in_seconds_each(capsys):
    clock = [0.0]
    lines = ProgressLines(clock=lambda: clock[0], every_s=2.0)
    _feed(
        lines,
        clock,
        [(0.0, Progress("box", "box", 0, 6)), (30.0, Progress("box", "re-scored 2 of 6", 2, 6, 2, 1.7))],
    )
    err = capsys.readouterr().err.splitlines()
    assert "15.0 s per candidate" in err[1] and "about 1 min 00 s left" in err[1]


# ---------------------------------------------------------------------------
# export of a design made without --gimbal


def test_export_on_a_gimbal_the_design_ignored_says_to_redesign_for_it(two_designs, tmp_path):
    out = tmp_path / "s.csv"
    r = _run(["export", two_designs / "mine.toml", "--gimbal", "cable-wrap", "-o", out, "--json"], ok=False)
    assert r.exit_code == 2 and "Traceback" not in r.output and not out.exists()
    fix = json.loads(r.stdout)["error"]["fix"]
    assert "seqdesign design --gimbal cable-wrap" in fix
    assert "seqdesign show" in fix and "--gimbal cable-wrap" in fix
