"""examples/five-jobs.ipynb runs top to bottom on a Jupyter kernel of this Python and draws its figures."""

from __future__ import annotations

import importlib.util
import json
import os
import sys
from pathlib import Path

import nbformat
import pytest
from jupyter_client.kernelspec import KernelSpecManager
from jupyter_client.manager import KernelManager
from nbclient import NotebookClient

# A Jupyter kernel runs the whole notebook (about 25 s): in `make test-slow`, which CI runs too.
pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
NOTEBOOK = REPO / "examples" / "five-jobs.ipynb"
CELL_TIMEOUT_S = 300  # a loaded 2-core machine; the whole notebook takes about 10 s alone


def _kernel_manager(spec_root: Path) -> KernelManager:
    """A kernel of this very interpreter (the venv's), whatever kernels the machine has installed."""
    spec = spec_root / "seqdesign-test"
    spec.mkdir(parents=True)
    argv = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"]
    (spec / "kernel.json").write_text(
        json.dumps({"argv": argv, "display_name": "seqdesign", "language": "python"})
    )
    return KernelManager(
        kernel_name="seqdesign-test", kernel_spec_manager=KernelSpecManager(kernel_dirs=[str(spec_root)])
    )


def _make_notebook_module():
    spec = importlib.util.spec_from_file_location("make_notebook", REPO / "examples" / "make_notebook.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_committed_notebook_is_the_script_s_and_has_no_outputs():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(nb)
    built = _make_notebook_module().build()
    assert [(c.cell_type, c.source) for c in nb.cells] == [(c.cell_type, c.source) for c in built.cells], (
        "run python examples/make_notebook.py"
    )
    assert all(
        not c.get("outputs") and c.get("execution_count") is None for c in nb.cells if c.cell_type == "code"
    )


def test_the_notebook_runs_on_a_jupyter_kernel(tmp_path):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    # First, in the kernel: it is this Python, and the library is this checkout's.
    nb.cells.insert(
        0,
        nbformat.v4.new_code_cell(
            "import os, sys, seqdesign\n"
            f"assert os.path.realpath(sys.executable) == {os.path.realpath(sys.executable)!r}, "
            "sys.executable\n"
            f"assert os.path.realpath(seqdesign.__file__).startswith({str(REPO)!r}), seqdesign.__file__"
        ),
    )
    work = tmp_path / "work"
    work.mkdir()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    env["MPLBACKEND"] = "Agg"  # as on CI: the notebook must still show its figures inline
    client = NotebookClient(
        nb,
        km=_kernel_manager(tmp_path / "kernels"),
        timeout=CELL_TIMEOUT_S,
        resources={"metadata": {"path": str(work)}},
    )
    client.execute(env=env)  # raises CellExecutionError, naming the cell, on any error

    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert errors == []
    plotting = [c for c in nb.cells if c.cell_type == "code" and "plt.show()" in c.source]
    assert len(plotting) >= 3
    for cell in plotting:
        pngs = [o for o in cell.outputs if "image/png" in o.get("data", {})]
        assert len(pngs) == 1, cell.source
    # What the jobs wrote, in the notebook's working directory.
    out = work / "five-jobs-out"
    assert (out / "commands.csv").read_text().startswith("# format: gimbal-commands/1")
    assert (out / "run.rrd").stat().st_size > 0
    # The calibration table: every parameter's error within a few sigma (the design meets the truth).
    table = "".join(
        o.get("text", "")
        for c in nb.cells
        if "error/sigma" in c.source
        for o in c.outputs
        if o.output_type == "stream"
    )
    rows = [line.split() for line in table.splitlines()[1:] if line.strip()]
    assert len(rows) == 21
    assert all(abs(float(r[-1])) < 5.0 for r in rows), table
