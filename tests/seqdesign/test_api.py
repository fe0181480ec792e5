"""The notebook API says what the CLI says: each call against the command's ``--json`` on the same input."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from click.testing import CliRunner

from calib.errors import CalibError
from calib.model.error_model import ErrorModel
from calib.noise.profiles import NoiseProfile, load_profile
from calib.runlog import Run, write_run
from calib.sequence.definition import Sequence, Step, load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate
from seqdesign import api as sd
from seqdesign.cli import main

GIMBALLED = "designed-30min-cable-wrap"  # a shipped design with lock counter-rotations on cable-wrap


def cli_json(*args: str) -> dict:
    res = CliRunner().invoke(main, [*args, "--json"])
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def as_json(doc: dict) -> dict:
    """A library document as the CLI prints it (tuples become lists, non-finite numbers null)."""
    from seqdesign.cli.tools import _json_safe

    return json.loads(json.dumps(_json_safe(doc)))


def without(doc: dict, *keys: str) -> dict:
    return {k: v for k, v in doc.items() if k not in keys}


@pytest.mark.parametrize("gimbal", [None, "cable-wrap"])
@pytest.mark.parametrize("sequence", ["paper-9pos", GIMBALLED])
def test_show_is_the_cli_show(sequence, gimbal):
    args = ["show", sequence] + (["--gimbal", gimbal] if gimbal else [])
    shown = sd.show(sequence, gimbal=gimbal)
    assert as_json(shown.to_json()) == cli_json(*args)
    res = CliRunner().invoke(main, args)
    assert res.stdout == shown.to_text() + "\n"


def test_show_takes_a_sequence_in_memory():
    seq = load_sequence("paper-9pos")
    shown = sd.show(seq)
    assert shown.to_json() == sd.show("paper-9pos").to_json()
    # Each rest lies where the sequence's time line puts it, one more rest than flips.
    assert len(shown.positions) == len(seq.steps) + 1
    assert shown.positions[0].start_s == 0.0 and shown.positions[-1].end_s == pytest.approx(seq.duration_s)


def test_export_is_the_cli_export(tmp_path):
    cli_file, api_file = tmp_path / "cli.csv", tmp_path / "api.csv"
    doc = cli_json("export", GIMBALLED, "--gimbal", "cable-wrap", "--rate-hz", "5", "-o", str(cli_file))
    schedule = sd.export(GIMBALLED, gimbal="cable-wrap", rate_hz=5)
    schedule.save(api_file)
    assert as_json(schedule.to_json(cli_file)) == doc
    header_cli, rows_cli = sd.read_schedule(cli_file)
    header_api, rows_api = sd.read_schedule(api_file)
    np.testing.assert_array_equal(rows_api, rows_cli)
    # The same file but for who wrote it: the call instead of the command line.
    differ = {k for k in header_cli if header_cli[k] != header_api.get(k)}
    assert differ == {"command"} and header_api["command"].startswith("Schedule.save(")
    assert header_api["sequence_sha256"] and header_api["gimbal_sha256"]


def test_export_arrays_hold_still_at_every_rest():
    """At rest the gimbals stand at show's encoder angles and turn at 0 deg/s."""
    schedule = sd.export(GIMBALLED, gimbal="cable-wrap", rate_hz=10)
    shown = sd.show(GIMBALLED, gimbal="cable-wrap")
    t = schedule.times_s
    angles, rates = schedule.encoders()
    assert angles.shape == rates.shape == (len(t), 3)
    assert np.all(np.diff(t) > 0) and t[-1] == pytest.approx(schedule.sequence.duration_s)
    for p in shown.positions:
        # the first second of each rest: after the flip, before any lock counter-rotation
        at = (t > p.start_s + 0.05) & (t < min(p.start_s + 1.0, p.end_s - 0.05))
        assert at.any()
        np.testing.assert_allclose(angles[at], np.broadcast_to(p.gimbal_deg, angles[at].shape), atol=1e-9)
        np.testing.assert_allclose(rates[at], 0.0, atol=1e-9)


TRUE = NoiseProfile("truth", gyro_arw_dph=0.1, accel_vrw_ug=50.0)


@pytest.fixture(scope="module")
def static_csv(tmp_path_factory):
    """A static log as a logger writes it: no format line, no height (20 min at 50 Hz, white noise)."""
    seq = Sequence("static", ("east", "south", "down"), (Step("Z", 90.0, 10.0, 1.0),), initial_dwell_s=1200.0)
    run, _ = simulate(
        seq,
        SimConfig(latitude_rad=math.radians(51.08), sample_rate_hz=50.0),
        ErrorModel.zero(),
        TRUE,
        options=SimOptions(seed=4),
    )
    keep = run.time_s <= 1200.0
    meta = {k: v for k, v in run.meta.items() if k != "sequence"}
    path = tmp_path_factory.mktemp("static") / "static.csv"
    write_run(Run(run.time_s[keep], run.dtheta_rad[keep], run.dv_mps[keep], meta), path)
    lines = path.read_text().splitlines()
    path.write_text("\n".join(x for x in lines if not x.startswith(("# format", "# height_m"))) + "\n")
    return path


