"""The fuzz tests' module-scoped fixtures: the tally's report, a work folder, the valid base documents.

What a tests/fuzz/conftest.py would hold. Each test module imports them instead
(``from fuzz_fixtures import bases_fixture, report_tally, work_fixture``): a second
conftest.py outside a package would take the module name ``conftest`` from tests/conftest.py,
whose helpers fifteen test files import by that name (some at run time).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from fuzzing import REPO, TALLY

from calib.calibration.result import CalibrationResult
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.nav.transform import attitude_from_directions, rotvec_to_dcm
from calib.noise.profiles import load_profile
from calib.runlog import Run, write_run
from calib.sequence.definition import load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate
from calib.sim.truth import write_truth


@pytest.fixture(scope="module", autouse=True)
def report_tally(request):
    TALLY.clear()  # each module reports the cases it tried
    yield
    reporter = request.config.pluginmanager.get_plugin("terminalreporter")
    capture = request.config.pluginmanager.get_plugin("capturemanager")
    if reporter is None or capture is None:
        return
    with capture.global_and_fixture_disabled():
        _write_tally(reporter)


def _write_tally(reporter) -> None:
    reporter.write_line("")
    reporter.write_line(
        "fuzz cases per reader: valid result / refused with CalibError (CLI: exit 0 / exit 2)"
    )
    for kind, tally in sorted(TALLY.items()):
        if kind.startswith("CLI "):
            ok, refused = tally["CLI exit 0"], tally["CLI exit 2"]
        else:
            ok, refused = tally["valid result"], tally["refused"]
        reporter.write_line(f"  {kind:<14} {ok + refused:6d} cases: {ok:5d} / {refused:5d}")


# ---------------------------------------------------------------------------
# Valid documents to start from


SHORT_SEQUENCE = """\
name = "fuzz-short"
description = "two flips, short dwells"
start = ["east", "up", "south"]
initial_dwell_s = 12.0
latitude_deg = 40.0
height_m = 0.0

[[step]]
axis = "Z"
angle_deg = 90.0
rate_dps = 10.0
dwell_s = 5.0

[[step]]
axis = "Y"
angle_deg = -90.0
dwell_s = 5.0
"""


@pytest.fixture(scope="module", name="work")
def work_fixture(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture(scope="module", name="bases")
def bases_fixture(work) -> dict[str, bytes]:
    """The bytes of one valid file per reader, written by the tool's own writers."""
    out = {
        "sequence": (REPO / "sequences" / "paper-9pos.toml").read_bytes(),
        "profile": (REPO / "calib" / "data" / "profiles" / "navigation.toml").read_bytes(),
    }
    (work / "short.toml").write_text(SHORT_SEQUENCE, encoding="utf-8")
    seq = load_sequence(work / "short.toml")
    run, truth = simulate(
        seq,
        SimConfig(latitude_rad=math.radians(40.0), sample_rate_hz=10.0),
        ErrorModel.from_table2(),
        load_profile("navigation"),
        options=SimOptions(setup_rotvec=np.radians([1.0, -2.0, 3.0]), flip_error_deg=0.2, noise=True, seed=3),
    )
    write_truth(work / "base.truth.toml", truth, {"tool_version": "fuzz"})
    out["truth"] = (work / "base.truth.toml").read_bytes()
    # A small run keeps CSV/NPZ parsing cheap; the simulated one has gimbal angles.
    small = Run(
        time_s=run.time_s[:40].copy(),
        dtheta_rad=run.dtheta_rad[:40].copy(),
        dv_mps=run.dv_mps[:40].copy(),
        meta=run.meta,
        gimbal_deg=run.gimbal_deg[:40].copy(),
    )
    write_run(small, work / "base.csv")
    write_run(small, work / "base.npz")
    out["csv"] = (work / "base.csv").read_bytes()
    out["npz"] = (work / "base.npz").read_bytes()
    rng = np.random.default_rng(5)
    A = rng.normal(size=(21, 40))
    cov = A @ A.T
    d = np.sqrt(np.diag(cov))
    result = CalibrationResult(
        values=P.to_si(rng.normal(size=21)),
        sigma=P.to_si(np.abs(rng.normal(size=21)) + 0.01),
        C_b_n0=attitude_from_directions("east", "up", "south") @ rotvec_to_dcm([0.01, -0.02, 0.03]),
        converged=True,
        iterations=4,
        residual_rms_mps=9e-4,
        profile="navigation",
        chi2_per_dof=1.03,
        correlation=cov / np.outer(d, d),
        provenance={"tool_version": "fuzz", "command": "seqdesign calibrate run.npz", "run_sha256": "0" * 64},
    )
    result.save(work / "base.result.toml")
    out["result"] = (work / "base.result.toml").read_bytes()
    return out
