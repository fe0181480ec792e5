"""``seqdesign simulate --by-hand``: a calibration run placed by hand on a table (calib.hand.simulate)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from calib.errors import CalibError

from .handtroubles import TROUBLE_DEFAULTS, trouble_spec
from .tools import emit_json, provenance

HAND_RATE_HZ = 100.0  # the rate of the hand-placed recordings (imu_tk's Xsens, imucal's)


def by_hand_refusals(sequence, given: dict) -> None:
    """What ``--by-hand`` cannot combine with: a sequence, and the gimbal run's options."""
    if sequence is not None:
        raise CalibError(
            f"a sequence ({sequence}) and --by-hand both given",
            "--by-hand",
            "a run placed by hand follows no sequence: drop SEQUENCE, or drop --by-hand",
        )
    if names := [name for name, value in given.items() if value]:
        raise CalibError(
            f"{', '.join(names)} cannot be used with --by-hand",
            "--by-hand",
            "drop " + ", ".join(names) + " (they describe a gimbal run)",
        )


def _errors(errors_file, table2, random_errors, rng):
    """The injected errors: a file's, the paper's Table 2, drawn for a grade, or none."""
    from calib.hand.simulate import draw_errors
    from calib.model.error_model import ErrorModel
    from calib.sim.truth import read_errors

    if sum(bool(x) for x in (errors_file, table2, random_errors)) > 1:
        raise CalibError("more than one of --errors, --table2, --random-errors given", None, "choose one")
    if errors_file:
        return read_errors(errors_file)
    if table2:
        return ErrorModel.from_table2()
    if random_errors:
        from seqdesign.verify import error_half_range

        return draw_errors(error_half_range(random_errors), rng)
    return ErrorModel.zero()


