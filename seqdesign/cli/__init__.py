"""The ``seqdesign`` command line: the group and its commands, one module each.

show, simulate (and simulate-stream), calibrate, correct, score, analyze and compare, design,
export (gimbal schedules), profile fit, view. Options shared by several commands
are declared once (:mod:`seqdesign.cli.options`), as are the refusal and JSON
helpers (:mod:`seqdesign.cli.tools`).

Every command refuses bad input with one line on stderr naming what, where
and how to fix it, and exits non-zero without a traceback. ``--json`` puts a
single JSON document on stdout; progress and logs go to stderr.
"""

from __future__ import annotations

from seqdesign import blas  # noqa: F401  first: one BLAS thread before numpy loads

# isort: split
import click

from seqdesign.provenance import tool_version

from . import analyze, calibrate, correct, design, gimbal, profile, score, show, simulate, verify, view
from .tools import emit_json


class _Group(click.Group):
    """The command group; a usage error (a bad option value) also honours ``--json``."""

    def invoke(self, ctx):
        raw = list(ctx.args)  # the group empties it before parsing the command's options
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            if "--json" in raw:
                where = exc.ctx.command_path if exc.ctx else "seqdesign"
                emit_json(
                    {"error": {"what": exc.format_message(), "where": where, "fix": f"see '{where} --help'"}}
                )
            raise


@click.group(name="seqdesign", cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(tool_version(), prog_name="seqdesign")
def main():
    """Self-calibration of a three-axis hybrid INS: design, analyse, simulate,
    calibrate and view multi-position sequences (21 IMU error parameters).
    """


for _command in (
    show.show,
    simulate.simulate,
    calibrate.calibrate,
    correct.correct,
    score.score,
    analyze.analyze,
    analyze.compare,
    design.design,
    gimbal.export,
    profile.profile,
    view.view,
    verify.verify,
    simulate.simulate_stream,
    calibrate.calibrate_stream,
):
    main.add_command(_command)


if __name__ == "__main__":
    main()
