"""The library under the CLI (issue 16): layers run one way, and the CLI adds no policy."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

REPO = Path(__file__).resolve().parents[1]

# calib <- seqdesign, calib <- viz; the CLI (in seqdesign) on top of both.
FORBIDDEN = {"calib": {"seqdesign", "viz"}, "viz": {"seqdesign"}}


def _imports(path: Path) -> set[str]:
    """Top-level packages a module imports, at module level or inside functions."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module.split(".")[0])
    return out


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_layers_run_one_way(package):
    offenders = {
        str(p.relative_to(REPO)): sorted(_imports(p) & FORBIDDEN[package])
        for p in (REPO / package).rglob("*.py")
    }
    assert {k: v for k, v in offenders.items() if v} == {}


@pytest.fixture(scope="module")
def noisy_run(paper_seq):
    """paper-9pos with Table 2 errors and the navigation profile's noise."""
    import math

    from calib.errormodel import ErrorModel
    from calib.profiles import load_profile
    from calib.sim import SimConfig, simulate

    run, _ = simulate(
        paper_seq,
        SimConfig(latitude_rad=math.radians(40.0)),
        ErrorModel.from_table2(),
        load_profile("navigation"),
        noise=True,
        seed=5,
    )
    return run


def test_cli_and_library_give_identical_sigmas(noisy_run, tmp_path):
    """The CLI's sigmas (Birge check included) are the library's, to the last digit."""
    from calib.calibration import calibrate_run
    from calib.runlog import write_run
    from seqdesign.cli import main

    run = noisy_run
    path = tmp_path / "run.npz"
    write_run(run, path)
    res = CliRunner().invoke(main, ["calibrate", str(path), "--json"])
    assert res.exit_code == 0, res.output
    cli = json.loads(res.stdout)
    lib = calibrate_run(run).to_json()
    for name, e in lib["parameters"].items():
        assert cli["parameters"][name]["sigma"] == e["sigma"], name
        assert cli["parameters"][name]["value"] == e["value"], name
    assert cli["fit"]["sigma_scale"] == lib["fit"]["sigma_scale"]


def test_library_result_carries_the_policy(noisy_run):
    """A notebook gets the Birge scale, convergence, correlation and gravity without the CLI."""
    from calib.calibration import calibrate_run
    from calib.profiles import NoiseProfile

    run = noisy_run
    # Half the simulated noise density: chi2/dof ~ 4, so the sigmas must come back inflated
    # by its square root (the Birge ratio) straight from the library.
    half = NoiseProfile("half", 0.0005, 5.0)
    res = calibrate_run(run, half)
    assert res.converged and 3.0 < res.chi2_per_dof < 5.0
    assert res.sigma_scale == pytest.approx(np.sqrt(res.chi2_per_dof))
    assert res.correlation.shape == (21, 21)
    assert res.gravity_source == "normal" and res.ppm_per_mgal == pytest.approx(1e-5 / 9.80 * 1e6, rel=0.01)
    assert any("sigmas inflated" in w for w in res.warnings())


def test_json_refusal_is_one_json_document():
    from seqdesign.cli import main

    for args in (
        ["analyze", "no-such-sequence", "--json"],
        ["analyze", "paper-9pos", "--tolerance-deg", "20", "--json"],
    ):
        res = CliRunner().invoke(main, args)
        assert res.exit_code == 2
        doc = json.loads(res.stdout)
        assert set(doc["error"]) == {"what", "where", "fix"} and doc["error"]["what"]
        assert "Traceback" not in res.output


def test_the_package_is_the_library():
    """``from seqdesign import api as sd`` gives the calls a notebook needs."""
    from seqdesign import api as sd

    analysis = sd.analyze("paper-9pos", tolerance_deg=0.0)
    assert set(analysis.to_json()["estimable"]) == set(analysis.to_json()["parameters"])
    assert callable(sd.calibrate) and callable(sd.design) and callable(sd.record)
    with pytest.raises(AttributeError):
        _ = sd.no_such_thing
