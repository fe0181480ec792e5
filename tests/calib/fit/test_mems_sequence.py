"""A MEMS run of a known sequence: `--sequence` judges the log's turns with the profile's noise.

The reported failure: `calibrate --sequence paper-9pos --profile mems` of a run simulated from
paper-9pos was refused ("the sequence has 8 flips where the log turns 750 times"): the log's
turns were found sample by sample, without the profile's noise, and a MEMS gyro's noise crosses
the threshold hundreds of times. Judged as the fit judges motion (windowed, with the profile's
ARW), and without the noise bursts that turn by under 5 deg within a rest, the log turns 8 times.
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import REPO

from calib.nav.strapdown import sample_intervals
from calib.noise.profiles import load_profile
from calib.runlog import read_run
from calib.sequence.motion import MIN_TURN_DEG, log_turns, runs_of
from seqdesign.cli import main


@pytest.fixture(scope="module")
def mems_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("mems") / "m.npz"
    res = CliRunner().invoke(
        main,
        [
            "simulate",
            "paper-9pos",
            "--profile",
            "mems",
            "--table2",
            "--seed",
            "4",
            "--sample-rate-hz",
            "100",
            "-o",
            str(path),
        ],
    )
    assert res.exit_code == 0, res.output
    return path


def test_the_log_turns_where_the_sequence_flips(mems_run):
    run = read_run(mems_run)
    dt = sample_intervals(run.time_s)
    starts, ends = runs_of(log_turns(run.dtheta_rad, dt, load_profile("mems").arw, run.source))
    # paper-9pos: 8 flips of 90 deg at 10 deg/s, each starting 180 s + 9 s after the last
    assert len(starts) == 8
    flip_starts = 180.0 + 189.0 * np.arange(8)
    assert np.abs(run.time_s[starts] - flip_starts).max() < 2.0  # the check's own tolerance
    assert MIN_TURN_DEG < 90.0 / 2  # a real flip is never taken for a noise burst


@pytest.mark.parametrize("reading", [[], ["--stream"]])
def test_calibrate_and_view_accept_the_sequence_of_a_mems_run(mems_run, tmp_path, reading):
    runner = CliRunner()
    res = runner.invoke(
        main,
        [
            "calibrate",
            str(mems_run),
            *reading,
            "--profile",
            "mems",
            "--requirements",
            "mems",
            "--sequence",
            "paper-9pos",
            "-o",
            str(tmp_path / "r.toml"),
        ],
    )
    assert res.exit_code == 0 and "converged" in res.output, res.output
    res = runner.invoke(
        main, ["view", str(mems_run), "--sequence", "paper-9pos", "-o", str(tmp_path / "m.rrd")]
    )
    assert res.exit_code == 0, res.output
    assert (tmp_path / "m.rrd").stat().st_size > 0


@pytest.mark.slow
def test_sequence_accepts_a_run_under_a_strong_gauss_markov_gyro(tmp_path):
    # The ADIS16405 profile that `profile fit` measured (gyro bias instability 60 deg/h, 214 s)
    # and the 8-min sequence designed for it (benchmarks/): the log's turns judged with the
    # profile's noise are the sequence's 9 moves, so `--sequence` accepts the run, and the fit
    # (within the wander the estimator follows) converges.

    from calib.sequence.definition import load_sequence

    bench = REPO / "benchmarks"
    seq, prof = bench / "sequences" / "adis16405-8min.toml", bench / "profiles" / "adis16405.toml"
    run = tmp_path / "adis.npz"
    runner = CliRunner()
    args = ["simulate", str(seq), "--profile", str(prof), "--table2", "--seed", "3"]
    res = runner.invoke(main, [*args, "--sample-rate-hz", "100", "-o", str(run)])
    assert res.exit_code == 0, res.output
    moves = len(load_sequence(seq).steps)
    r = read_run(run)
    starts, _ = runs_of(
        log_turns(r.dtheta_rad, sample_intervals(r.time_s), load_profile(str(prof)).arw, r.source)
    )
    assert len(starts) == moves
    res = runner.invoke(
        main,
        ["calibrate", str(run), "--profile", str(prof), "--requirements", "mems", "--sequence", str(seq)]
        + ["-o", str(tmp_path / "r.toml")],
    )
    assert res.exit_code == 0 and "converged" in res.output, res.output