def simulate_by_hand(output, profile, injected, seed, site, noise_free, as_json, hand) -> None:
    """Simulate a run placed by hand and write the run log and its truth file (with the plan).

    ``injected`` is ``(errors_file, table2)`` (``--errors``, ``--table2``) as given; ``site``
    ``(latitude, height, gravity_mps2, sample_rate_hz)``; ``hand`` the ``--by-hand`` options by
    name (the troubles' of :mod:`seqdesign.cli.handtroubles` too).
    """
    errors_file, table2 = injected
    latitude, height, gravity_mps2, sample_rate_hz = site
    from calib.hand.plan import HAND_PLAN, HAND_POSES, random_hand_plan, xsens_like_plan
    from calib.hand.simulate import HandStreams, simulate_by_hand as run_simulation, write_hand_run
    from calib.nav import earth
    from calib.noise.profiles import load_profile
    from calib.sequence.definition import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG
    from calib.sequence.kinematics import SimConfig

    if Path(output).suffix.lower() not in (".csv", ".npz"):
        raise CalibError(
            f"unknown run format {Path(output).suffix!r}", "-o/--output", "name the file .csv or .npz"
        )
    if hand["poses"] is not None and hand["like"]:
        raise CalibError("--poses and --like both given", "--poses", "choose one")
    if hand["like"] and (
        names := [f"--{k.replace('_', '-')}" for k in ("rest_s", "first_rest_s") if hand[k]]
    ):
        raise CalibError(
            f"{', '.join(names)} and --like both given", names[0], "--like fixes the rests: choose one"
        )
    if hand["rest_s"] and hand["rest_s"][0] > hand["rest_s"][1]:
        raise CalibError(f"--rest-s {hand['rest_s'][0]:g} {hand['rest_s'][1]:g}: MIN above MAX", "--rest-s")
    spec = trouble_spec({k: hand[k] for k in TROUBLE_DEFAULTS})
    if spec.stamps == "epoch-ms" and Path(output).suffix.lower() != ".csv":
        raise CalibError(
            "--stamps epoch-ms writes integer milliseconds, which an .npz run log does not hold",
            "--stamps",
            "name the output .csv, or drop --stamps epoch-ms",
        )
    lat = latitude if latitude is not None else DEFAULT_LATITUDE_DEG
    h = height if height is not None else DEFAULT_HEIGHT_M
    earth.check_site(lat, h)
    source = click.get_current_context().get_parameter_source("sample_rate_hz")
    if source is click.core.ParameterSource.DEFAULT:
        sample_rate_hz = HAND_RATE_HZ
    prof = load_profile(profile)
    # The plan, the errors, the noise, the troubles (spawn(4)[:3] is spawn(3): runs without troubles
    # are the same with and without this fourth stream).
    streams = np.random.SeedSequence(seed).spawn(4)
    plan_rng, errors_rng, noise_rng, trouble_rng = (np.random.default_rng(s) for s in streams)
    given = ("translation_m", "wobble_deg", "peak_rate_dps", "rest_s", "first_rest_s")
    shape = replace(HAND_PLAN, **{k: hand[k] for k in given if hand[k] is not None})
    if hand["like"] == "xsens":
        plan = xsens_like_plan(plan_rng, shape)
    else:
        n_poses = hand["poses"] if hand["poses"] is not None else HAND_POSES
        plan = random_hand_plan(n_poses, plan_rng, shape)
    errors = _errors(errors_file, table2, hand["random_errors"], errors_rng)
    troubles = spec.draw(plan, trouble_rng)
    cfg = SimConfig(
        latitude_rad=math.radians(lat), height_m=h, sample_rate_hz=sample_rate_hz, gravity_mps2=gravity_mps2
    )
    run, truth = run_simulation(
        plan,
        cfg,
        errors,
        None if noise_free else prof,
        seed=seed,
        oversample=hand["oversample"],
        troubles=troubles,
        streams=HandStreams(noise_rng, trouble_rng),
    )
    files = {"errors": errors_file, "profile": profile if Path(profile).exists() else None}
    prov = provenance(files, motion="by-hand", profile=prof.name)
    run.meta.update({k: prov[k] for k in ("tool_version", "command")} | {"profile": prof.name})
    truth_path = write_hand_run(output, run, truth, prov)
    peak = float(np.degrees(plan.peak_rate_rad_s.max())) if plan.n_poses > 1 else 0.0
    summary = {
        "run": str(output),
        "truth": str(truth_path),
        "motion": "by-hand",
        "poses": plan.n_poses,
        "samples": int(run.time_s.size),
        "duration_s": run.n_samples / sample_rate_hz,  # as the log says: its samples at the nominal rate
        "sample_rate_hz": sample_rate_hz,
        "peak_rate_dps": peak,
        "profile": prof.name,
        "noise": not noise_free,
        "latitude_deg": lat,
        "height_m": h,
    }
    if troubles.any:
        summary["troubles"] = _troubles_summary(troubles)
    if as_json:
        emit_json(summary)
        return
    click.echo(
        f"wrote {output} ({plan.n_poses} poses placed by hand, {summary['samples']} samples, "
        f"{summary['duration_s']:.1f} s, peak {peak:.0f} deg/s, "
        f"{'noise-free' if noise_free else 'profile ' + prof.name}"
        + (f"; {', '.join(summary['troubles'])}" if troubles.any else "")
        + f") and {truth_path}"
    )


def _troubles_summary(troubles) -> list[str]:
    """The troubles of a simulated run in words, for its summary line."""
    out = []
    if troubles.tremor is not None:
        deg = float(np.degrees(troubles.tremor.rms_angle_rad().mean())) if len(troubles.tremor.rest) else 0.0
        n = len(troubles.tremor.rest)
        out.append(f"{n} pose{'s' if n != 1 else ''} held in the hand ({deg:.2g} deg RMS tremor)")
    if troubles.g_sensitivity is not None:
        out.append(f"g-sensitivity up to {np.abs(troubles.g_sensitivity_dphg).max():.3g} deg/h/g")
    if troubles.rate_error:
        out.append(f"sample rate {troubles.rate_error:+.3%} off")
    if troubles.stamp_jitter_s:
        out.append(f"host stamps up to {1000 * troubles.stamp_jitter_s:g} ms late")
    if troubles.stamps != "seconds":
        out.append(f"stamps in {troubles.stamps}")
    return out
