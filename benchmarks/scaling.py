"""Calibrate time and peak memory against the number of samples (issue 18).

    python benchmarks/scaling.py [--rates 200,1000,2000] [--minutes 15,28.2,60,120]
                                 [--base ../wt-base] [--base-max-samples 2000000]
                                 [--write BENCHMARKS.md] [--plot docs/scaling.png]

For every rate and duration it simulates a run of the paper's 9 positions
with the dwells stretched to the duration (Table 2 errors, mounting
(1, -2, 3) deg, seed 7), streamed to NPZ (:mod:`calib.sim.to_disk`), then
times ``seqdesign calibrate`` on it in a subprocess under ``/usr/bin/time -v``:
wall time, CPU time (user + system: the machine is shared, CPU time is
the steadier figure) and peak resident memory. With ``--base`` the same
command also runs from another checkout (the code before issue 18) on the
same files, in the same run, and the estimates of the two are compared in
units of the reported sigma. Nothing is asserted: the table says what was
measured, where and when.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PYTHON = sys.executable
FLIPS_S = 8 * 9.0  # the paper's 8 flips of 90 deg at 10 deg/s
BEGIN, END = "<!-- scaling:begin -->", "<!-- scaling:end -->"


def stretched_sequence(minutes: float, folder: Path) -> Path:
    """paper-9pos with its 9 dwells stretched so that the run lasts ``minutes``."""
    text = (ROOT / "sequences" / "paper-9pos.toml").read_text()
    dwell = (60.0 * minutes - FLIPS_S) / 9.0
    text = re.sub(r"(dwell_s\s*=\s*)[0-9.]+", lambda m: f"{m.group(1)}{dwell:.3f}", text)
    text = text.replace('name = "paper-9pos"', f'name = "paper-9pos-{minutes:g}min"')
    path = folder / f"paper-9pos-{minutes:g}min.toml"
    path.write_text(text)
    return path


def timed(cmd: list[str], cwd: Path) -> dict:
    """Wall, CPU and peak RSS of a command, from GNU time."""
    out = subprocess.run(["/usr/bin/time", "-v", *cmd], cwd=cwd, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"failed ({out.returncode}): {' '.join(cmd)}\n{out.stderr[-2000:]}")

    def field(name):
        return re.search(rf"{name}: (.*)", out.stderr).group(1).strip()

    elapsed = field(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\)")
    h, m, s = ([0] + [float(x) for x in elapsed.split(":")])[-3:]
    return {
        "wall_s": 3600 * h + 60 * m + s,
        "cpu_s": float(field("User time \\(seconds\\)")) + float(field("System time \\(seconds\\)")),
        "rss_mb": int(field("Maximum resident set size \\(kbytes\\)")) / 1024.0,
    }


def calibrate(tree: Path, run: Path, out: Path) -> dict:
    return timed([PYTHON, "-m", "seqdesign.cli", "calibrate", str(run), "-o", str(out)], tree)


def simulate(seq: Path, rate: float, run: Path) -> dict:
    return timed(
        [
            PYTHON,
            "-m",
            "seqdesign.cli",
            "simulate-stream",
            str(seq),
            "-o",
            str(run),
            "--table2",
            "--setup-deg",
            "1",
            "-2",
            "3",
            "--seed",
            "7",
            "--sample-rate-hz",
            f"{rate:g}",
        ],
        ROOT,
    )


def max_difference_sigma(new: Path, base: Path) -> float:
    """Largest |estimate difference| / sigma over the 21, from two result files."""
    sys.path.insert(0, str(ROOT))
    from calib.calibration.result import CalibrationResult

    a, b = CalibrationResult.load(new), CalibrationResult.load(base)
    return float(max(abs(x - y) / s for x, y, s in zip(a.values, b.values, b.sigma, strict=True)))


def measure(rates, minutes, base: Path | None, base_max: int, folder: Path) -> list[dict]:
    rows = []
    for mins in minutes:
        seq = stretched_sequence(mins, folder)
        for rate in rates:
            run = folder / f"run-{rate:g}hz-{mins:g}min.npz"
            sim = simulate(seq, rate, run)
            row = {
                "rate": rate,
                "minutes": mins,
                "samples": int(round(rate * 60 * mins)),
                "sim": sim,
                "new": calibrate(ROOT, run, run.with_suffix(".new.toml")),
            }
            if base is not None and row["samples"] <= base_max:
                row["base"] = calibrate(base, run, run.with_suffix(".base.toml"))
                row["diff_sigma"] = max_difference_sigma(
                    run.with_suffix(".new.toml"), run.with_suffix(".base.toml")
                )
            rows.append(row)
            print(_line(row), flush=True)
            run.unlink()
    return rows


def _line(r: dict) -> str:
    base = r.get("base")
    cells = [
        f"{r['rate']:g}",
        f"{r['minutes']:g}",
        f"{r['samples']:,}",
        f"{r['new']['wall_s']:.2f}",
        f"{r['new']['cpu_s']:.2f}",
        f"{r['new']['rss_mb']:.0f}",
        f"{base['wall_s']:.2f}" if base else "-",
        f"{base['cpu_s']:.2f}" if base else "-",
        f"{base['rss_mb']:.0f}" if base else "-",
        f"{r['diff_sigma']:.1e}" if "diff_sigma" in r else "-",
        f"{r['sim']['wall_s']:.1f}",
        f"{r['sim']['rss_mb']:.0f}",
    ]
    return "| " + " | ".join(cells) + " |"


def table(rows: list[dict], command: str, base: Path | None) -> str:
    head = (
        "| rate Hz | min | samples | calibrate wall s | CPU s | peak MB | base wall s | "
        "base CPU s | base peak MB | max |new-base|/sigma | simulate wall s | simulate peak MB |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    machine = (
        f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, {platform.node()}"
    )
    return (
        f"{BEGIN}\nMeasured {datetime.date.today().isoformat()} on {machine}; base = "
        f"{base or 'not run'}; command:\n\n    {command}\n\n"
        + head
        + "\n".join(_line(r) for r in rows)
        + f"\n{END}\n"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", default="200,1000,2000")
    ap.add_argument("--minutes", default="15,28.2,60,120")
    ap.add_argument("--base", type=Path, help="checkout of the code to compare with")
    ap.add_argument("--base-max-samples", type=int, default=2_000_000)
    ap.add_argument("--write", type=Path, help="replace the scaling table in this Markdown file")
    ap.add_argument("--plot", type=Path, help="PNG of time and memory against samples")
    a = ap.parse_args()
    rates = [float(x) for x in a.rates.split(",")]
    minutes = [float(x) for x in a.minutes.split(",")]
    with tempfile.TemporaryDirectory(prefix="scaling-") as tmp:
        rows = measure(rates, minutes, a.base, a.base_max_samples, Path(tmp))
    text = table(rows, "python benchmarks/scaling.py " + " ".join(sys.argv[1:]), a.base)
    print(text)
    if a.write:
        doc = a.write.read_text() if a.write.exists() else ""
        if BEGIN in doc:
            doc = doc[: doc.index(BEGIN)] + text + doc[doc.index(END) + len(END) + 1 :]
        else:
            doc += "\n## Calibrate scaling (issue 18)\n\n" + text
        a.write.write_text(doc)
    if a.plot:
        plot(rows, a.plot)


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    n = [r["samples"] for r in rows]
    for key, label in (("new", "streamed"), ("base", "before (37f6570)")):
        pts = [(r["samples"], r[key]) for r in rows if key in r]
        if not pts:
            continue
        ax1.loglog([p[0] for p in pts], [p[1]["cpu_s"] for p in pts], "o", label=label)
        ax2.loglog([p[0] for p in pts], [p[1]["rss_mb"] for p in pts], "o", label=label)
    ref = min(n), max(n)
    t0 = min(r["new"]["cpu_s"] for r in rows if r["samples"] == ref[0])
    ax1.loglog(ref, [t0, t0 * ref[1] / ref[0]], "k:", label="linear")
    ax1.set(xlabel="samples", ylabel="calibrate CPU time, s")
    ax2.set(xlabel="samples", ylabel="peak RSS, MB")
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