def test_profile_fit_is_the_cli_profile_fit(static_csv, tmp_path):
    out = tmp_path / "unit.toml"
    doc = cli_json("profile", "fit", str(static_csv), "-o", str(out), "--no-plot")
    with pytest.warns(UserWarning, match="no height"):
        fitted = sd.profile_fit(static_csv, name="unit")
    assert as_json(fitted.to_json()) == without(doc, "output", "plot", "seconds")
    assert fitted.height_assumed and fitted.to_json()["site"]["height_m"] == 0.0
    # The white noise the log was simulated with comes back (a 20-min log: within 10 %).
    assert fitted.profile.gyro_arw_dph == pytest.approx(TRUE.gyro_arw_dph, rel=0.1)
    assert fitted.profile.accel_vrw_ug == pytest.approx(TRUE.accel_vrw_ug, rel=0.1)
    # What it saves is what the CLI wrote, but for the provenance; and it loads as a profile.
    written = fitted.save(tmp_path / "api.toml", plot=tmp_path / "api.png")
    assert written == [str(tmp_path / "api.toml"), str(tmp_path / "api.png")]
    assert (tmp_path / "api.png").read_bytes()[:4] == b"\x89PNG"
    assert load_profile(str(tmp_path / "api.toml")) == fitted.profile == load_profile(str(out))
    res = CliRunner().invoke(main, ["profile", "fit", str(static_csv), "-o", str(out), "--no-plot"])
    assert res.stdout == fitted.to_text() + "\n"


def test_profile_fit_with_the_height_given_warns_nothing(static_csv):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fitted = sd.profile_fit(static_csv, height_m=1100.0)
    assert not fitted.height_assumed and fitted.fit.height_m == 1100.0
    assert fitted.fit.name == "static"


NARROW = sd.DesignOptions(beam_width=8)  # with at most 3 quarter turns: a few seconds


@pytest.fixture(scope="module")
def keyword_design():
    return sd.design([2], {"max_quarters": 3}, options=NARROW, gimbal="cable-wrap")


def _designs(report) -> list[dict]:
    return [without(d, "search_seconds") for d in as_json(report.to_json())["designs"]]


@pytest.mark.slow  # three designs of tens of seconds: run with the slow tests (CI runs both)
def test_design_is_the_cli_design(keyword_design, tmp_path):
    doc = cli_json(
        "design",
        "--budget-min",
        "2",
        "--beam-width",
        "8",
        "--max-quarters",
        "3",
        "--gimbal",
        "cable-wrap",
        "-o",
        str(tmp_path / "d.toml"),
    )
    got = as_json(keyword_design.to_json())
    assert without(got, "designs") == without(doc, "designs")
    assert _designs(keyword_design) == [without(d, "search_seconds") for d in doc["designs"]]
    # Without a rate, the gimbal's own (cable-wrap: 20 deg/s) as the CLI; and every move plays on it.
    seq = keyword_design.rows[0].result.sequence
    assert {s.rate_dps for s in seq.steps} == {20.0}
    assert sd.show(seq, gimbal="cable-wrap").playable


@pytest.mark.slow  # three designs of tens of seconds: run with the slow tests (CI runs both)
def test_design_keywords_equal_the_dict_and_the_typed_constraints(keyword_design):
    from calib.gimbal.description import load_gimbal

    as_dict = sd.design([2], {"max_quarters": 3, "rate_dps": None, "gimbal": "cable-wrap"}, options=NARROW)
    typed = sd.design(
        [2], sd.Constraints(max_quarters=3, rate_dps=20.0, gimbal=load_gimbal("cable-wrap")), options=NARROW
    )
    assert _designs(as_dict) == _designs(keyword_design) == _designs(typed)


def test_design_reads_the_dict_as_the_cli_reads_its_options():
    report = sd.design([2], {"max_quarters": 3, "axes": "zy", "min_dwell_s": 12.0}, options=NARROW)
    steps = report.rows[0].result.sequence.steps
    assert {s.axis for s in steps} <= {"Y", "Z"}
    assert all(abs(s.angle_deg) <= 270.0 for s in steps)
    assert all(s.dwell_s >= 12.0 - 1e-9 for s in steps)


@pytest.mark.parametrize(
    ("call", "where"),
    [
        (lambda: sd.show("paper-9pos", gimbal="no-such-gimbal"), "gimbal"),
        (lambda: sd.export("paper-9pos", rate_hz=0.5), "rate_hz"),
        (lambda: sd.export("paper-9pos").save("commands.txt"), "commands.txt"),
        (lambda: sd.design([2], {"start": "east,up,up"}), "start"),
        (lambda: sd.design([2], gimbal="no-such-gimbal"), "gimbal"),
    ],
)
def test_the_api_refuses_in_its_own_words(call, where):
    """A notebook's refusals name the argument, not a CLI option."""
    with pytest.raises(CalibError) as info:
        call()
    assert info.value.where == where
    assert "--" not in info.value.message


def test_the_api_has_a_call_per_command():
    for name in ("analyze", "calibrate", "design", "export", "profile_fit", "record", "show", "simulate"):
        assert callable(getattr(sd, name)) and getattr(sd, name).__doc__, name
