"""Every option of every command says what it is: the help a user reads before the README."""

from __future__ import annotations

import click
import pytest
from click.testing import CliRunner

from seqdesign.cli import main


def _commands(cmd: click.Command, path: tuple[str, ...] = ()):
    """Every visible command under ``cmd``, recursively through groups, with its path."""
    if getattr(cmd, "hidden", False):
        return
    yield path, cmd
    if isinstance(cmd, click.Group):
        for name, sub in sorted(cmd.commands.items()):
            yield from _commands(sub, (*path, name))


COMMANDS = list(_commands(main))


def test_the_walk_finds_the_commands_and_subcommands():
    paths = {" ".join(p) for p, _ in COMMANDS}
    assert {"design", "analyze", "compare", "calibrate", "export", "profile fit"} <= paths


@pytest.mark.parametrize("path, cmd", COMMANDS, ids=[" ".join(p) or "seqdesign" for p, _ in COMMANDS])
def test_every_option_has_help(path, cmd):
    bare = [
        "/".join(p.opts)
        for p in cmd.params
        if isinstance(p, click.Option) and not p.hidden and not (p.help or "").strip()
    ]
    assert not bare, f"seqdesign {' '.join(path)}: options without help: {bare}"


@pytest.mark.parametrize("path, cmd", COMMANDS, ids=[" ".join(p) or "seqdesign" for p, _ in COMMANDS])
def test_help_speaks_to_a_user_not_of_the_tracker(path, cmd):
    texts = [cmd.help or "", cmd.short_help or "", cmd.epilog or ""]
    texts += [p.help or "" for p in cmd.params if isinstance(p, click.Option)]
    assert not [t for t in texts if "issue" in t.lower()], f"seqdesign {' '.join(path)}"


@pytest.mark.parametrize("path, cmd", COMMANDS, ids=[" ".join(p) or "seqdesign" for p, _ in COMMANDS])
def test_help_page_renders(path, cmd):
    r = CliRunner().invoke(main, [*path, "--help"])
    assert r.exit_code == 0 and "Usage:" in r.stdout


def test_profile_fit_help_lists_every_format_it_reads():
    # what calib.runlog.read_run reads: CSV (also gzipped), NPZ and the PSINS .imu log
    text = CliRunner().invoke(main, ["profile", "fit", "--help"]).stdout
    for fmt in ("CSV", "CSV.GZ", "NPZ", ".imu"):
        assert fmt in text, fmt


def test_design_dwell_options_say_their_unit_and_meaning():
    text = CliRunner().invoke(main, ["design", "--help"]).stdout
    for opt in ("--min-dwell-s", "--max-dwell-s", "--tolerance-deg", "--beam-width", "--name"):
        assert opt in text
    assert "Shortest rest between moves, s" in " ".join(text.split())
