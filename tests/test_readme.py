"""The README's five jobs work as written, from an empty directory.

Every fenced block of README.md is read in order:

- ```sh blocks: each line starting with ``seqdesign `` is run through click's CliRunner
  (exit code 0 expected), in one temporary directory, in the README's order;
- ```toml blocks whose first line is ``# file: NAME``: written to NAME there, as the README
  asks the reader to save them;
- ```python blocks: executed there, after the commands before them;
- ```text blocks: templates for the reader's own files (``mylog.csv``); not run, but every
  command and option they name must exist.

A line may end with ``# needs: FEATURE``: a feature another part of the tool provides. It is run
(or, in a template, checked) once its command and options exist, and skipped until then.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from seqdesign.cli import main

README = Path(__file__).parents[1] / "README.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)
NEEDS = re.compile(r"\s+#\s*needs:\s*([\w ,-]+)$")


@dataclass(frozen=True)
class Block:
    """One fenced block of the README: its language and its text."""

    lang: str
    text: str


@dataclass(frozen=True)
class Command:
    """One ``seqdesign`` line: its arguments (without ``seqdesign``) and what it needs, if marked."""

    args: tuple[str, ...]
    needs: str | None
    line: str


def blocks() -> list[Block]:
    return [Block(m.group(1), m.group(2)) for m in FENCE.finditer(README.read_text())]


def commands(block: Block) -> list[Command]:
    out = []
    for raw in block.text.splitlines():
        line = raw.strip()
        if not line.startswith("seqdesign "):
            continue
        match = NEEDS.search(line)
        needs = match.group(1).strip() if match else None
        words = shlex.split(line[: match.start()] if match else line, comments=True)
        out.append(Command(tuple(words[1:]), needs, line))
    return out


def resolve(args: tuple[str, ...]) -> tuple[click.Command | None, list[str]]:
    """The click command the arguments name and its options' spellings (None: no such command)."""
    command: click.Command = main
    for word in args:
        if not isinstance(command, click.Group) or word.startswith("-"):
            break
        sub = command.commands.get(word)
        if sub is None:
            return None, []
        command = sub
    spellings = [opt for p in command.params for opt in (*p.opts, *p.secondary_opts)]
    return command, spellings


def missing(cmd: Command) -> list[str]:
    """What the line names that the CLI lacks: its command, or options."""
    command, spellings = resolve(cmd.args)
    if command is None:
        return [" ".join(cmd.args[:2])]
    options = [a.split("=", 1)[0] for a in cmd.args if a.startswith("--")]
    return [o for o in options if o not in spellings and o != "--help"]


def test_readme_is_a_short_guide_without_issue_numbers():
    text = README.read_text()
    assert len(text.splitlines()) <= 200
    assert not re.search(r"\bissue\s+\d+|the issue's", text, re.I)


def test_no_issue_numbers_where_a_user_reads():
    root = README.parent
    pages = [README, root / "CHANGELOG.md", root / "BENCHMARKS.md", *sorted((root / "docs").glob("*.md"))]
    pages.append(root / "docs" / "analysis" / "README.md")
    for page in pages:
        hits = re.findall(r".{0,30}\b(?:issues?\s+\d+|the issue's).{0,30}", page.read_text(), re.I)
        assert hits == [], f"{page.name}: {hits}"


def _resolves(dotted: str) -> bool:
    """Whether ``calib.x.y`` (a module, then attributes) names something that exists."""
    import importlib

    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for name in parts[i:]:
                obj = getattr(obj, name)
        except AttributeError:
            return False
        return True
    return False


def test_every_code_name_the_pages_quote_exists():
    """A page that sends a reader to `calib.fit.start.MIN_ALIGN_S` after it moved sends them nowhere:
    every dotted name of ours quoted in code on the pages a user reads still exists."""
    root = README.parent
    pages = [README, root / "CHANGELOG.md", root / "BENCHMARKS.md", *sorted((root / "docs").glob("*.md"))]
    quoted = {
        (page.name, m.group(1))
        for page in pages
        for m in re.finditer(r"`((?:calib|seqdesign|viz)(?:\.[A-Za-z_]\w*)+)", page.read_text())
    }
    assert sorted(q for q in quoted if not _resolves(q[1])) == []


def test_every_command_the_readme_names_exists():
    """Runnable and template lines alike: unmarked lines name only commands and options that exist."""
    lines = [c for b in blocks() if b.lang in ("sh", "text") for c in commands(b)]
    assert len(lines) >= 15
    for cmd in lines:
        if cmd.needs is None:
            assert missing(cmd) == [], f"README: {cmd.line}: no such command or option"


@pytest.mark.slow
def test_the_five_jobs_run_as_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    ran, skipped = 0, []
    for block in blocks():
        if block.lang == "toml":
            first, _, _ = block.text.partition("\n")
            name = first.removeprefix("# file:").strip()
            assert first.startswith("# file:") and name, f"a toml block names its file: {first}"
            Path(name).write_text(block.text)
        elif block.lang == "python":
            exec(compile(block.text, "README.md (python block)", "exec"), {})
        elif block.lang == "sh":
            for cmd in commands(block):
                if cmd.needs is not None and missing(cmd):
                    skipped.append(cmd.line)
                    continue
                result = runner.invoke(main, list(cmd.args))
                assert result.exit_code == 0, f"{cmd.line}\n{result.output}"
                ran += 1
    assert ran >= 15, skipped
    # What the jobs leave behind: a design, its gimbal schedule, results, recordings.
    for name in ("myimu.toml", "mine.toml", "mine-commands.csv", "run.result.toml", "run2.result.toml"):
        assert Path(name).is_file(), name
    for name in ("run.rrd", "mine-analysis.rrd"):
        assert Path(name).stat().st_size > 0, name
