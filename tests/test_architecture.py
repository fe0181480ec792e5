"""The library under the CLI: the import map holds, and the CLI adds no policy.

calib is the core (it imports no other package of ours), viz draws what calib
computes, seqdesign holds the search, the report objects and, on top, the CLI.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
from click.testing import CliRunner

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("calib", "seqdesign", "viz", "sequences")
LIBRARY = ("calib", "seqdesign", "viz")
# What each package may import of ours (its own modules always).
ALLOWED = {"calib": set(), "viz": {"calib"}, "seqdesign": {"calib", "viz", "sequences"}, "sequences": set()}
MAX_LINES = 500
# The CLI imports its commands' machinery when a command runs, so that `seqdesign --help` and
# a one-line refusal do not pay for casadi, scipy and rerun; nothing else may hide imports.
LAZY_ALLOWED = ("seqdesign/cli",)
# The compiled kernels start numba (~1 s): imported where the Gauss-Markov paths call them, so
# that the white-noise ones never pay for it.
LAZY_TARGETS = {"calib.noise.kernels"}


def _modules() -> dict[str, Path]:
    out = {}
    for package in PACKAGES:
        for path in (REPO / package).rglob("*.py"):
            parts = path.relative_to(REPO).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = path
    return out


MODULES = _modules()


def _resolve(name: str) -> str | None:
    """The module of ours that an import name lands in (a package's __init__ or a module)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(module: str, path: Path, lazy: bool | None = None) -> set[str]:
    """Modules of ours that ``module`` imports (lazy=True: only inside functions; None: all)."""
    tree = ast.parse(path.read_text())
    inside = {
        id(n)
        for f in ast.walk(tree)
        if isinstance(f, ast.FunctionDef | ast.AsyncFunctionDef)
        for n in ast.walk(f)
        if isinstance(n, ast.Import | ast.ImportFrom)
    }
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if not isinstance(node, ast.Import | ast.ImportFrom):
            continue
        if lazy is not None and (id(node) in inside) != lazy:
            continue
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            # `from pkg import sub` imports the submodule where there is one
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names]
        out |= {r for r in map(_resolve, names) if r and r != module}
    return out


def _graph() -> nx.DiGraph:
    g = nx.DiGraph()
    for module, path in MODULES.items():
        g.add_node(module)
        g.add_edges_from((module, target) for target in _imports(module, path))
    return g


def test_layers_run_one_way():
    bad = sorted(
        (a, b)
        for a, b in _graph().edges
        if b.split(".")[0] != a.split(".")[0] and b.split(".")[0] not in ALLOWED[a.split(".")[0]]
    )
    assert bad == []


# calib's folders, bottom up: a module imports only from its own folder or the folders before it
# in this list (calib/__init__.py draws the same map; docs/architecture.md names each in its table).
CALIB_LAYERS = (
    "errors", "io", "model", "noise", "nav", "sequence", "gimbal", "runlog", "allan",
    "analysis", "fit", "sim", "hand", "calibration", "peers",
)  # fmt: skip


