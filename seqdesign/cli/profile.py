"""``seqdesign profile fit``: a noise profile from your IMU's own static log."""

from __future__ import annotations

import time
from pathlib import Path

import click

from . import options
from .tools import command_line, emit_json, guarded, info, provenance


@click.group(short_help="Noise profiles from your IMU's own data.")
def profile():
    """Noise profiles from your IMU's own data (docs/profiles.md)."""


def _plot_path(output: str, plot: str | None) -> Path:
    out = Path(output)
    return Path(plot) if plot else out.with_name(out.stem + ".allan.png")


@profile.command("fit", short_help="Fit a static log's noise terms per axis and write a profile.")
@click.argument("log", type=click.Path(dir_okay=False))
@options.latitude("Site latitude, deg (when the log lacks it).")
@options.height(
    "Site height, m (when the log lacks it; default 0, which moves only the "
    "accelerometer bias along the vertical, by 0.31 ug per m)."
)
@options.columns
@click.option("-o", "--output", required=True, help="Profile TOML to write.")
@click.option("--name", help="Profile name (default: the output's stem).")
@click.option("--plot", help="Allan deviation PNG (default: OUTPUT with .allan.png).")
@click.option("--no-plot", is_flag=True, help="Draw no PNG.")
@options.as_json
@guarded
# over 8 parameters: a click command, whose options arrive one parameter each
def fit(log, latitude, height, columns, output, name, plot, no_plot, as_json):
    """Fit the noise of a static LOG (CSV, CSV.GZ, NPZ or PSINS .imu; docs/logs-columns.md) and
    write a profile the other commands accept (--profile OUTPUT).

    Per axis: the terms its Allan deviation shows (ARW/VRW, quantisation, Gauss-Markov biases,
    rate random walk, a sinusoid) and how well they follow it (fit/measured over the fitted
    range). The profile carries white noise and one GM; what it cannot carry is named
    (docs/profiles.md).
    """
    from calib.allan.profile_fit import METHOD, FittedProfile, fit_profile, profile_doc, read_static_log
    from calib.errors import CalibError

    if not output.lower().endswith(".toml"):
        raise CalibError("the profile must be a .toml file", output, "name it e.g. myimu.toml")
    start = time.perf_counter()
    run, assumed = read_static_log(log, latitude, height, columns=columns)
    if assumed:
        info("the log gives no height and --height is not given: using 0 m")
    result = fit_profile(run, name or Path(output).stem)
    # command_line() knows the subcommand, not its group: put "profile" back.
    command = "seqdesign profile " + command_line().removeprefix("seqdesign ")
    fitted = FittedProfile(
        result, profile_doc(result, provenance({"log": log}, method=METHOD, command=command))
    )
    png = None if no_plot else _plot_path(output, plot)
    fitted.save(output, png)
    seconds = time.perf_counter() - start
    if as_json:
        emit_json(
            {**fitted.to_json(), "output": output, "plot": str(png) if png else None, "seconds": seconds}
        )
        return
    click.echo(fitted.to_text())
    info(f"wrote {output}" + (f" and {png}" if png else "") + f" in {seconds:.1f} s")
