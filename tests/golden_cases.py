"""The golden figures: what the CLI and the library say today, to hold a refactoring to.

Each case is a command run through the CLI (``--json``) or a library call, on inputs a
fresh clone makes itself (simulated runs, shipped sequences).  ``python
tests/golden_cases.py`` rewrites ``tests/golden/figures.json`` from the current code:
do that only when a change of figures is intended, and say which in the commit.
Volatile keys (wall-clock time, versions, paths, dates) are dropped before comparing.

The figures are computed in a process of their own whose OpenBLAS uses its AVX2 (Haswell)
kernels on every x86-64 CPU (:func:`in_own_process`). A CPU with AVX-512 makes OpenBLAS
pick other kernels, whose products round otherwise in the last bits; the worst mounting
within +-3 deg is the argmax of a flat function, so those bits moved it by 4e-5 deg, and
the figures evaluated there by up to 3e-4, far past the 1e-8 a refactoring is held to
(measured 2026-12-05 on a Sapphire Rapids machine: `OPENBLAS_CORETYPE=Haswell` restores
every figure). One kernel makes the golden figures a property of the code, not of the CPU.
numpy's own loops are held to AVX2 as well: on an AVX-512 CPU numpy evaluates sin, cos, exp and
log by SVML kernels that round otherwise than the C library, and the streamed MEMS fit, iterated
through its attitude feedback, carried those bits to 1e-7 (the figures written on the Sapphire
Rapids machine were 1e-7 away from an AMD EPYC's, AVX2 only, on 2026-12-07, at the same commit).
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

if __name__ == "__main__":  # as a script: tests/seqdesign/ must not shadow the package
    sys.path[0:1] = [str(Path(__file__).resolve().parents[1]), sys.path[0]]

from seqdesign import blas  # noqa: E402, F401  (one BLAS thread, set before numpy loads)

# isort: split
from click.testing import CliRunner

GOLDEN = Path(__file__).resolve().parent / "golden" / "figures.json"

# Keys whose values depend on the clock, the machine or the checkout, not on the physics.
VOLATILE = {
    "search_seconds",
    "seconds",
    "elapsed_s",
    "tool_version",
    "version",
    "created",
    "date",
    "path",
    "run",
    "truth",
    "output",
    "file",
    "written",
    "provenance",
    "wall_s",
    "cpu_s",
    "commit",
    "source_file",
    "result",
}

SIMULATIONS = {
    # name: simulate arguments (the run is written to <tmp>/<name>.npz)
    "nav": [
        "paper-9pos",
        "--table2",
        "--setup-deg",
        "1",
        "-2",
        "3",
        "--seed",
        "7",
        "--sample-rate-hz",
        "100",
    ],
    "mems": [
        "designed-15min",
        "--profile",
        "mems",
        "--table2",
        "--setup-deg",
        "-2",
        "1",
        "0.5",
        "--seed",
        "3",
        "--sample-rate-hz",
        "100",
    ],
}

ANALYSES = {
    **{
        f"analyze {s}": ["analyze", s]
        for s in (
            "paper-9pos",
            "paper-9pos-turns",
            "designed-15min",
            "designed-15min-gm",
            "designed-30min",
            "designed-30min-9moves",
            "designed-30min-cable-wrap",
            "designed-30min-slip-rings",
            "designed-30min-gm",
        )
    },
    "analyze paper-9pos mems": ["analyze", "paper-9pos", "--profile", "mems", "--requirements", "mems"],
    "analyze paper-9pos with all": ["analyze", "paper-9pos", "--with", "all"],
    "analyze designed-15min-gm gm": [
        "analyze",
        "designed-15min-gm",
        "--profile",
        "navigation-gm",
        "--tolerance-deg",
        "0",
    ],
    "compare": ["compare", "paper-9pos", "designed-15min"],
    "show paper-9pos": ["show", "paper-9pos"],
}

CALIBRATIONS = {
    # name: (run, arguments after the run file)
    "calibrate nav": ("nav", ["calibrate"]),
    "calibrate nav sequence": ("nav", ["calibrate", "--sequence", "paper-9pos"]),
    "calibrate nav with all": ("nav", ["calibrate", "--with", "all"]),
    "calibrate nav mems-req": ("nav", ["calibrate", "--requirements", "mems"]),
    "calibrate-stream nav": ("nav", ["calibrate-stream"]),
    "calibrate mems": ("mems", ["calibrate", "--profile", "mems"]),
    "calibrate-stream mems": ("mems", ["calibrate-stream", "--profile", "mems"]),
}

# The clock's fit of a simulated (ideal) time column: round-off figures (jitter ~1e-13 s, rate
# error ~2e-11 ppm) whose last digits vary from run to run; held to an absolute floor
# far below anything a user reads (1 ns, 1e-9 ppm).
ABSOLUTE = {"jitter_max_s": 1e-9, "jitter_rms_s": 1e-9, "rate_error_ppm": 1e-9}

DESIGN = ["design", "--budget-min", "2", "--beam-width", "8", "--min-dwell-s", "10"]

# The hand path: a simulated hand run with some of a real recording's troubles (poses held in a
# trembling hand for the first 20 s, a gyro g-sensitivity), calibrated as its owner would; a
# shipped pose list analysed; a small by-hand Monte Carlo.
HAND_SIMULATION = [
    "simulate", "--by-hand", "--poses", "20", "--profile", "mems", "--random-errors", "mems",
    "--seed", "3", "--sample-rate-hz", "100", "--tremor-deg", "0.1", "--hand-held-s", "20",
    "--g-sensitivity-dphg", "200",
]  # fmt: skip
HAND = {
    "calibrate hand": ["calibrate", "{run}", "--by-hand", "--profile", "mems"],
    "calibrate hand without g-sensitivity": [
        "calibrate", "{run}", "--by-hand", "--profile", "mems", "--without", "g-sensitivity",
    ],
    "analyze hand mems-5min": [
        "analyze", "sequences/hand/mems-5min.toml", "--by-hand", "--profile", "mems", "--placements", "3",
    ],
    "verify hand": [
        "verify", "--by-hand", "--poses", "14", "--profile", "mems", "--runs", "2", "--seed", "1",
        "--workers", "1", "--sample-rate-hz", "100",
    ],
}  # fmt: skip

# The real hand recordings copied into tests/data/realdata (sources and licences beside them),
# calibrated as their owners would (`--by-hand --profile mems` and the site, nothing else), and a
# pose list designed by hand.
REALDATA = "tests/data/realdata"
MIKOFF = [
    "--columns", "1=accel_x_mps2,2=accel_y_mps2,3=accel_z_mps2,4=gyro_x_radps,5=gyro_y_radps,6=gyro_z_radps",
    "--sample-rate-hz", "100", "--latitude", "55", "--height", "100",
]  # fmt: skip
REAL = {
    "calibrate real xsens": [
        "calibrate", f"{REALDATA}/imu_tk-xsens/xsens_acc.mat.gz",
        "--gyro-file", f"{REALDATA}/imu_tk-xsens/xsens_gyro.mat.gz",
        "--conversion", f"{REALDATA}/imu_tk-xsens/xsens-nominal-values.txt",
        "--by-hand", "--profile", "mems", "--latitude", "45.4", "--height", "0",
    ],
    "calibrate real ferraris": [
        "calibrate", f"{REALDATA}/imucal-ferraris/example_ferraris_session.csv", "--sample-rate-hz", "102.4",
        "--columns", "n_samples=counter,gyr_x=gyro_x_dps,gyr_y=gyro_y_dps,gyr_z=gyro_z_dps,"
        "acc_x=accel_x_mps2,acc_y=accel_y_mps2,acc_z=accel_z_mps2",
        "--by-hand", "--profile", "mems", "--latitude", "49.6", "--height", "300", "--gravity", "9.81",
    ],
    "calibrate real mpu9150 imu0": [
        "calibrate", f"{REALDATA}/mikoff-mpu9150/imu0.log.gz", *MIKOFF, "--by-hand", "--profile", "mems",
    ],
    "calibrate real mpu9150 imu1": [
        "calibrate", f"{REALDATA}/mikoff-mpu9150/imu1.log.gz", *MIKOFF, "--by-hand", "--profile", "mems",
    ],
    "design hand 3 min": ["design", "--by-hand", "--budget-min", "3", "--profile", "mems"],
}  # fmt: skip


def scrub(doc):
    """The document without its volatile keys (recursively)."""
    if isinstance(doc, dict):
        return {k: scrub(v) for k, v in doc.items() if k not in VOLATILE}
    if isinstance(doc, list):
        return [scrub(v) for v in doc]
    return doc


def _cli(args: list[str]) -> dict:
    from seqdesign.cli import main

    res = CliRunner().invoke(main, [*args, "--json"])
    if res.exit_code != 0:
        raise RuntimeError(f"{' '.join(args)} failed ({res.exit_code}): {res.output[-2000:]}")
    return scrub(json.loads(res.stdout))


def figures(tmp: Path, which: str = "all") -> dict:
    """Every golden figure, computed now, run files written under ``tmp``."""
    out: dict = {}
    if which in ("all", "analyze"):
        for name, args in ANALYSES.items():
            out[name] = _cli(args)
    if which in ("all", "calibrate"):
        for name, args in SIMULATIONS.items():
            out[f"simulate {name}"] = _cli(["simulate", *args, "-o", str(tmp / f"{name}.npz")])
        for name, (run, args) in CALIBRATIONS.items():
            out[name] = _cli(
                [
                    args[0],
                    str(tmp / f"{run}.npz"),
                    *args[1:],
                    "-o",
                    str(tmp / f"{name.replace(' ', '_')}.result.toml"),
                ]
            )
        out["api calibrate nav"] = _api_calibrate(tmp / "nav.npz")
    if which in ("all", "hand"):
        run = str(tmp / "hand.npz")
        out["simulate hand"] = _cli([*HAND_SIMULATION, "-o", run])
        repo = Path(__file__).resolve().parent.parent
        for name, args in HAND.items():
            args = [a.replace("{run}", run) for a in args]
            args = [str(repo / a) if a.startswith("sequences/") else a for a in args]
            if args[0] == "calibrate":
                args += ["-o", str(tmp / f"{name.replace(' ', '_')}.result.toml")]
            out[name] = _cli(args)
    if which in ("all", "real"):
        repo = Path(__file__).resolve().parent.parent
        for name, args in REAL.items():
            args = [str(repo / a) if a.startswith(REALDATA) else a for a in args]
            out[name] = _cli([*args, "-o", str(tmp / f"{name.replace(' ', '_')}.toml")])
    if which in ("all", "design"):
        out["design 2 min"] = _cli([*DESIGN, "-o", str(tmp / "d2.toml")])
        out["api design 2 min"] = _api_design()
        out["api analyze designed-15min"] = _api_analyze()
    return out


def _api_calibrate(path: Path) -> dict:
    from seqdesign import api as sd

    return scrub(sd.calibrate(sd.read_run(path), profile="navigation").to_json())


def _api_analyze() -> dict:
    from seqdesign import api as sd

    return scrub(sd.analyze("designed-15min", tolerance_deg=3.0).to_json())


def _api_design() -> dict:
    from seqdesign import api as sd

    constraints = {"min_dwell_s": 10.0}
    report = sd.design([2.0], constraints, "navigation", sd.DesignOptions(beam_width=8))
    return scrub(report.to_json())


def compare(got, want, where: str = "", rel: float = 1e-8) -> list[str]:
    """Differences between two documents: numbers beyond ``rel`` relative, anything else unequal."""
    if isinstance(want, dict):
        if not isinstance(got, dict) or set(got) != set(want):
            return [f"{where}: keys {sorted(set(got) ^ set(want)) if isinstance(got, dict) else got}"]
        return [d for k in want for d in compare(got[k], want[k], f"{where}.{k}", rel)]
    if isinstance(want, list):
        if not isinstance(got, list) or len(got) != len(want):
            return [f"{where}: length {len(got) if isinstance(got, list) else got} != {len(want)}"]
        return [
            d
            for i, (g, w) in enumerate(zip(got, want, strict=True))
            for d in compare(g, w, f"{where}[{i}]", rel)
        ]
    if isinstance(want, float) and isinstance(got, (int, float)) and not isinstance(got, bool):
        floor = ABSOLUTE.get(where.rsplit(".", 1)[-1], 0.0)
        if got == want or abs(got - want) <= max(rel * max(abs(want), abs(got)), floor):
            return []
        return [f"{where}: {got!r} != {want!r}"]
    return [] if got == want else [f"{where}: {got!r} != {want!r}"]


# numpy's AVX-512 dispatch targets (numpy 2.x names), turned off so that AVX2 runs everywhere.
NUMPY_AVX512 = "AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR"


def kernel_env() -> dict[str, str]:
    """This process's environment with OpenBLAS and numpy held to AVX2 kernels (module docstring)."""
    env = dict(os.environ)
    if platform.machine().lower() in ("x86_64", "amd64"):
        env["OPENBLAS_CORETYPE"] = "Haswell"
        env["NPY_DISABLE_CPU_FEATURES"] = NUMPY_AVX512
    return env


def in_own_process(tmp: Path, which: str) -> dict:
    """:func:`figures` computed by ``python golden_cases.py figures WHICH TMP`` under :func:`kernel_env`."""
    done = subprocess.run(
        [sys.executable, __file__, "figures", which, str(tmp)],
        env=kernel_env(),
        cwd=Path(__file__).resolve().parent.parent,
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise RuntimeError(f"golden figures '{which}' failed ({done.returncode}): {done.stderr[-3000:]}")
    return json.loads(done.stdout)


if __name__ == "__main__":
    import tempfile

    pinned = ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES")
    if any(os.environ.get(k) != kernel_env().get(k) for k in pinned):
        os.execve(sys.executable, [sys.executable, *sys.argv], kernel_env())  # before numpy loads
    if sys.argv[1:2] == ["figures"]:
        print(json.dumps(figures(Path(sys.argv[3]), sys.argv[2])))
        sys.exit(0)
    with tempfile.TemporaryDirectory() as tmp:
        doc = figures(Path(tmp))
    GOLDEN.parent.mkdir(exist_ok=True)
    GOLDEN.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    print(f"wrote {GOLDEN} ({len(doc)} cases)", file=sys.stderr)
