"""Same inputs and seed -> byte-identical outputs; every output names its inputs."""

from __future__ import annotations

import os

from click.testing import CliRunner

from calib.io.files import sha256_file
from seqdesign.cli import main


def _run_in(directory, args):
    old = os.getcwd()
    os.chdir(directory)
    try:
        r = CliRunner().invoke(main, args)
    finally:
        os.chdir(old)
    assert r.exit_code == 0, r.output
    return r


def test_simulate_and_calibrate_are_byte_identical(tmp_path):
    outs = []
    for name in ("a", "b"):
        d = tmp_path / name
        d.mkdir()
        for ext in ("npz", "csv"):
            _run_in(
                d,
                [
                    "simulate",
                    "paper-9pos",
                    "--table2",
                    "--seed",
                    "11",
                    "--random-setup",
                    "--flip-error-deg",
                    "0.3",
                    "--sample-rate-hz",
                    "20",
                    "-o",
                    f"run.{ext}",
                ],
            )
        _run_in(d, ["calibrate", "run.npz", "-o", "result.toml"])
        outs.append({f: sha256_file(d / f) for f in ("run.npz", "run.csv", "run.truth.toml", "result.toml")})
    assert outs[0] == outs[1]


def test_outputs_record_version_command_and_input_hashes(tmp_path):
    import tomllib

    from calib.runlog import read_run
    from calib.sequence.definition import resolve_sequence_path

    _run_in(tmp_path, ["simulate", "paper-9pos", "--seed", "1", "--sample-rate-hz", "20", "-o", "run.csv"])
    _run_in(tmp_path, ["calibrate", "run.csv", "-o", "res.toml"])
    seq_hash = sha256_file(resolve_sequence_path("paper-9pos"))
    run = read_run(tmp_path / "run.csv")
    assert run.meta["sequence_sha256"] == seq_hash and run.meta["profile"] == "navigation"
    assert run.meta["command"].startswith("seqdesign simulate") and run.meta["tool_version"]
    truth = tomllib.loads((tmp_path / "run.truth.toml").read_text())["provenance"]
    assert truth["sequence_sha256"] == seq_hash and truth["profile"] == "navigation"
    res = tomllib.loads((tmp_path / "res.toml").read_text())["provenance"]
    assert res["run_sha256"] == sha256_file(tmp_path / "run.csv")
    assert res["truth_sha256"] == sha256_file(tmp_path / "run.truth.toml")
    assert res["profile"] == "navigation" and res["command"].startswith("seqdesign calibrate")
