"""`seqdesign verify`: a Monte Carlo of simulate -> calibrate held against the analyser's prediction."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.stats import chi2

from calib.model import params as P
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from calib.sequence.kinematics import SimConfig
from seqdesign.cli import main
from seqdesign.verify import VerifyOptions, chi2_band, error_half_range, grade_of, verify

# 50 Hz keeps each run under a second; white noise, so the sigmas do not depend on the rate
# beyond the sample count (the prediction is the same continuous-time information).
FAST = ["--sample-rate-hz", "50"]


def test_grades_follow_the_gyro_noise():
    assert grade_of(load_profile("navigation")) == "navigation"
    assert grade_of(load_profile("tactical")) == "tactical"
    assert grade_of(load_profile("mems")) == "mems"
    # a MEMS unit's errors are orders larger than a navigation unit's, parameter by parameter
    assert np.all(error_half_range("mems") > error_half_range("navigation"))


def test_chi2_band_is_the_chi_square_of_all_runs_degrees_of_freedom():
    lo, hi = chi2_band(50)
    # mean of 50 chi2(21): 1050 dof in all; the band is its 0.5 % and 99.5 % quantiles over 50
    assert lo == pytest.approx(chi2.ppf(0.005, 1050) / 50) and hi == pytest.approx(chi2.ppf(0.995, 1050) / 50)
    assert lo < P.N_PARAMS < hi


@pytest.mark.slow
def test_verify_is_honest_on_the_paper_sequence():
    """12 runs of paper-9pos, navigation grade: the NEES mean falls in its 99 % band, and every
    parameter's RMS z-score in the 99.9 % band of chi2(12)/12 (the runs are independent, each
    z-score N(0, 1) if the reported sigma is right)."""
    out = CliRunner().invoke(main, ["verify", "paper-9pos", "--runs", "12", "--seed", "3", "--json", *FAST])
    assert out.exit_code == 0, out.output
    doc = json.loads(out.stdout)
    assert doc["converged"] == 12 and not doc["refused"]
    assert doc["nees"]["in_band"], doc["nees"]
    lo, hi = (math.sqrt(q / 12) for q in chi2.ppf([0.0005, 0.9995], 12))
    for name, e in doc["parameters"].items():
        assert lo < e["rms_over_reported_sigma"] < hi, name
        # the prediction is the worst case over the mounting box: the runs' errors, at random
        # mountings, are not larger than it beyond the same statistical band
        assert e["rms_over_predicted_sigma"] < hi, name


def test_workers_and_a_dask_cluster_give_the_serial_answer():
    distributed = pytest.importorskip("distributed")
    seq, prof = load_sequence("paper-9pos"), load_profile("navigation")
    kw = dict(
        config=SimConfig(latitude_rad=math.radians(40.0), sample_rate_hz=20.0),
        predicted_sigma=np.ones(P.N_PARAMS),
    )
    serial = verify(seq, prof, VerifyOptions(runs=2, seed=11), **kw).to_json()
    assert verify(seq, prof, VerifyOptions(runs=2, seed=11, workers=2), **kw).to_json() == serial
    with (
        distributed.LocalCluster(
            # ":0": a free port; two clusters in two test workers both asked for dask's 8787, and
            # the loser's fallback left its first socket open (a ResourceWarning, an error here)
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        assert verify(seq, prof, VerifyOptions(runs=2, seed=11, scheduler=client), **kw).to_json() == serial


def test_verify_writes_a_plot_and_refuses_bad_options(tmp_path):
    png = tmp_path / "v.png"
    out = CliRunner().invoke(main, ["verify", "paper-9pos", "--runs", "2", "--plot", str(png), *FAST])
    assert out.exit_code == 0, out.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for args in (["--errors", str(tmp_path / "e.toml"), "--table2"], ["--plot", str(tmp_path / "v.jpg")]):
        bad = CliRunner().invoke(main, ["verify", "paper-9pos", "--runs", "2", *args])
        assert bad.exit_code == 2 and "Traceback" not in bad.output, bad.output
    assert not (tmp_path / "v.jpg").exists()
