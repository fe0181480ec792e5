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


@profile.command("fit", short_help="Fit ARW/VRW, bias instability (GM) and RRW from a static log.")
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
def fit(log, latitude, height, columns, output, name, plot, no_plot, as_json):
    """Fit the noise of a static LOG (CSV, CSV.GZ, NPZ or PSINS .imu; docs/logs-columns.md) and
    write a profile the other commands accept (--profile OUTPUT).
    """
    from calib.errors import CalibError
    from calib.profilefit import fit_profile, per_axis_tables, plain, plot_allan, profile_doc, save_profile
    from calib.runlog import read_run

    if not output.lower().endswith(".toml"):
        raise CalibError("the profile must be a .toml file", output, "name it e.g. myimu.toml")
    start = time.perf_counter()
    run = _read(read_run, log, latitude, height, columns)
    result = fit_profile(run, name or Path(output).stem)
    # command_line() knows the subcommand, not its group: put "profile" back.
    command = "seqdesign profile " + command_line().removeprefix("seqdesign ")
    doc = profile_doc(result, provenance({"log": log}, method=_METHOD, command=command))
    png = None if no_plot else _plot_path(output, plot)
    save_profile(doc, output)
    if png is not None:
        plot_allan(result, png)
    seconds = time.perf_counter() - start
    if as_json:
        emit_json(
            plain(
                {
                    "profile": {k: v for k, v in doc.items() if k not in ("fit", "provenance")},
                    **per_axis_tables(result),
                    "site": doc["fit"]["site"],
                    "log": doc["fit"]["log"],
                    "output": output,
                    "plot": str(png) if png else None,
                    "seconds": seconds,
                }
            )
        )
        return
    _print_table(doc)
    info(f"wrote {output}" + (f" and {png}" if png else "") + f" in {seconds:.1f} s")


_METHOD = (
    "overlapping Allan deviation (allantools.oadev, 4 taus per octave, 68 % CI from "
    "edf_simple); N from the slope -1/2 region; B = floor / 0.664; GM sigma, tau and "
    "RRW by weighted least squares in log deviation with N held"
)


def _read(read_run, log, latitude, height, columns):
    """The run, with the site from the options; height 0 when neither gives it."""
    from calib.errors import CalibError

    try:
        return read_run(log, latitude_deg=latitude, height_m=height, columns=columns)
    except CalibError as exc:
        if (
            height is None
            and "'height_m'" in exc.message
            and "lacks" in exc.message
            and "'latitude_deg'" not in exc.message
        ):
            info("the log gives no height and --height is not given: using 0 m")
            return read_run(log, latitude_deg=latitude, height_m=0.0, columns=columns)
        raise


def _print_table(doc: dict) -> None:
    g, a, site = doc["fit"]["gyro"], doc["fit"]["accel"], doc["fit"]["site"]
    rows = [
        ("ARW, deg/sqrt(h)", g["arw_dph"]),
        ("  white region, s", g["white_tau_s"]),
        ("bias instability B, deg/h", g["bias_instability_dph"]),
        ("  floor at tau, s", g["floor_tau_s"]),
        ("GM sigma, deg/h", g["gm_sigma_dph"]),
        ("GM correlation, s", g["gm_correlation_s"]),
        ("RRW, deg/h/sqrt(h)", g["rrw_dph_per_sqrt_h"]),
        ("quantisation, urad", g["quantisation_urad"]),
        ("gyro bias, deg/h", g["bias_dph"]),
        ("VRW, ug/sqrt(Hz)", a["vrw_ug"]),
        ("  white region, s", a["white_tau_s"]),
        ("bias instability B, ug", a["bias_instability_ug"]),
        ("  floor at tau, s", a["floor_tau_s"]),
        ("GM sigma, ug", a["gm_sigma_ug"]),
        ("GM correlation, s", a["gm_correlation_s"]),
        ("RRW, ug/sqrt(h)", a["rrw_ug_per_sqrt_h"]),
        ("quantisation, mm/s", a["quantisation_mmps"]),
        ("accel bias, ug", a["bias_ug"]),
    ]
    click.echo(f"{'':28s}{'x':>16s}{'y':>16s}{'z':>16s}")
    for label, values in rows:
        cells = [f"{v[0]:.3g}-{v[1]:.3g}" if isinstance(v, list) else f"{v:.4g}" for v in values]
        click.echo(f"{label:28s}" + "".join(f"{c:>16s}" for c in cells))
    click.echo(
        f"profile {doc['name']}: gyro_arw_dph {doc['gyro_arw_dph']:.4g}, accel_vrw_ug "
        f"{doc['accel_vrw_ug']:.4g}, GM gyro {doc['gyro_bias_instability_dph']:.4g} deg/h "
        f"/ {doc['gyro_bias_correlation_s']:.4g} s, GM accel "
        f"{doc['accel_bias_instability_ug']:.4g} ug / {doc['accel_bias_correlation_s']:.4g} s"
        " (worst axis)"
    )
    click.echo(
        f"removed: gravity {site['gravity_removed_mps2']:.6g} m/s^2 along the measured up "
        f"{[round(float(u), 4) for u in site['up_body']]} (body), Earth rate "
        f"{site['earth_rate_removed_dph']:.3g} deg/h along it; the horizontal Earth rate "
        f"({site['earth_rate_left_in_bias_dph']:.3g} deg/h) is left in the gyro bias: "
        "a MEMS gyro cannot find north. The Allan deviations do not change; the biases do."
    )
