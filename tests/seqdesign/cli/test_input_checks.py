"""What a newcomer types (issue 17): near misses, unknown keys, delimiters, files of the wrong kind.

Every refusal is checked through the CLI with and without ``--json``: one line on stderr
naming what, where and how to fix, exit code 2, nothing written, and with ``--json`` one JSON
document ``{"error": {"what", "where", "fix"}}`` on stdout.
"""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from seqdesign.cli import main

SEQ = """name = "s"
start = ["east", "up", "south"]
initial_dwell_s = 60
[[step]]
axis = "Z"
angle_deg = 90
{rate_key} = 10
dwell_s = 60
"""
PROFILE = 'name = "p"\n{key} = 0.001\naccel_vrw_ug = 10.0\n'
GIMBAL = 'name = "g"\n[outer]\n{key} = 20\n[middle]\n[inner]\n'
REQUIREMENTS = "[requirements]\n{key} = 2.0\n"


def refused(tmp_path, args, *parts):
    before = sorted(p.name for p in tmp_path.iterdir())
    for extra in ([], ["--json"]):
        res = CliRunner().invoke(main, args + extra)
        assert res.exit_code == 2, res.output
        lines = [ln for ln in res.stderr.splitlines() if ln.startswith("error: ")]
        assert len(lines) == 1 and "Traceback" not in res.output, res.output
        for part in parts:
            assert part in lines[0], (part, lines[0])
        if extra:
            doc = json.loads(res.stdout)["error"]
            assert doc["what"] and doc["what"] in lines[0]
        else:
            assert res.stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    return lines[0]


@pytest.mark.parametrize(
    "kind, text, args, typo, right",
    [
        ("sequence", SEQ.format(rate_key="rate_dsp"), ["show", "{f}"], "rate_dsp", "rate_dps"),
        (
            "profile",
            PROFILE.format(key="gyro_arw_dhp"),
            ["analyze", "paper-9pos", "--profile", "{f}"],
            "gyro_arw_dhp",
            "gyro_arw_dph",
        ),
        (
            "gimbal",
            GIMBAL.format(key="max_rate_dsp"),
            ["show", "paper-9pos", "--gimbal", "{f}"],
            "max_rate_dsp",
            "max_rate_dps",
        ),
        (
            "requirements",
            REQUIREMENTS.format(key="sgxx"),
            ["analyze", "paper-9pos", "--requirements", "{f}"],
            "sgxx",
            "sgx",
        ),
    ],
)
def test_a_near_miss_key_is_refused_naming_the_closest(tmp_path, kind, text, args, typo, right):
    path = tmp_path / f"{kind}.toml"
    path.write_text(text)
    line = refused(tmp_path, [a.format(f=path) for a in args], typo, f"did you mean '{right}'")
    # The file is named (by its whole path, or by its name where the path would take the line
    # past the 400 characters a refusal is printed in).
    assert str(path) in line or (f"{path.name}:" in line and len(line) <= 400 + len("error: "))


def test_any_other_unknown_key_is_a_warning_not_a_refusal(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SEQ.format(rate_key="rate_dps").replace('name = "s"', 'name = "s"\noperator = "me"'))
    res = CliRunner().invoke(main, ["show", str(path)])
    assert res.exit_code == 0
    assert "warning:" in res.stderr and "'operator' is not a sequence key" in res.stderr


def test_a_sequence_with_a_stray_result_table_is_still_a_sequence(tmp_path):
    """A hand-typed sequence that borrows ``[initial_attitude]`` from a result is a sequence with
    an unknown key (its ``start`` and ``[[step]]`` say so), not "a calibration result"."""
    path = tmp_path / "s.toml"
    path.write_text(
        SEQ.format(rate_key="rate_dps") + "[initial_attitude]\nC_b_n = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\n"
    )
    res = CliRunner().invoke(main, ["show", str(path)])
    assert res.exit_code == 0, res.output
    assert "calibration result" not in res.output
    assert "'initial_attitude' is not a sequence key" in res.stderr


def test_a_result_missing_its_parameters_is_still_named_a_result(files, tmp_path):
    """The other way round: a result whose ``[parameters]`` table was cut is still a result."""
    kept, inside = [], False
    for line in (files / "r.result.toml").read_text().splitlines():
        if line.startswith("["):
            inside = line.startswith("[parameters")
        if not inside:
            kept.append(line)
    assert "[initial_attitude]" in kept and not any("parameters" in ln for ln in kept)
    path = tmp_path / "cut.result.toml"
    path.write_text("\n".join(kept) + "\n")
    refused(tmp_path, ["show", str(path)], "this is a calibration result")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("kinds")
    run = folder / "run.npz"
    res = CliRunner().invoke(
        main, ["simulate", "paper-9pos", "--noise-free", "--sample-rate-hz", "10", "-o", str(run)]
    )
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(main, ["calibrate", str(run), "-o", str(folder / "r.result.toml")])
    assert res.exit_code == 0, res.output
    return folder


@pytest.mark.parametrize(
    "args, named",
    [
        (["show", "{d}/r.result.toml"], "this is a calibration result"),
        (["analyze", "{d}/run.npz"], "this is a run log, not a sequence file"),
        (["calibrate", "{d}/run.truth.toml"], "this is a truth file"),
        (["analyze", "paper-9pos", "--profile", "{d}/run.truth.toml"], "not a noise profile"),
    ],
)
def test_a_file_of_the_wrong_kind_is_named_as_what_it_is(files, tmp_path, args, named):
    refused(tmp_path, [a.format(d=files) for a in args], named)


@pytest.mark.parametrize("sep, decimal", [(";", "."), ("\t", "."), (";", ",")])
def test_csv_with_another_delimiter_is_read(files, tmp_path, sep, decimal):
    from calib.runlog import read_run, write_run

    base = read_run(files / "run.npz")
    write_run(base, tmp_path / "comma.csv")
    lines = (tmp_path / "comma.csv").read_text().splitlines()
    text = [ln if ln.startswith("#") else ln.replace(",", sep).replace(".", decimal) for ln in lines]
    (tmp_path / "other.csv").write_text("\n".join(text) + "\n")
    res = CliRunner().invoke(
        main, ["calibrate", str(tmp_path / "other.csv"), "--json", "-o", str(tmp_path / "o.toml")]
    )
    assert res.exit_code == 0, res.output
    assert "read as such" in res.stderr
    with pytest.warns(UserWarning, match="read as such"):  # the notice, through the library too
        other = read_run(tmp_path / "other.csv")
    assert (other.dtheta_rad == base.dtheta_rad).all() and (other.dv_mps == base.dv_mps).all()


def test_a_logger_csv_without_metadata_lists_every_missing_key(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text(
        "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_g,accel_y_g,accel_z_g\n"
        "0.01,0,0,0,0,0,1\n0.02,0,0,0,0,0,1\n"
    )
    line = refused(tmp_path, ["calibrate", str(path)], "latitude_deg", "height_m")
    assert "--latitude" in line
