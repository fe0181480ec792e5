"""Helpers every command shares: refusals without tracebacks, JSON on stdout, provenance.

Every command module of :mod:`seqdesign.cli` uses the same ones.

"""

from __future__ import annotations

import functools
import json
import math
import os
import shlex
import shutil
import sys
import warnings
from pathlib import Path

import click

from calib.errors import CalibError
from seqdesign.provenance import call_provenance

EXIT_BAD_INPUT = 2
# No notice the tool prints is longer: a message names the first few of a long list
# (calib.runlog.clock.describe); this bound catches a warning that would not, keeping both ends.
# A refusal is printed with its file named by its name alone when the whole path would take it
# past the bound (a temporary folder's path is a hundred characters), then bounded alike;
# `--json` keeps every field whole.
MAX_MESSAGE = 400


def bounded(text: str) -> str:
    """``text`` cut in the middle to `MAX_MESSAGE` characters: what is wrong and the fix (its ends)
    stay, each cut at a space so that no word is left in part.
    """
    if len(text) <= MAX_MESSAGE:
        return text
    head = MAX_MESSAGE * 2 // 3
    tail = MAX_MESSAGE - head - 5
    first, last = text[:head], text[-tail:]
    first = first.rsplit(" ", 1)[0] if " " in first else first
    last = last.split(" ", 1)[1] if " " in last else last
    return first + " ... " + last


def refusal_line(exc: CalibError) -> str:
    """A refusal in at most `MAX_MESSAGE` characters: a long path to its file name, then `bounded`."""
    text = exc.message
    if len(text) > MAX_MESSAGE and exc.where and "/" in exc.where:
        head, sep, rest = exc.where.partition(",")
        short = CalibError(exc.what, Path(head).name + sep + rest, exc.fix)
        text = short.message
    return bounded(text)


def command_line() -> str:
    """The command as a user would retype it: subcommand and every non-default parameter."""
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return "seqdesign " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    assert ctx.info_name is not None  # click names the context of every command it invokes
    parts = ["seqdesign", ctx.info_name]
    for param in ctx.command.params:
        if ctx.get_parameter_source(param.name) is click.core.ParameterSource.DEFAULT:
            continue
        value = ctx.params.get(param.name)
        values = list(value) if isinstance(value, (tuple, list)) else [value]
        if isinstance(param, click.Argument):
            parts += [shlex.quote(str(v)) for v in values]
        elif getattr(param, "is_flag", False):
            parts.append(param.opts[0] if value else (param.secondary_opts or param.opts)[0])
        else:
            parts += [param.opts[0]] + [shlex.quote(str(v)) for v in values]
    return " ".join(parts)


def rerun_command() -> str:
    """The viewer's command as the user's shell finds it.

    ``rerun`` when it is on PATH (an activated environment); else the one
    installed beside this Python, e.g. ``.venv/bin/rerun`` (``make demo`` runs
    the tool from the venv without activating it, where plain ``rerun`` is not found).
    """
    beside = Path(sys.executable).parent / "rerun"  # not resolved: the venv's bin, not the base Python's
    on_path = shutil.which("rerun")
    if not beside.exists() or (on_path and Path(on_path).resolve() == beside.resolve()):
        return "rerun"
    try:
        return str(beside.relative_to(Path.cwd()))
    except ValueError:  # the environment is elsewhere
        return str(beside)


def provenance(inputs: dict | None = None, **extra) -> dict:
    """Tool version, the command line as typed, SHA-256 of every input file, and ``extra`` facts."""
    return call_provenance(command_line(), inputs, **extra)


def hidden_alias(command: click.Command, name: str, flag: str) -> click.Command:
    """``name``: ``command`` with its ``flag`` on, kept (hidden) for scripts that call the old name."""

    def callback(**given):
        return command.callback(**given, **{flag: True})  # the callback is guarded already

    return click.Command(
        name,
        callback=callback,
        params=[p for p in command.params if p.name != flag],
        help=f"Same as `seqdesign {command.name} --{flag}`.",
        hidden=True,
    )


def _same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether two paths name one file: the same inode when both exist (links, ``./x``), else one path."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist yet: compare the paths it would be written at
        return os.path.realpath(a) == os.path.realpath(b)


Paths = dict[str, str | os.PathLike | None]


def refuse_overwrite(outputs: Paths, inputs: Paths) -> None:
    """Refuse, before anything is read or written, an output that is one of the inputs.

    Writing the result over the raw log (``-o x.csv`` on ``x.csv``) would lose the
    only copy of the recording; two outputs at one path would lose the first.

    Parameters
    ----------
    outputs, inputs
        Option name (as the user typed it, e.g. ``"-o"``, ``"LOG"``) to path; None is not given.

    Raises
    ------
    CalibError
        Naming the option and the input it would overwrite.
    """
    # An input that is not a file is a shipped name (--profile mems), nothing to overwrite.
    given_in = [(name, path) for name, path in inputs.items() if path is not None and os.path.isfile(path)]
    given_out = [(name, path) for name, path in outputs.items() if path is not None]
    for i, (out_name, out_path) in enumerate(given_out):
        for in_name, in_path in given_in + given_out[:i]:
            if _same_file(out_path, in_path):
                raise CalibError(
                    f"{out_name} is the same file as {in_name}, which it would overwrite",
                    str(out_path),
                    f"give {out_name} another file name",
                )


def guarded(fn):
    """Turn the tool's own errors (and Ctrl-C) into a message and an exit code.

    With ``--json`` a refusal is also one JSON document on stdout,
    ``{"error": {"what", "where", "fix"}}``, so a program reading stdout
    gets a document either way. The library's warnings are printed as
    ``warning: ...`` lines on stderr.
    """

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("always")
                warnings.showwarning = _show_warning
                return fn(*args, **kwargs)
        except CalibError as exc:
            click.echo(f"error: {refusal_line(exc)}", err=True)
            if kwargs.get("as_json"):
                emit_json({"error": {"what": exc.what, "where": exc.where, "fix": exc.fix}})
            sys.exit(EXIT_BAD_INPUT)
        except KeyboardInterrupt:
            click.echo("interrupted; nothing was written", err=True)
            sys.exit(130)

    return wrapper


def _json_safe(x):
    """Non-finite numbers (an unobservable parameter's sigma) become null: JSON has no inf."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    return x


def emit_json(doc) -> None:
    """One JSON document on stdout (non-finite numbers become null)."""
    click.echo(json.dumps(_json_safe(doc), indent=2, allow_nan=False))


def info(msg: str) -> None:
    """A line on stderr (stdout is for results)."""
    click.echo(bounded(msg) if "\n" not in msg else msg, err=True)


def say_filled(run, before: str) -> None:
    """Say what the reader did with the samples the log lost at rest and repeated (``--allow-gaps``):
    filled, or, rows read at their stamps, left in the stalled row's own interval; repeats dropped.
    """
    if run.clock is None:
        return
    lost = sum(count for _, count in run.clock.dropped)
    repeated = sum(count for _, count in run.clock.duplicates)
    if lost:
        how = "left in their stalled rows' intervals" if run.clock.rule == "stamps" else "filled"
        info(f"{lost} sample(s) the log lost at rest {how} {before} (--allow-gaps)")
    if repeated:
        info(f"{repeated} repeated sample(s) dropped {before} (--allow-gaps)")


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    click.echo(bounded(f"warning: {message}"), err=True)