def _folder(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if parts[0] == "calib" and len(parts) > 1 else None


def test_calib_folders_are_layered_one_way():
    """No arrow runs back up between calib's folders; the simulator is below none of analysis and fit."""
    up = sorted(
        (a, b)
        for a, b in _graph().edges
        if (fa := _folder(a)) and (fb := _folder(b)) and CALIB_LAYERS.index(fa) < CALIB_LAYERS.index(fb)
    )
    assert up == []


def test_calib_is_its_folders():
    """Every module of calib lives in a folder of the map (``errors`` the one module beside them)."""
    top = {p.stem for p in (REPO / "calib").glob("*.py")} - {"__init__"}
    folders = {p.name for p in (REPO / "calib").iterdir() if (p / "__init__.py").exists()}
    assert top == {"errors"}
    assert folders | top == set(CALIB_LAYERS)


def test_each_folder_has_a_public_face():
    """Each folder's ``__init__`` says what it is and names what it offers; every name it offers exists."""
    import importlib

    for folder in CALIB_LAYERS:
        if folder == "errors":
            continue
        package = importlib.import_module(f"calib.{folder}")
        assert package.__doc__ and len(package.__doc__.split()) > 10, folder
        assert package.__all__, folder
        missing = [name for name in package.__all__ if not hasattr(package, name)]
        assert missing == [], folder


def test_no_two_modules_of_one_name():
    """No module of calib shares its name with another, or with a folder of calib.

    (The CLI names its modules after its commands, viz after what a recording shows: a module there
    may share a name with the calib concept it serves.)
    """
    names: dict[str, list[str]] = {}
    for module in MODULES:
        if module.startswith("calib.") and MODULES[module].name != "__init__.py":
            names.setdefault(module.rsplit(".", 1)[1], []).append(module)
    twice = {n: m for n, m in names.items() if len(m) > 1 or (n in CALIB_LAYERS and n != "errors")}
    assert twice == {}


def test_the_architecture_page_names_every_folder():
    """docs/architecture.md's table of folders names each of calib's folders, and nothing else."""
    page = (REPO / "docs" / "architecture.md").read_text()
    table = page[page.index("## The folders") :].split("\n## ")[0]
    rows = [line.split("|")[1:4] for line in table.splitlines() if line.startswith("| `calib")]
    named = [
        folder.strip().strip("`").removeprefix("calib/").rstrip("/").removesuffix(".py")
        for folder, _, _ in rows
    ]
    assert named == list(CALIB_LAYERS)  # in the layers' order
    for folder, (_, _, modules) in zip(named, rows, strict=True):
        if folder != "errors":
            on_disk = {p.stem for p in (REPO / "calib" / folder).glob("*.py")} - {"__init__"}
            assert set(modules.split()) == on_disk, folder


def folder_arrows() -> str:
    """calib's folders top down, each with the folders its modules import (also top down)."""
    imports: dict[str, set[str]] = {folder: set() for folder in CALIB_LAYERS}
    for a, b in _graph().edges:
        if (fa := _folder(a)) and (fb := _folder(b)) and fa != fb:
            imports[fa].add(fb)
    down = CALIB_LAYERS[::-1]
    width = max(map(len, down))
    return "\n".join(
        f"{folder:<{width}} -> {' '.join(f for f in down if f in imports[folder])}".rstrip()
        for folder in down
    )


def test_the_architecture_page_draws_the_folders_as_they_import():
    """The drawing of who imports whom on docs/architecture.md is the import graph's, not a memory of it."""
    page = (REPO / "docs" / "architecture.md").read_text()
    drawn = page.split("<!-- folder-arrows -->\n```\n", 1)[1].split("\n```", 1)[0]
    assert drawn == folder_arrows(), "redraw docs/architecture.md's block with:\n" + folder_arrows()


def test_no_import_cycles():
    # A package's __init__ re-exporting its modules is not a cycle unless a module imports the
    # package back (then the order of imports decides whether a name exists yet).
    cycles = list(nx.simple_cycles(_graph()))
    assert cycles == []


@pytest.mark.parametrize("package", LIBRARY)
def test_no_module_over_500_lines(package):
    long = {
        str(p.relative_to(REPO)): n
        for p in (REPO / package).rglob("*.py")
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    }
    assert long == {}


MAX_PARAMETERS = 8
OVER_8 = "# over 8 parameters:"


def _parameter_count(f: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Parameters as a caller sees them: positional-only, ordinary, keyword-only, *args, **kwargs."""
    a = f.args
    names = [x.arg for x in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    bound = 1 if names and names[0] in ("self", "cls") else 0
    return len(names) - bound + (a.vararg is not None) + (a.kwarg is not None)


def _over_8_without_a_reason() -> set[str]:
    """Functions over 8 parameters whose reason is not written beside them."""
    missing = set()
    for package in LIBRARY:
        for path in sorted((REPO / package).rglob("*.py")):
            lines = path.read_text().splitlines()
            for f in ast.walk(ast.parse("\n".join(lines))):
                if not isinstance(f, ast.FunctionDef | ast.AsyncFunctionDef):
                    continue
                if _parameter_count(f) <= MAX_PARAMETERS:
                    continue
                name = f"{path.relative_to(REPO)}:{f.name}"
                first = min([d.lineno for d in f.decorator_list] + [f.lineno])
                # The 3 lines above the first decorator (or the def), and those among the decorators.
                near = lines[max(first - 4, 0) : f.lineno - 1]
                if not any(line.strip().startswith(OVER_8) for line in near):
                    missing.add(name)
    return missing


def test_no_function_over_8_parameters_without_a_reason():
    # Over 8 parameters, a call is a relayed list that an options object or a value (a Site, a
    # config) should carry; where plain parameters are right (a numba kernel, a click command,
    # a registry row), a comment `# over 8 parameters: <why>` above the def says so.
    assert _over_8_without_a_reason() == set()


def test_no_hidden_first_party_imports():
    hidden = {
        m: sorted(targets)
        for m, p in MODULES.items()
        if not str(p.relative_to(REPO)).startswith(LAZY_ALLOWED)
        and (targets := _imports(m, p, lazy=True) - LAZY_TARGETS)
    }
    assert hidden == {}


def test_importing_the_library_leaves_the_process_alone():
    """``import calib, seqdesign, viz`` sets no environment variable (BLAS threads are the CLI's choice)."""
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
    }
    code = (
        "import os; before = dict(os.environ); import calib, seqdesign, viz, seqdesign.api; "
        "print(sorted(set(os.environ.items()) ^ set(before.items())))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=REPO, check=True
    )
    assert out.stdout.strip() == "[]"


def test_one_quaternion_product():
    """One quaternion convention: the product is defined once in the library."""
    defs = [
        str(p.relative_to(REPO))
        for p in MODULES.values()
        for n in ast.walk(ast.parse(p.read_text()))
        if isinstance(n, ast.FunctionDef) and n.name in ("quat_mult", "quat_product")
    ]
    assert len(defs) == 1, defs


@pytest.fixture(scope="module")
def noisy_run(paper_seq):
    """paper-9pos with Table 2 errors and the navigation profile's noise."""
    import math

    from calib.model.error_model import ErrorModel
    from calib.noise.profiles import load_profile
    from calib.sequence.kinematics import SimConfig
    from calib.sim.gimbal_run import SimOptions, simulate

    run, _ = simulate(
        paper_seq,
        SimConfig(latitude_rad=math.radians(40.0)),
        ErrorModel.from_table2(),
        load_profile("navigation"),
        options=SimOptions(noise=True, seed=5),
    )
    return run


def test_cli_and_library_give_identical_sigmas(noisy_run, tmp_path):
    """The CLI's sigmas (Birge check included) are the library's, to the last digit."""
    from calib.calibration.entry import calibrate
    from calib.runlog import write_run
    from seqdesign.cli import main

    run = noisy_run
    path = tmp_path / "run.npz"
    write_run(run, path)
    res = CliRunner().invoke(main, ["calibrate", str(path), "--json"])
    assert res.exit_code == 0, res.output
    cli = json.loads(res.stdout)
    lib = calibrate(run).to_json()
    for name, e in lib["parameters"].items():
        assert cli["parameters"][name]["sigma"] == e["sigma"], name
        assert cli["parameters"][name]["value"] == e["value"], name
    assert cli["fit"]["sigma_scale"] == lib["fit"]["sigma_scale"]


def test_library_result_carries_the_policy(noisy_run):
    """A notebook gets the Birge scale, convergence, correlation and gravity without the CLI."""
    from calib.calibration.entry import calibrate
    from calib.noise.profiles import NoiseProfile

    run = noisy_run
    # Half the simulated noise density: chi2/dof ~ 4, so the sigmas must come back inflated
    # by its square root (the Birge ratio) straight from the library.
    half = NoiseProfile("half", 0.0005, 5.0)
    res = calibrate(run, half)
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


def test_the_command_line_starts_without_the_heavy_libraries():
    """`seqdesign --help` and a one-line refusal load no solver, viewer or plotting library: each
    command imports its machinery when it runs (casadi alone costs ~0.3 s of every start)."""
    code = (
        "import sys, seqdesign.cli; "
        "print(sorted(m for m in ('casadi', 'scipy', 'rerun', 'matplotlib', 'networkx', 'dask') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True)
    assert out.stdout.strip() == "[]"


def test_the_white_noise_paths_do_not_start_numba():
    """Analysing under white noise (the worst case over the box included) never imports numba."""
    code = (
        "import sys; from seqdesign.analysis import analyze; "
        "analyze('paper-9pos', 'navigation', latitude_deg=40.0); print('numba' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True)
    assert out.stdout.strip() == "False"
