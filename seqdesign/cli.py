"""The ``seqdesign`` command line: show, simulate, calibrate, analyze, compare.

Every command refuses bad input with one line on stderr naming what, where
and how to fix it, and exits non-zero without a traceback. ``--json`` puts a
single JSON document on stdout; progress and logs go to stderr.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import click
import numpy as np

from calib.errors import CalibError

from seqdesign.clitools import emit_json, guarded, info, provenance, tool_version


@click.group(name="seqdesign", context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(tool_version(), prog_name="seqdesign")
def main():
    """Self-calibration of a three-axis hybrid INS: design, analyse, simulate,
    calibrate and view multi-position sequences (21 IMU error parameters)."""


# ---------------------------------------------------------------------------
# show


@main.command(short_help="Print a sequence's rest positions: axes, gimbal angles, times.")
@click.argument("sequence")
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def show(sequence, as_json):
    """Print where body X, Y, Z point at every rest position of SEQUENCE (a
    file or a shipped name such as paper-9pos), its gimbal angles (outer,
    middle, inner; continuous along the run) and its start and end times."""
    from calib.sequence import load_sequence, rest_positions

    seq = load_sequence(sequence)
    positions = rest_positions(seq)
    if as_json:
        emit_json({
            "sequence": seq.name, "duration_s": seq.duration_s,
            "positions": [{
                "position": p.number, "x": p.directions[0], "y": p.directions[1],
                "z": p.directions[2], "outer_deg": float(p.gimbal_deg[0]),
                "middle_deg": float(p.gimbal_deg[1]), "inner_deg": float(p.gimbal_deg[2]),
                "start_s": p.start_s, "end_s": p.end_s, "gimbal_lock": p.gimbal_lock,
                "on_grid": p.on_grid}
                for p in positions]})
        return
    click.echo(f"{seq.name}: {seq.description}".rstrip(": "))
    w = max(6, *(len(d) + 1 for p in positions for d in p.directions))  # off-grid axes are vectors
    click.echo(f"{'pos':>3}  {'X':<{w}}{'Y':<{w}}{'Z':<{w}} {'outer':>8}{'middle':>8}{'inner':>8}"
               f"  {'start s':>8}{'end s':>8}")
    for p in positions:
        lock = "  GIMBAL LOCK" if p.gimbal_lock else ""
        click.echo(f"{p.number:>3}  {p.directions[0]:<{w}}{p.directions[1]:<{w}}{p.directions[2]:<{w}}"
                   f" {p.gimbal_deg[0]:8.1f}{p.gimbal_deg[1]:8.1f}{p.gimbal_deg[2]:8.1f}"
                   f"  {p.start_s:8.1f}{p.end_s:8.1f}{lock}")
    if not all(p.on_grid for p in positions):
        click.echo("off-grid axes are shown as [east north up] components")
    click.echo(f"{len(positions)} rest positions, {len(seq.steps)} flips, "
               f"total {seq.duration_s:.1f} s ({seq.duration_s / 60:.1f} min)")


# ---------------------------------------------------------------------------
# simulate


def _site(seq, latitude, height):
    from calib.sequence import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG
    lat = latitude if latitude is not None else (
        seq.latitude_deg if seq.latitude_deg is not None else DEFAULT_LATITUDE_DEG)
    h = height if height is not None else (
        seq.height_m if seq.height_m is not None else DEFAULT_HEIGHT_M)
    if not -89.0 <= lat <= 89.0:
        raise CalibError(f"latitude {lat} deg is outside [-89, 89]", "--latitude",
                         "stationary calibration needs the Earth rate to have a horizontal part")
    if not -1000.0 <= h <= 10000.0:
        raise CalibError(f"height {h} m is outside [-1000, 10000]", "--height")
    return lat, h


def _run_suffix(path: str, option: str) -> None:
    if Path(path).suffix.lower() not in (".csv", ".npz"):
        raise CalibError(f"unknown run format {Path(path).suffix!r}", option,
                         "name the file .csv or .npz")


@main.command(short_help="Simulate a calibration run of a sequence to a run log + truth file.")
@click.argument("sequence")
@click.option("-o", "--output", required=True, help="Run log to write: .csv or .npz.")
@click.option("--profile", default="navigation", show_default=True,
              help="Noise profile: built-in name or TOML file.")
@click.option("--errors", "errors_file", type=click.Path(dir_okay=False),
              help="TOML file with an [errors] table (spec names and units).")
@click.option("--table2", is_flag=True, help="Inject the paper's Table 2 standard values.")
@click.option("--setup-deg", nargs=3, type=float, metavar="E N U",
              help="Base mounting rotation vector, degrees.")
@click.option("--random-setup", is_flag=True,
              help="Draw the mounting rotation uniformly within the +-3 deg tolerance.")
@click.option("--seed", type=int, default=None, help="Random seed (noise, setup, flip errors).")
@click.option("--latitude", type=float, help="Site latitude, deg (default: sequence, else 40).")
@click.option("--height", type=float, help="Site height, m (default: sequence, else 0).")
@click.option("--gravity", "gravity_mps2", type=float,
              help="Measured site gravity, m/s^2 (default: WGS-84 normal gravity).")
@click.option("--sample-rate-hz", type=float, default=200.0, show_default=True)
@click.option("--flip-error-deg", type=float, default=0.0, show_default=True,
              help="Each flip misses its angle by up to this much (uniform).")
@click.option("--noise-free", is_flag=True, help="No sensor noise.")
@click.option("--extra", "extra_text", metavar="NAME=VALUE,...",
              help="Terms of a real unit beyond the 21, in report units: lever arms "
                   "rxx..rzz (cm), k2x k2y k2z (ug/g^2), dt_ga (ms, accelerometers lag), "
                   "e.g. rxx=3,k2y=20,dt_ga=0.5.")
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def simulate(sequence, output, profile, errors_file, table2, setup_deg, random_setup, seed,
             latitude, height, gravity_mps2, sample_rate_hz, flip_error_deg, noise_free,
             extra_text, as_json):
    """Simulate the IMU increments of SEQUENCE on a stationary base with exact
    kinematics, the 21 errors and white noise; write the run log (-o) and its
    truth file beside it (run.truth.toml)."""
    from calib.errormodel import ErrorModel
    from calib.profiles import load_profile
    from calib.runlog import write_run
    from calib.sequence import load_sequence
    from calib.extras import parse_values
    from calib.sim import SimConfig, simulate as run_simulation
    from calib.truth import read_errors, truth_path_for, write_truth

    _run_suffix(output, "-o/--output")
    if errors_file and table2:
        raise CalibError("--errors and --table2 both given", None, "choose one")
    if setup_deg and random_setup:
        raise CalibError("--setup-deg and --random-setup both given", None, "choose one")
    if setup_deg and any(abs(a) > 10 or not math.isfinite(a) for a in setup_deg):
        raise CalibError(f"--setup-deg {setup_deg} beyond 10 deg", "--setup-deg",
                         "the mounting tolerance of the conventions is +-3 deg")
    if not (1.0 <= sample_rate_hz <= 10000.0):
        raise CalibError(f"--sample-rate-hz {sample_rate_hz} outside [1, 10000]", "--sample-rate-hz")
    if not (0.0 <= flip_error_deg <= 10.0):
        raise CalibError(f"--flip-error-deg {flip_error_deg} outside [0, 10]", "--flip-error-deg")
    if gravity_mps2 is not None and not (9.7 < gravity_mps2 < 9.9):
        raise CalibError(f"--gravity {gravity_mps2} m/s^2 is not an Earth gravity", "--gravity",
                         "give m/s^2, e.g. 9.80123")
    extra = parse_values(extra_text)
    seq = load_sequence(sequence)
    prof = load_profile(profile)
    errors = (read_errors(errors_file) if errors_file
              else ErrorModel.from_table2() if table2 else ErrorModel.zero())
    lat, h = _site(seq, latitude, height)
    cfg = SimConfig(latitude_rad=math.radians(lat), height_m=h, sample_rate_hz=sample_rate_hz,
                    gravity_mps2=gravity_mps2)
    run, truth = run_simulation(
        seq, cfg, errors, prof, setup_rotvec=np.radians(setup_deg) if setup_deg else (0, 0, 0),
        flip_error_deg=flip_error_deg, noise=not noise_free, seed=seed,
        random_setup_deg=3.0 if random_setup else None,
        extra=extra)
    truth_path = truth_path_for(output)
    prov = provenance({"sequence": sequence, "errors": errors_file,
                       "profile": profile if Path(profile).exists() else None},
                      sequence=seq.name, profile=prof.name)
    run.meta.update({"tool_version": prov["tool_version"], "command": prov["command"],
                     "sequence_sha256": prov["sequence_sha256"], "profile": prof.name})
    write_run(run, output)
    write_truth(truth_path, truth, prov)
    summary = {"run": str(output), "truth": str(truth_path), "sequence": seq.name,
               "samples": int(run.time_s.size), "duration_s": float(run.time_s[-1]),
               "profile": prof.name, "noise": not noise_free,
               "setup_deg": [float(x) for x in np.degrees(truth.setup_rotvec)],
               "latitude_deg": lat, "height_m": h}
    if as_json:
        emit_json(summary)
    else:
        click.echo(f"wrote {output} ({summary['samples']} samples, {summary['duration_s']:.1f} s, "
                   f"{'noise-free' if noise_free else 'profile ' + prof.name}) and {truth_path}")


# ---------------------------------------------------------------------------
# calibrate


@main.command(short_help="Identify the 21 parameters (value and sigma) from a run log.")
@click.argument("run_path", metavar="RUN")
@click.option("--sequence", help="Sequence file the run followed (default: detect flips from the gyros).")
@click.option("--profile", default="navigation", show_default=True,
              help="Noise profile that weights the fit and scales the sigmas.")
@click.option("-o", "--output", help="Result TOML (default: RUN with .result.toml).")
@click.option("--truth", "truth_path", type=click.Path(dir_okay=False),
              help="Truth file to compare with (default: RUN.truth.toml if it exists).")
@click.option("--allow-gaps", is_flag=True,
              help="Remove duplicated samples and fill samples dropped at rest.")
@click.option("--with", "with_terms", metavar="TERMS",
              help="Also fit a real unit's terms beyond the 21: any of lever-arm, k2, "
                   "time-offset (comma-separated), or all.")
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def calibrate(run_path, sequence, profile, output, truth_path, allow_gaps, with_terms, as_json):
    """Align, navigate on the stationary base and fit the 21 error parameters of
    RUN (CSV, NPZ or PSINS .imu) by iterated, noise-weighted least squares."""
    from calib import earth
    from calib.estimator import calibrate as fit_run, check_sequence_matches, detect_motion, \
        sequence_motion
    from calib.extras import ExtraValues, Extras, parse_groups
    from calib.profiles import load_profile
    from calib.result import CalibrationResult
    from calib.runlog import read_run
    from calib.sequence import load_sequence
    from calib.truth import read_truth, truth_path_for
    from seqdesign.report import extra_entries, format_table, parameter_entries, worst

    extras = Extras(parse_groups(with_terms))
    prof = load_profile(profile)
    run = read_run(run_path, allow_gaps=allow_gaps)
    info(run.clock.summary())  # jitter, dropped and duplicated samples (calib.clock)
    out_path = Path(output) if output else Path(run_path).with_name(Path(run_path).stem + ".result.toml")
    if truth_path is None and truth_path_for(run_path).exists():
        truth_path = truth_path_for(run_path)
    truth = read_truth(truth_path) if truth_path else None
    lat = math.radians(run.latitude_deg)
    g = run.gravity_mps2 if run.gravity_mps2 is not None else earth.gravity(lat, run.height_m)
    t = run.time_s
    dt = np.diff(np.concatenate([[t[0] - run.dt_nominal], t]))
    moving = None
    if sequence:
        seq = load_sequence(sequence)
        moving = sequence_motion(seq, t, dt)
        check_sequence_matches(seq, detect_motion(run.dtheta_rad, dt, run.source).moving,
                               moving, dt, run.source)
    info(f"calibrating {run_path}: {t.size} samples, {t[-1] - t[0] + run.dt_nominal:.1f} s, "
         f"profile {prof.name}")
    fit = fit_run(t, run.dtheta_rad, run.dv_mps, lat, g, prof, moving=moving, where=run.source,
                  extras=extras)
    if not fit.converged:
        raise CalibError(f"the fit did not converge in {fit.iterations} iterations (last step "
                         f"{fit.history[-1]['max_step_sigma']:.3g} sigma)", run.source,
                         "no result written; check the run and the noise profile")
    sigma = fit.sigma
    scale = 1.0
    if fit.chi2_per_dof > 1.2:
        # The profile understates the noise: inflate by the Birge ratio, and say so.
        scale = math.sqrt(fit.chi2_per_dof)
        sigma = sigma * scale
        info(f"warning: residuals are {fit.chi2_per_dof:.2f}x the profile's noise power; "
             f"sigmas inflated by {scale:.2f}")
    result = CalibrationResult(
        values=fit.values, sigma=sigma, C_b_n0=fit.C_b_n0, converged=fit.converged,
        iterations=fit.iterations, residual_rms_mps=fit.residual_rms_mps, profile=prof.name,
        chi2_per_dof=fit.chi2_per_dof, correlation=fit.correlation[:21, :21],
        provenance=provenance({"run": run_path, "sequence": sequence, "truth": truth_path,
                               "profile": profile if Path(profile).exists() else None},
                              sequence=sequence, profile=prof.name,
                              sigma_scale=scale if scale != 1.0 else None),
        extras=extras, extra_values=fit.extra_values, extra_sigma=fit.extra_sigma * scale)
    result.save(out_path)
    entries = parameter_entries(sigma, fit.values, truth.errors.values if truth else None)
    if extras.n:
        true_extra = None
        if truth is not None:
            true_extra = extras.pack(truth.extra if truth.extra is not None else ExtraValues())
        entries |= extra_entries(extras, fit.extra_sigma * scale, fit.extra_values, true_extra)
    if as_json:
        doc = {"parameters": entries, "worst": worst(entries), "profile": prof.name,
               "result": str(out_path),
               "fit": {"converged": fit.converged, "iterations": fit.iterations,
                       "residual_rms_mps": fit.residual_rms_mps,
                       "chi2_per_dof": fit.chi2_per_dof, "sigma_scale": scale,
                       "extras": list(extras.groups)}, "clock": run.clock.as_dict()}
        if truth is not None:
            e = (fit.values - truth.errors.values)
            doc["nees"] = float(e @ np.linalg.solve(fit.covariance[:21, :21] * scale ** 2, e))
        emit_json(doc)
        return
    click.echo(format_table(entries))
    w = worst(entries)
    click.echo(f"profile {prof.name}; converged in {fit.iterations} iterations; residual RMS "
               f"{fit.residual_rms_mps:.3g} m/s; chi2/dof {fit.chi2_per_dof:.3f}; "
               f"worst 3 sigma/requirement {w['ratio']:.2f} ({w['name']})")
    click.echo(f"wrote {out_path}")


# ---------------------------------------------------------------------------
# analyze / compare


def _analysis(sequence, profile, latitude, tolerance_deg):
    from calib import earth
    from calib.profiles import load_profile
    from calib.sequence import load_sequence
    from seqdesign.observability import accel_scale_bound, analyze_tolerance

    if not (0.0 <= tolerance_deg <= 10.0):
        raise CalibError(f"--tolerance-deg {tolerance_deg} outside [0, 10]", "--tolerance-deg")
    seq = load_sequence(sequence)
    prof = load_profile(profile)
    lat, h = _site(seq, latitude, None)
    rob = analyze_tolerance(seq, prof, math.radians(lat), h, tolerance_deg)
    bound = accel_scale_bound(seq.duration_s, prof, earth.gravity(math.radians(lat), h))
    return seq, prof, lat, rob, bound


def _analysis_doc(seq, prof, lat, rob, bound) -> dict:
    from calib import params as P
    from seqdesign.report import parameter_entries, worst

    w = rob.worst
    # Each parameter's figure is its own worst over the box (conventions.md).
    entries = parameter_entries(rob.per_parameter_worst_sigma)
    for p in P.PARAMETERS:
        entries[p.name]["ratio_nominal"] = float(rob.nominal.ratio[p.index])
    doc = {"sequence": seq.name, "duration_s": seq.duration_s, "profile": prof.name,
           "latitude_deg": lat, "tolerance_deg": rob.tolerance_deg, "setups_evaluated": rob.points,
           "ipopt_search": rob.searched,
           "parameters": entries, "worst": worst(entries),
           "worst_setup_deg": [float(x) for x in np.degrees(w.setup_rotvec)],
           "rank": w.rank, "unobservable": w.unobservable,
           "correlated_pairs": [{"a": a, "b": b, "rho": r} for a, b, r in w.correlated_pairs()],
           "criteria": w.criteria(),
           "accel_scale_bound": {"best_possible_ratio": bound,
                                 "achieved_ratio": float(max(entries[n]["ratio"]
                                                             for n in ("sax", "say", "saz")))}}
    return doc


@main.command(short_help="Predict sigma and separability of the 21 parameters for a sequence.")
@click.argument("sequence")
@click.option("--profile", default="navigation", show_default=True, help="Noise profile.")
@click.option("--latitude", type=float, help="Site latitude, deg (default: sequence, else 40).")
@click.option("--tolerance-deg", type=float, default=3.0, show_default=True,
              help="Base mounting tolerance; the figures are the worst over the box (0: nominal only).")
@click.option("--view", "view_path", is_flag=False, flag_value="", default=None, metavar="[FILE.rrd]",
              help="Also write a rerun recording (default: <sequence>-analysis.rrd).")
@click.option("--with", "with_terms", metavar="TERMS",
              help="Also fit a real unit's terms beyond the 21 (lever-arm, k2, time-offset, "
                   "comma-separated, or all): sigma of each of the 21 with and without them, "
                   "and whether the sequence observes them.")
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def analyze(sequence, profile, latitude, tolerance_deg, view_path, with_terms, as_json):
    """Fisher information of SEQUENCE under a noise profile: predicted sigma of
    each parameter against its requirement (3 sigma / requirement), correlated
    pairs, unobservable directions, worst case over the +-tolerance mounting box."""
    from calib.extras import Extras, parse_groups

    if view_path and Path(view_path).suffix != ".rrd":
        raise CalibError(f"recording {view_path!r} must end in .rrd", "--view")
    extras = Extras(parse_groups(with_terms))
    seq, prof, lat, rob, bound = _analysis(sequence, profile, latitude, tolerance_deg)
    doc = _analysis_doc(seq, prof, lat, rob, bound)
    if extras.n:
        doc["extras"] = _extras_doc(seq, prof, lat, extras, tolerance_deg)
    if view_path is not None:
        from viz.record import record_analysis
        path = view_path or f"{seq.name}-analysis.rrd"
        record_analysis(rob.worst, seq, path)
        doc["recording"] = str(path)
        info(f"wrote {path} (open it with: rerun {path})")
    if as_json:
        emit_json(doc)
        return
    from seqdesign.report import format_table
    click.echo(f"{seq.name}: {seq.duration_s:.0f} s ({seq.duration_s / 60:.1f} min), profile "
               f"{prof.name}, latitude {lat:g} deg, worst case over +-{rob.tolerance_deg:g} deg "
               f"({rob.points} mountings{' + IPOPT search' if rob.searched else ''})")
    click.echo(format_table(doc["parameters"]))
    _verdict(doc)
    if extras.n:
        _print_extras(doc["extras"])


def _extras_doc(seq, prof, lat, extras, tolerance_deg) -> dict:
    """``analyze --with``: the cost of the optional terms to each of the 21, and their sigma."""
    from calib import params as P
    from seqdesign.observability import analyze_extras

    _, h = _site(seq, lat, None)
    cost = analyze_extras(seq, prof, math.radians(lat), extras, h, tolerance_deg)
    r0, r1 = P.ratio(cost.sigma_without), P.ratio(cost.sigma_with)
    params = {p.name: {"unit": p.unit, "sigma_without": float(cost.sigma_without[p.index] / p.si_per_unit),
                       "sigma_with": float(cost.sigma_with[p.index] / p.si_per_unit),
                       "ratio_without": float(r0[p.index]), "ratio_with": float(r1[p.index]),
                       "sigma_increase": float(cost.sigma_with[p.index] / cost.sigma_without[p.index])}
              for p in P.PARAMETERS}
    extra = {p.name: {"unit": p.unit, "sigma": float(s / p.si_per_unit), "typical_size": p.scale,
                      "verdict": v, "meaning": p.meaning}
             for p, s, v in zip(extras.parameters, cost.extra_sigma, cost.verdicts())}
    w = int(np.argmax(r1))
    return {"terms": list(extras.groups), "setups_evaluated": cost.points,
            "tolerance_deg": tolerance_deg, "parameters": params, "extra_parameters": extra,
            "worst_with": {"name": P.NAMES[w], "ratio": float(r1[w])},
            "unobservable": cost.unobservable}


def _print_extras(d) -> None:
    click.echo("")
    click.echo(f"with {', '.join(d['terms'])} also fitted (worst over {d['setups_evaluated']} "
               f"mountings within +-{d['tolerance_deg']:g} deg, direct evaluation):")
    click.echo(f"{'param':<6}{'unit':<8}{'sigma w/o':>11}{'sigma with':>11}{'x':>7}"
               f"{'3s/req w/o':>11}{'3s/req with':>12}")
    for name, e in d["parameters"].items():
        click.echo(f"{name:<6}{e['unit']:<8}{e['sigma_without']:11.4g}{e['sigma_with']:11.4g}"
                   f"{e['sigma_increase']:7.2f}{e['ratio_without']:11.2f}{e['ratio_with']:12.2f}")
    click.echo(f"{'param':<6}{'unit':<8}{'sigma':>11}{'typical':>9}  verdict")
    for name, e in d["extra_parameters"].items():
        click.echo(f"{name:<6}{e['unit']:<8}{e['sigma']:11.4g}{e['typical_size']:9.4g}  {e['verdict']}")
    if d["unobservable"]:
        click.echo("UNOBSERVABLE with the extra terms: " + "; ".join(d["unobservable"]))
    worst_p = max(d["parameters"].items(), key=lambda kv: kv[1]["sigma_increase"])
    click.echo(f"Fitting them costs most on {worst_p[0]} (sigma x{worst_p[1]['sigma_increase']:.2f}); "
               f"worst ratio with them {d['worst_with']['ratio']:.2f} ({d['worst_with']['name']}). "
               "'weak': 3 sigma exceeds the typical size; 'unobservable': no information.")


def _verdict(doc) -> None:
    misses = [n for n, e in doc["parameters"].items() if e["ratio"] > 1.0]
    if doc["unobservable"]:
        click.echo("UNOBSERVABLE directions: " + "; ".join(doc["unobservable"]))
    if doc["correlated_pairs"]:
        click.echo("correlated pairs (|rho| > 0.9): " + ", ".join(
            f"{p['a']}/{p['b']} {p['rho']:+.3f}" for p in doc["correlated_pairs"]))
    b = doc["accel_scale_bound"]
    click.echo(f"accel scale-factor bound for {doc['duration_s']:.0f} s: best possible ratio "
               f"{b['best_possible_ratio']:.2f}, this sequence {b['achieved_ratio']:.2f}")
    w = doc["worst"]
    if doc["rank"] < 21:
        verdict = (f"Verdict: only {doc['rank']} of 21 parameters are observable; calibration "
                   "with this sequence cannot separate them.")
    elif not misses:
        verdict = (f"Verdict: all 21 parameters meet their requirements (worst ratio {w['ratio']:.2f}, "
                   f"{w['name']}) under profile {doc['profile']}, worst case over the mounting box.")
    else:
        verdict = (f"Verdict: {len(misses)} of 21 parameters miss their requirement ("
                   + ", ".join(misses) + f"); the worst is {w['name']} at {w['ratio']:.2f} x the "
                   f"requirement (3 sigma), under profile {doc['profile']}, worst case over the "
                   "mounting box.")
    if doc["tolerance_deg"] == 0:
        verdict = verdict.replace("worst case over the mounting box", "at the nominal mounting")
    click.echo(verdict)


@main.command(short_help="Compare sequences side by side: time, worst ratio, per-parameter ratios.")
@click.argument("sequences", nargs=-1, required=True)
@click.option("--profile", default="navigation", show_default=True, help="Noise profile.")
@click.option("--latitude", type=float, help="Site latitude, deg (default: each sequence's, else 40).")
@click.option("--tolerance-deg", type=float, default=3.0, show_default=True)
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def compare(sequences, profile, latitude, tolerance_deg, as_json):
    """Analyse several sequences and print their 3 sigma / requirement ratios side by side."""
    from calib import params as P

    docs = [_analysis_doc(*_analysis(s, profile, latitude, tolerance_deg)) for s in sequences]
    if as_json:
        emit_json({"sequences": docs})
        return
    names = [d["sequence"] for d in docs]
    width = max(10, *(len(n) + 2 for n in names))
    click.echo(f"{'':<12}" + "".join(f"{n:>{width}}" for n in names))
    click.echo(f"{'time min':<12}" + "".join(f"{d['duration_s'] / 60:>{width}.1f}" for d in docs))
    click.echo(f"{'worst':<12}" + "".join(
        f"{d['worst']['name'] + ' ' + format(d['worst']['ratio'], '.2f'):>{width}}" for d in docs))
    for p in P.PARAMETERS:
        click.echo(f"{p.name:<12}" + "".join(f"{d['parameters'][p.name]['ratio']:>{width}.2f}"
                                              for d in docs))
    click.echo(f"ratios are 3 sigma / requirement, worst over +-{tolerance_deg:g} deg, profile {profile}")


# ---------------------------------------------------------------------------
# design


def _write_design(result, path, args_doc) -> None:
    from calib.sequence import save_sequence
    from dataclasses import replace as _replace

    seq = _replace(result.sequence, provenance=provenance(**args_doc))
    save_sequence(seq, path)


@main.command(short_help="Search for a sequence that beats the paper's, robust to the mounting tolerance.")
@click.option("--budget-min", type=float, default=15.0, show_default=True, help="Total time budget, minutes.")
@click.option("--max-flips", type=int, default=10, show_default=True, help="Most moves (continuous turns).")
@click.option("--max-quarters", type=int, default=5, show_default=True,
              help="Longest move in quarter turns (5 = a turn and a quarter).")
@click.option("--start", default="east,up,south", show_default=True, help="Where X, Y, Z point at the start.")
@click.option("--end", default=None, help="Required final attitude (optional), e.g. \"east,up,south\".")
@click.option("--axes", default="XYZ", show_default=True, help="Body axes the gimbal may turn about.")
@click.option("--rate-dps", type=float, default=10.0, show_default=True, help="Rotation rate, deg/s.")
@click.option("--min-dwell-s", type=float, default=30.0, show_default=True)
@click.option("--max-dwell-s", type=float, default=300.0, show_default=True)
@click.option("--objective", type=click.Choice(["worst", "D", "A", "E"]), default="worst",
              show_default=True, help="worst 3 sigma/requirement, or D-, A-, E-optimal.")
@click.option("--profile", default="navigation", show_default=True, help="Noise profile.")
@click.option("--latitude", type=float, default=40.0, show_default=True, help="Site latitude, deg.")
@click.option("--tolerance-deg", type=float, default=3.0, show_default=True)
@click.option("--beam-width", type=int, default=200, show_default=True)
@click.option("--no-refine", is_flag=True, help="Keep uniform dwells (skip the IPOPT refinement).")
@click.option("-o", "--output", help="Sequence file to write (default: designed-<budget>min.toml).")
@click.option("--pareto", is_flag=True, help="Sweep budgets and print/save the time vs worst-ratio front.")
@click.option("--budgets", default="10,15,20,25,30", show_default=True,
              help="Budgets (min) of the --pareto sweep.")
@click.option("--workers", type=int, default=1, show_default=True, help="Local processes.")
@click.option("--scheduler", default=None, help="dask.distributed scheduler address.")
@click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")
@guarded
def design(budget_min, max_flips, max_quarters, start, end, axes, rate_dps, min_dwell_s,
           max_dwell_s, objective, profile, latitude, tolerance_deg, beam_width, no_refine, output,
           pareto, budgets, workers, scheduler, as_json):
    """Search flip walks on the graph of the 24 grid attitudes (beam search with
    incremental information), re-score the finalists exactly at the worst
    case of the mounting tolerance, refine the best's dwells with IPOPT, and
    write it as a sequence file with its provenance."""
    from calib import earth
    from calib.profiles import load_profile
    from seqdesign.design import Constraints, design as run_design
    from seqdesign.graph import parse_node
    from seqdesign.observability import accel_scale_bound

    prof = load_profile(profile)
    lat = math.radians(latitude)
    if not -89.0 <= latitude <= 89.0:
        raise CalibError(f"latitude {latitude} outside [-89, 89]", "--latitude")
    if not (0.0 <= tolerance_deg <= 10.0):
        raise CalibError(f"--tolerance-deg {tolerance_deg} outside [0, 10]", "--tolerance-deg")
    if workers < 1 or beam_width < 1:
        raise CalibError("--workers and --beam-width must be >= 1", "--workers/--beam-width")
    base = dict(start=parse_node(start, "--start"), end=parse_node(end, "--end") if end else None,
                max_flips=max_flips, axes=axes.upper(), max_quarters=max_quarters,
                rate_dps=rate_dps, min_dwell_s=min_dwell_s, max_dwell_s=max_dwell_s)
    if pareto:
        try:
            sweep = [float(b) for b in budgets.split(",") if b.strip()]
        except ValueError:
            raise CalibError(f"--budgets {budgets!r} is not a list of minutes", "--budgets") from None
    else:
        sweep = [budget_min]
    g = earth.gravity(lat)
    rows = []
    for b in sweep:
        c = Constraints(budget_s=b * 60.0, **base)
        info(f"designing for {b:g} min ({prof.name}, objective {objective}) ...")
        from seqdesign.design import check_constraints, design_steps
        check_constraints(c)
        with click.progressbar(length=design_steps(c, 4), label=f"{b:g} min", file=sys.stderr,
                               item_show_func=lambda m: m, show_pos=True) as bar:
            res = run_design(c, prof, lat, 0.0, objective, tolerance_deg, beam_width, keep=4,
                             refine=not no_refine,
                             name=f"designed-{b:g}min", workers=workers, scheduler=scheduler,
                             progress=lambda msg, n: bar.update(n, msg))
        bound = accel_scale_bound(res.sequence.duration_s, prof, g)
        rows.append((b, res, bound))
        default = f"designed-{b:g}min.toml"
        if pareto:  # every budget's design goes beside the front's files
            path = str(Path(output).parent / default) if output else default
        else:
            path = output or default
        _write_design(res, path, {
            "objective": objective, "profile": prof.name, "score": res.worst_ratio,
            "score_parameter": res.worst_name, "tolerance_deg": tolerance_deg,
            "latitude_deg": latitude, "budget_min": b,
            "uniform_dwell_score": res.uniform_worst_ratio,
            "candidates_evaluated": res.evaluated})
        info(f"wrote {path}")
    paper_T, paper_worst = _paper_point(prof, lat, tolerance_deg)
    doc = {"profile": prof.name, "objective": objective, "tolerance_deg": tolerance_deg,
           "designs": [{"budget_min": b, "duration_s": r.sequence.duration_s,
                        "worst": {"name": r.worst_name, "ratio": r.worst_ratio},
                        "uniform_dwell_worst_ratio": r.uniform_worst_ratio,
                        "accel_scale_bound_ratio": bound,
                        "steps": [{"axis": s.axis, "angle_deg": s.angle_deg, "dwell_s": s.dwell_s}
                                  for s in r.sequence.steps],
                        "initial_dwell_s": r.sequence.initial_dwell_s,
                        "candidates_evaluated": r.evaluated,
                        "search_seconds": r.search_seconds} for b, r, bound in rows],
           "paper_9pos": {"duration_s": paper_T, "worst_ratio": paper_worst}}
    if pareto:
        _write_pareto(doc, prof, g, output or "pareto")
    if as_json:
        emit_json(doc)
        return
    click.echo(f"{'budget':>7} {'time':>7} {'worst ratio':>16} {'uniform':>8} {'bound':>6}  moves")
    for b, r, bound in rows:
        moves_txt = " ".join(f"{s.angle_deg:+.0f}{s.axis}" for s in r.sequence.steps)
        click.echo(f"{b:6g}m {r.sequence.duration_s / 60:6.1f}m {r.worst_name:>5} {r.worst_ratio:9.3f} "
                   f"{r.uniform_worst_ratio:8.3f} {bound:6.3f}  {moves_txt}")
    click.echo(f"paper-9pos: {paper_T / 60:.1f} min, worst ratio {paper_worst:.2f}. Ratios are "
               f"3 sigma/requirement, worst over +-{tolerance_deg:g} deg, profile {prof.name}; "
               "bound = best possible for the accelerometer scale factors at that time.")


def _paper_point(prof, lat, tolerance_deg):
    from calib.sequence import load_sequence
    from seqdesign.observability import analyze_tolerance
    seq = load_sequence("paper-9pos")
    rob = analyze_tolerance(seq, prof, lat, 0.0, tolerance_deg, search=False)
    return seq.duration_s, float(rob.per_parameter_worst_ratio.max())


def _write_pareto(doc, prof, g, stem) -> None:
    """The front as CSV and as an SVG drawn against the physical bound curve."""
    from calib.fileio import atomic_write_text
    from seqdesign.observability import accel_scale_bound

    stem = str(stem).removesuffix(".toml")
    lines = ["budget_min,duration_s,worst_ratio,worst_parameter,bound_ratio"]
    for d in doc["designs"]:
        lines.append(f"{d['budget_min']},{d['duration_s']:.1f},{d['worst']['ratio']:.4f},"
                     f"{d['worst']['name']},{d['accel_scale_bound_ratio']:.4f}")
    p = doc["paper_9pos"]
    lines.append(f"paper-9pos,{p['duration_s']:.1f},{p['worst_ratio']:.4f},,"
                 f"{accel_scale_bound(p['duration_s'], prof, g):.4f}")
    atomic_write_text(stem + ".csv", "\n".join(lines) + "\n")
    # SVG: x = minutes (0..max), y = log worst ratio.
    W, H, m = 640, 400, 60
    tmax = max([d["duration_s"] for d in doc["designs"]] + [p["duration_s"]]) / 60 * 1.1
    ys = [d["worst"]["ratio"] for d in doc["designs"]] + [p["worst_ratio"], 1.0]
    lo, hi = math.log10(min(ys) * 0.8), math.log10(max(ys) * 1.3)

    def X(t):
        return m + (W - 2 * m) * t / tmax

    def Y(r):
        return H - m - (H - 2 * m) * (math.log10(r) - lo) / (hi - lo)

    curve = " ".join(f"{X(t):.1f},{Y(accel_scale_bound(t * 60, prof, g)):.1f}"
                     for t in np.linspace(max(1.0, tmax / 40), tmax, 80)
                     if lo <= math.log10(accel_scale_bound(t * 60, prof, g)) <= hi)
    pts = "".join(f'<circle cx="{X(d["duration_s"] / 60):.1f}" cy="{Y(d["worst"]["ratio"]):.1f}" r="5" '
                  f'fill="#1f77b4"><title>{d["budget_min"]} min: {d["worst"]["ratio"]:.2f}</title></circle>'
                  for d in doc["designs"])
    front = " ".join(f"{X(d['duration_s'] / 60):.1f},{Y(d['worst']['ratio']):.1f}"
                     for d in sorted(doc["designs"], key=lambda d: d["duration_s"]))
    ticks = "".join(f'<text x="{X(t):.0f}" y="{H - m + 18}" font-size="11" text-anchor="middle">{t:g}</text>'
                    for t in range(0, int(tmax) + 1, 5))
    yt = "".join(f'<text x="{m - 8}" y="{Y(r) + 4:.0f}" font-size="11" text-anchor="end">{r:g}</text>'
                 f'<line x1="{m}" x2="{W - m}" y1="{Y(r):.1f}" y2="{Y(r):.1f}" stroke="#ddd"/>'
                 for r in (0.5, 1, 1.5, 2, 3, 5, 10, 20) if lo <= math.log10(r) <= hi)
    svg = (f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif">'
           f'<rect width="{W}" height="{H}" fill="white"/>{yt}{ticks}'
           f'<line x1="{m}" y1="{H - m}" x2="{W - m}" y2="{H - m}" stroke="black"/>'
           f'<line x1="{m}" y1="{m}" x2="{m}" y2="{H - m}" stroke="black"/>'
           f'<polyline points="{curve}" fill="none" stroke="#d62728" stroke-dasharray="6,4"/>'
           f'<polyline points="{front}" fill="none" stroke="#1f77b4"/>{pts}'
           f'<rect x="{X(p["duration_s"] / 60) - 5:.1f}" y="{Y(p["worst_ratio"]) - 5:.1f}" width="10" '
           f'height="10" fill="#ff7f0e"/>'
           f'<text x="{X(p["duration_s"] / 60) + 8:.1f}" y="{Y(p["worst_ratio"]) + 4:.1f}" font-size="12">'
           f'paper-9pos</text>'
           f'<text x="{W / 2}" y="{H - 15}" font-size="13" text-anchor="middle">total time, min</text>'
           f'<text x="15" y="{H / 2}" font-size="13" transform="rotate(-90 15 {H / 2})" '
           f'text-anchor="middle">worst 3 sigma / requirement (+-{doc["tolerance_deg"]:g} deg)</text>'
           f'<text x="{W - m}" y="{m - 10}" font-size="12" text-anchor="end" fill="#d62728">'
           f'dashed: accelerometer scale-factor bound ({prof.name})</text></svg>')
    atomic_write_text(stem + ".svg", svg)
    info(f"wrote {stem}.csv and {stem}.svg")


from viz.cli import view  # noqa: E402  (its own module; registered here)

main.add_command(view)


if __name__ == "__main__":
    main()
