"""What a careful user expects to read (issue 39): commands that work as printed, honest help and notes.

Each is run as a user runs it, the CLI in a process of its own.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


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
