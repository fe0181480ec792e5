"""What a careful user expects to read (issue 39): commands that work as printed, honest help and notes.

Each is run as a user runs it, the CLI in a process of its own.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from realdata import REPO


def cli(*args, cwd=None, env=None) -> subprocess.CompletedProcess:
    """``seqdesign ARGS`` in a process of its own: exit code, stdout and stderr as a user sees them."""
    return subprocess.run(
        [sys.executable, "-m", "seqdesign.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
    )


# ---------------------------------------------------------------------------
# 8. The viewer's command, as printed, runs from the user's shell


def test_the_printed_viewer_command_is_found_from_the_shell_that_ran_the_tool(tmp_path):
    res = cli("simulate", "paper-9pos", "--sample-rate-hz", "10", "-o", tmp_path / "r.npz")
    assert res.returncode == 0, res.stderr
    # As `make demo` runs it: the venv's Python, the venv not on PATH.
    bin_dir = str(Path(sys.executable).parent)
    path = os.pathsep.join(p for p in os.environ["PATH"].split(os.pathsep) if p != bin_dir)
    res = cli(
        "view", tmp_path / "r.npz", "-o", tmp_path / "r.rrd", cwd=REPO, env={**os.environ, "PATH": path}
    )
    assert res.returncode == 0, res.stderr
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("open it with: "))
    command = line.removeprefix("open it with: ").split()[0]
    found = shutil.which(command, path=path) if "/" not in command else str(REPO / command)
    assert found and os.access(found, os.X_OK), line


# ---------------------------------------------------------------------------
# 6. A warning names what the user can type where they are


def test_the_gravity_warning_names_the_command_line_flag(tmp_path):
    res = cli("simulate", "paper-9pos", "--sample-rate-hz", "10", "--seed", "2", "-o", tmp_path / "r.npz")
    assert res.returncode == 0, res.stderr
    # The paper's 1 ppm scale-factor requirement is within five mGal of normal gravity's error.
    res = cli("calibrate", tmp_path / "r.npz", "-o", tmp_path / "r.result.toml")
    assert res.returncode == 0, res.stderr
    line = next(ln for ln in res.stderr.splitlines() if "normal gravity" in ln)
    assert "--gravity" in line and "gravity_mps2" not in line
    # ... and with the surveyed gravity given, no such warning.
    res = cli("calibrate", tmp_path / "r.npz", "-o", tmp_path / "r2.result.toml", "--gravity", "9.80170")
    assert res.returncode == 0, res.stderr
    assert "normal gravity" not in res.stderr


# ---------------------------------------------------------------------------
# 14. Help that says what works, and is not cut mid-word


def _commands() -> list[str]:
    from seqdesign.cli import main

    return sorted(name for name, command in main.commands.items() if not command.hidden)


def _help(*command: str) -> str:
    res = subprocess.run(
        [sys.executable, "-m", "seqdesign.cli", *command, "--help"],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "80"},
    )
    assert res.returncode == 0, res.stderr
    return res.stdout


def test_no_help_text_is_cut_mid_word():
    import click

    from seqdesign.cli import main

    for name in _commands():
        command = main.commands[name]
        groups = [command] + list(getattr(command, "commands", {}).values())
        for cmd in groups:
            path = [name] if cmd is command else [name, cmd.name]
            # A line may end at a hyphen ("comma-" / "separated"), as typeset text does; any other
            # break inside a word (an example value cut in two) leaves a token that is not whole.
            words = set(" ".join(_help(*path).split()).replace("- ", "-").split())
            for param in cmd.params:
                if isinstance(param, click.Option) and param.help and not param.hidden:
                    for token in " ".join(param.help.split()).replace("- ", "-").split():
                        assert token in words, (path, param.name, token)


@pytest.mark.parametrize("command", ["show", "export", "simulate", "design", "verify"])
def test_gimbal_help_names_the_shipped_gimbals_that_work(command):
    shipped = sorted(p.stem for p in (REPO / "sequences" / "gimbals").glob("*.toml"))
    text = " ".join(_help(command).split())
    assert "(TOML)" not in text
    for name in shipped:
        assert name in text, (command, name)
        res = cli("show", "paper-9pos", "--gimbal", name)  # each name works as it is given
        assert "Traceback" not in res.stderr and "not found" not in res.stderr, res.stderr


def test_calibrate_by_hand_help_says_it_wants_a_white_noise_profile():
    text = " ".join(_help("calibrate").split())
    by_hand = text[text.index("--by-hand") :]
    assert "white-noise profile" in by_hand and "--profile mems" in by_hand


# ---------------------------------------------------------------------------
# 5. No casadi warnings where nothing is wrong


@pytest.mark.parametrize(
    "args",
    [
        ["analyze", "paper-9pos", "--profile", "mems"],
        ["analyze", "designed-15min", "--profile", str(REPO / "benchmarks" / "profiles" / "adis16405.toml")],
        ["compare", "paper-9pos", "designed-15min", "--profile", "mems"],
    ],
)
def test_mems_and_fitted_profiles_print_no_casadi_warnings(args):
    res = cli(*args)
    assert res.returncode == 0, res.stderr
    assert "CasADi" not in res.stderr and "WARNING(" not in res.stderr and "Inf detected" not in res.stderr


# ---------------------------------------------------------------------------
# 10, 11. Why a requirement is missed, said where it is printed; what no sequence can meet, before
# the search

G_40 = 9.801697  # normal gravity at 40 deg, 0 m (m/s^2), as conventions.md's WGS-84 formula gives
UG = 9.80665e-6


def _minutes_after(text: str, marker: str) -> float:
    tail = text[text.index(marker) + len(marker) :].split()
    value, unit = float(tail[0]), tail[1]
    return value * {"s": 1 / 60, "min": 1.0, "h": 60.0}[unit.rstrip(",;")]


def test_analyze_under_the_defaults_says_why_the_paper_sequence_misses():
    res = cli("analyze", "paper-9pos")
    assert res.returncode == 0, res.stderr
    out = res.stdout
    verdict = out.index("Verdict:")
    why = out[verdict:]
    assert "requirements paper under profile navigation" in why
    assert "these are the defaults" in why and "--profile" in why
    # The accelerometer scale factors: gravity is their only excitation, sigma >= VRW sqrt(3 / T) / g
    # (conventions.md); 1 ppm needs T >= 3 (3 VRW / (g 1e-6))^2.
    line = next(ln for ln in why.splitlines() if "sax, say, saz" in ln and "no sequence" in ln)
    needed_min = 3.0 * (3.0 * 10.0 * UG / (G_40 * 1e-6)) ** 2 / 60.0
    assert abs(_minutes_after(line, "a run of at least") - needed_min) < 0.01 * needed_min
    # The gyro scale factors are missed by this sequence's moves, not by a bound: said as such.
    assert any("sgy" in ln and "other moves" in ln for ln in why.splitlines())


def test_analyze_with_the_unit_s_own_profile_and_requirements_does_not_blame_the_defaults():
    res = cli("analyze", "paper-9pos", "--profile", "tactical", "--requirements", "tactical")
    assert res.returncode == 0, res.stderr
    assert "these are the defaults" not in res.stdout


@pytest.mark.slow  # a 3-min design search under a fitted Gauss-Markov profile: ~8 s
def test_design_says_before_searching_what_no_sequence_of_the_budget_can_meet(tmp_path):
    import json
    import tomllib

    prof_path = REPO / "benchmarks" / "profiles" / "adis16405.toml"
    prof = tomllib.loads(prof_path.read_text())
    res = cli("design", "--budget-min", "3", "--profile", prof_path, "--json", "-o", tmp_path / "d.toml")
    assert res.returncode == 0, res.stderr
    err = res.stderr
    line = next(ln for ln in err.splitlines() if "bgx, bgy, bgz" in ln and "no sequence" in ln)
    assert err.index(line) < err.index("designing")  # said before the search
    # The constant part of a stationary Gauss-Markov bias (sigma, tau) watched for T has variance
    # 2 sigma^2 tau / (T + 2 tau) at best; against the mems requirement of 30 deg/h at 3 sigma.
    sigma, tau, T = prof["gyro_bias_instability_dph"], prof["gyro_bias_correlation_s"], 180.0
    bound = 3.0 * sigma * (2.0 * tau / (T + 2.0 * tau)) ** 0.5 / 30.0
    stated = float(line.split("3 sigma is ")[1].split()[0])
    assert abs(stated - bound) < 0.01 * bound
    needed_h = 2.0 * tau * (sigma**2 / 10.0**2 - 1.0) / 3600.0  # sd = 10 deg/h
    assert abs(_minutes_after(line, "a run of at least") / 60.0 - needed_h) < 0.06
    # ... and the design found does not beat it.
    res = cli("analyze", tmp_path / "d.toml", "--profile", prof_path, "--json")
    ratios = json.loads(res.stdout)["parameters"]
    assert min(ratios[n]["ratio"] for n in ("bgx", "bgy", "bgz")) >= bound * 0.999


# ---------------------------------------------------------------------------
# 12. A profile's grade carries its requirements


def test_a_mems_run_calibrates_under_the_mems_profile_with_the_mems_requirements(tmp_path):
    run = tmp_path / "m.npz"
    res = cli(
        "simulate", "paper-9pos", "--profile", "mems", "--sample-rate-hz", "20", "--seed", "4", "-o", run
    )
    assert res.returncode == 0, res.stderr
    res = cli("calibrate", run, "--sequence", "paper-9pos", "--profile", "mems", "-o", tmp_path / "m.toml")
    assert res.returncode == 0, res.stderr  # the paper's requirements refused it: "cannot observe"
    assert "requirements mems: the default for profile mems" in res.stderr
    assert "requirements mems" in res.stdout
    # Asked for, the paper's stay.
    res = cli("analyze", "paper-9pos", "--profile", "mems", "--requirements", "paper", "--json")
    assert json.loads(res.stdout)["requirements"] == "paper" and "the default for" not in res.stderr


@pytest.mark.parametrize(
    "profile, requirements", [("navigation", "paper"), ("tactical", "tactical"), ("mems", "mems")]
)
def test_each_shipped_profile_is_judged_by_its_grade_s_requirements(profile, requirements):
    res = cli("analyze", "paper-9pos", "--profile", profile, "--tolerance-deg", "0", "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["requirements"] == requirements


# ---------------------------------------------------------------------------
# 13. verify says how far it is, and prints no column that has nothing


def test_verify_prints_progress_on_stderr_and_its_table_on_stdout():
    res = cli("verify", "paper-9pos", "--runs", "2", "--sample-rate-hz", "10", "--json")
    assert res.returncode == 0, res.stderr
    assert "2 of 2 runs done" in res.stderr
    assert json.loads(res.stdout)["runs"] == 2  # stdout stays one document


def test_verify_by_hand_prints_no_column_that_is_all_dashes():
    res = cli("verify", "--by-hand", "--runs", "2")
    assert res.returncode == 0, res.stderr
    assert "2 of 2 runs done" in res.stderr
    lines = res.stdout.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.split()[:2] == ["param", "unit"])
    assert "analyze σ" not in lines[head] and "pred" not in lines[head]
    rows = [ln.split() for ln in lines[head + 1 : head + 22]]
    assert len(rows) == 21 and all(len(r) == 4 for r in rows)  # param, unit, RMS error, RMS/σ run
    for column in range(2, len(rows[0])):
        assert any(r[column] != "-" for r in rows)
    # A pose list has the analyser's prediction: its columns are there.
    res = cli(
        "verify",
        "--by-hand",
        REPO / "sequences" / "hand" / "mems-5min.toml",
        "--profile",
        "mems",
        "--runs",
        "2",
    )
    assert res.returncode == 0, res.stderr
    assert "analyze σ" in res.stdout and "RMS/σ pred" in res.stdout


@pytest.mark.parametrize("arw_dph", [0.0005, 0.01, 0.02, 0.5, 0.6, 2.6])
def test_the_requirements_grade_is_the_grade_verify_draws_errors_by(arw_dph):
    from calib.model.requirements import grade_of
    from calib.noise.profiles import NoiseProfile
    from seqdesign import verify

    prof = NoiseProfile(name="p", gyro_arw_dph=arw_dph, accel_vrw_ug=10.0)
    assert grade_of(prof)[0].lower() == verify.grade_of(prof)


# ---------------------------------------------------------------------------
# 17. show says what the default gimbal is, and what keeps a design off a real one


def test_show_on_the_default_gimbal_warns_of_lock_and_winding_a_real_gimbal_refuses():
    seq = REPO / "benchmarks" / "sequences" / "adis16405-10min.toml"
    res = cli("show", seq)
    assert res.returncode == 0, res.stderr
    gimbal_line = next(ln for ln in res.stdout.splitlines() if ln.startswith("gimbal: "))
    assert "ideal" in gimbal_line and "no angle, rate or acceleration limit" in gimbal_line
    doc = json.loads(cli("show", seq, "--json").stdout)
    warnings = [ln for ln in res.stderr.splitlines() if ln.startswith("warning: ")]
    assert warnings == [f"warning: {w}" for w in doc["warnings"]]
    assert any("plays on none of the shipped gimbals" in w for w in warnings)
    # The rests in lock are those whose middle gimbal is at +-90 deg (conventions.md).
    locked = [p["position"] for p in doc["positions"] if abs((p["middle_deg"] + 90.0) % 180.0 - 90.0) > 89.99]
    assert locked and any(
        w.startswith(f"warning: rest(s) {', '.join(map(str, locked))} in gimbal lock") for w in warnings
    )
    # The middle gimbal's largest encoder angle, beyond a turn: cables would not follow.
    reach = max(abs(p["middle_deg"]) for p in doc["positions"])
    assert reach > 360 and any(f"middle gimbal winds to {reach:.0f} deg" in w for w in warnings)


@pytest.mark.parametrize("args", [["designed-30min-slip-rings"], ["paper-9pos", "--gimbal", "slip-rings"]])
def test_show_does_not_warn_of_a_real_gimbal_where_one_plays_it_or_one_is_given(args):
    res = cli("show", *args)
    assert "plays on none" not in res.stderr and "winds to" not in res.stderr
