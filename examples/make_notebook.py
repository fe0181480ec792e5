"""Write examples/five-jobs.ipynb (without outputs): ``python examples/make_notebook.py``.

The notebook is code: edit the cells here, run this script, commit both. The tests
(tests/test_notebook.py) execute the notebook top to bottom on a Jupyter kernel.
"""

from __future__ import annotations

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).resolve().parent

CELLS = [
    (
        "md",
        """# The five jobs, from a notebook

What `seqdesign` does, with the library a notebook calls (`from seqdesign import api as sd`):
every command of the CLI is one call here, and every result prints itself (`to_text()`) and
gives the numbers of the command's `--json` (`to_json()`).

1. check a sequence (`seqdesign analyze`)
2. design one for your unit and your gimbal (`seqdesign design`, `show`, `export`)
3. calibrate a run (`seqdesign simulate`, `calibrate`)
4. look at a run (`seqdesign view`: a rerun recording)
5. do it from a notebook: this notebook.

It runs in under a minute (short budget, small beam) and writes its files to `five-jobs-out/`.""",
    ),
    (
        "code",
        """# One BLAS thread before numpy loads, as the CLI does: the work is many small matrix
# products, which extra BLAS threads slow down.
from seqdesign import blas  # noqa: F401

%matplotlib inline
import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from seqdesign import api as sd

out = Path("five-jobs-out")
out.mkdir(exist_ok=True)""",
    ),
    (
        "md",
        """## 1. Check a sequence

`sd.analyze` gives each of the 21 parameters' 3σ over its requirement (the paper's), at the
worst mounting within ±3°. Below 1 the sequence meets the requirement. Here the paper's
9-position sequence against a shipped design of 15 minutes.""",
    ),
    (
        "code",
        """paper = sd.analyze("paper-9pos", tolerance_deg=3.0)
designed = sd.analyze("designed-15min", tolerance_deg=3.0)
print(paper.to_text())""",
    ),
    (
        "code",
        '''def ratios(analysis):
    """3 sigma / requirement of each parameter, in the table's order."""
    doc = analysis.to_json()
    return [doc["parameters"][p.name]["ratio"] for p in sd.PARAMETERS]


names = [p.name for p in sd.PARAMETERS]
x = np.arange(len(names))
fig, ax = plt.subplots(figsize=(11, 3.5))
for k, (label, analysis) in enumerate((("paper-9pos", paper), ("designed-15min", designed))):
    minutes = analysis.to_json()["duration_s"] / 60
    ax.bar(x + 0.4 * (k - 0.5), ratios(analysis), width=0.4, label=f"{label} ({minutes:.0f} min)")
ax.axhline(1.0, color="k", lw=1, ls="--")
ax.set(yscale="log", xticks=x, ylabel="3 sigma / requirement", title="Check a sequence: worst over +-3 deg")
ax.set_xticklabels(names, rotation=90)
ax.legend()
plt.show()''',
    ),
    (
        "md",
        """## 2. Design a sequence for your gimbal

A 2-minute budget on the shipped `cable-wrap` gimbal (±360° cumulative, a lock margin, runs
end at home), with a small beam and moves of at most three quarter turns, so that it takes
seconds. The CLI's `seqdesign design --budget-min 2 --gimbal cable-wrap --beam-width 8
--max-quarters 3` is the same search; a real design uses the defaults (minutes).""",
    ),
    (
        "code",
        """constraints = {"max_quarters": 3, "min_dwell_s": 10}  # as sd.Constraints' fields
report = sd.design([2], constraints, options=sd.DesignOptions(beam_width=8), gimbal="cable-wrap")
print(report.to_text())
seq = report.rows[0].result.sequence""",
    ),
    (
        "md",
        """`sd.show` lists its rest positions and how the gimbal plays it; `sd.export` gives the
encoder commands a controller plays (and writes them as CSV).""",
    ),
    (
        "code",
        """shown = sd.show(seq, gimbal="cable-wrap")
print(shown.to_text())
schedule = sd.export(seq, gimbal="cable-wrap", rate_hz=20)
schedule.save(out / "commands.csv")
angles, rates = schedule.encoders()
fig, ax = plt.subplots(figsize=(11, 3))
for j, axis in enumerate(("outer", "middle", "inner")):
    ax.plot(schedule.times_s, angles[:, j], label=axis)
ax.set(xlabel="time, s", ylabel="encoder angle, deg", title=f"{seq.name} on {schedule.gimbal.name}")
ax.legend()
plt.show()""",
    ),
    (
        "md",
        """## 3. Calibrate a run

No IMU at hand: simulate one running the design on the gimbal, with the paper's Table 2
errors and the `navigation` noise profile, then calibrate it. With your own log,
`run = sd.read_run("mylog.csv", latitude_deg=..., height_m=...)` takes its place.""",
    ),
    (
        "code",
        """site = sd.SimConfig(latitude_rad=math.radians(40.0), sample_rate_hz=100.0)
errors, noise = sd.ErrorModel.from_table2(), sd.load_profile("navigation")
draws = sd.SimOptions(seed=1)  # the run's draws: mounting, flip errors, noise, seed
run, truth = sd.simulate(seq, site, errors, noise, draws, gimbal=shown.gimbal)
result = sd.calibrate(run, profile="navigation")
estimates = result.to_json()["parameters"]
true_values = truth.errors.in_units()
print(f"{'param':6} {'unit':7} {'truth':>9} {'estimate':>10} {'sigma':>8} {'error/sigma':>11}")
for p, true in zip(sd.PARAMETERS, true_values, strict=True):
    e = estimates[p.name]
    z = (e["value"] - true) / e["sigma"]
    print(f"{p.name:6} {p.unit:7} {true:9.4g} {e['value']:10.5g} {e['sigma']:8.3g} {z:11.2f}")""",
    ),
    (
        "code",
        """z = [
    (estimates[p.name]["value"] - t) / estimates[p.name]["sigma"]
    for p, t in zip(sd.PARAMETERS, true_values, strict=True)
]
fig, ax = plt.subplots(figsize=(11, 3))
ax.bar(x, z)
for level in (-3, 3):
    ax.axhline(level, color="k", lw=1, ls="--")
ax.set(xticks=x, ylabel="(estimate - truth) / sigma", title="Calibrate: each error within its 3 sigma")
ax.set_xticklabels(names, rotation=90)
plt.show()""",
    ),
    (
        "md",
        """## 4. Look at the run

`sd.record` writes a rerun recording (what `seqdesign view` writes): the gimbal and the IMU
in 3D, the signals, the residuals before and after, the results against the truth.""",
    ),
    (
        "code",
        """summary = sd.record(run, out / "run.rrd", result=result, sequence=seq, truth=truth)
print(f"wrote {summary.path}: {len(summary.entities)} entities")""",
    ),
    (
        "md",
        """Open it with the rerun viewer, which the `rerun-sdk` package installs: `rerun
five-jobs-out/run.rrd` in a terminal (in the repository, inside `.venv`). From a log file,
`seqdesign view run.npz --sequence SEQ -o run.rrd` writes the same.""",
    ),
    (
        "md",
        """## 5. From a notebook

That was it. The calls, one per command: `sd.analyze`, `sd.design`, `sd.show`, `sd.export`,
`sd.simulate`, `sd.read_run`, `sd.calibrate`, `sd.record`, `sd.profile_fit` (a noise profile
from your IMU's static log), `sd.compare_results`. Each has its documentation:
`help(sd.design)`.""",
    ),
    ("code", """print(", ".join(sd.__all__))"""),
]


def build() -> nbformat.NotebookNode:
    """The notebook, without outputs."""
    nb = new_notebook(
        cells=[new_markdown_cell(text) if kind == "md" else new_code_cell(text) for kind, text in CELLS],
        metadata={
            "kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"},
            "language_info": {"name": "python"},
        },
    )
    for i, cell in enumerate(nb.cells):
        cell["id"] = f"cell-{i}"  # stable ids: the file changes only when a cell does
    return nb


if __name__ == "__main__":
    nbformat.write(build(), HERE / "five-jobs.ipynb")
