"""``seqdesign analyze`` and ``compare``: predicted sigma and separability of sequences."""

from __future__ import annotations

from pathlib import Path

import click

from calib.errors import CalibError

from . import options
from .tools import emit_json, guarded, info, rerun_command, say_filled

TOLERANCE = click.FloatRange(0.0, 10.0)


@click.command(short_help="Predict sigma and separability of the 21 parameters for a sequence.")
@click.argument("sequence")
@options.profile()
@options.latitude()
@options.tolerance()
@options.requirements
@click.option(
    "--view",
    "view_path",
    is_flag=False,
    flag_value="",
    default=None,
    metavar="[FILE.rrd]",
    help="Also write a rerun recording (default: <sequence>-analysis.rrd).",
)
@options.with_terms(
    "Also fit a real unit's terms beyond the 21 (lever-arm, k2, time-offset, "
    "comma-separated, or all): sigma of each of the 21 with and without them, "
    "and whether the sequence observes them."
)
@click.option(
    "--by-hand",
    is_flag=True,
    help="SEQUENCE is a pose list for a run placed by hand (docs/by-hand.md): the sigmas its "
    "recording will give, the worst over --placement-deg, and the face that helps most.",
)
@click.option(
    "--placement-deg",
    type=click.FloatRange(0.0, 45.0),
    default=15.0,
    show_default=True,
    help="--by-hand: each pose is placed within this of where it was meant (each axis).",
)
@click.option(
    "--placements",
    type=click.IntRange(0, 1000),
    default=10,
    show_default=True,
    help="--by-hand: perturbed placements drawn for the worst case (0: as planned only).",
)
@options.height("--by-hand LOG: site height, m, for a logger's file that does not carry it.")
@options.gravity("--by-hand LOG: surveyed site gravity, m/s^2.")
@options.fill_gaps
@options.log_reading
@options.as_json
@guarded
# over 8 parameters: a click command, whose options arrive one parameter each
def analyze(
    sequence,
    profile,
    latitude,
    tolerance_deg,
    requirements,
    view_path,
    with_terms,
    by_hand,
    placement_deg,
    placements,
    height,
    gravity_mps2,
    allow_gaps,
    reading,
    as_json,
):
    """Fisher information of SEQUENCE under a noise profile: predicted sigma of
    each parameter against its requirement (3 sigma / requirement), which
    parameters are estimable, correlated pairs, unobservable directions,
    worst case over the +-tolerance mounting box.
    """
    if by_hand:
        site = dict(latitude_deg=latitude, height_m=height, gravity_mps2=gravity_mps2, allow_gaps=allow_gaps)
        from seqdesign.hand.prediction import Placement

        placement = Placement(placement_deg, placements)
        hand = _analyze_by_hand(
            sequence, profile, requirements, with_terms, placement, view_path, reading, site
        )
        if as_json:
            emit_json(hand.to_json())
            return
        click.echo(hand.to_text())
        return
    from calib.model.requirements import default_for
    from calib.noise.profiles import load_profile
    from seqdesign.analysis import analyze as run_analysis

    if view_path and Path(view_path).suffix != ".rrd":
        raise CalibError(f"recording {view_path!r} must end in .rrd", "--view")
    prof = load_profile(profile)
    requirements, chosen = default_for(prof, requirements)  # the profile's grade, when not given
    if chosen:
        info(chosen)
    result = run_analysis(
        sequence,
        prof,
        latitude_deg=latitude,
        tolerance_deg=tolerance_deg,
        extras=with_terms,
        requirements=requirements,
    )
    doc = result.to_json()
    if view_path is not None:
        from viz.record import record_analysis

        path = view_path or f"{result.sequence.name}-analysis.rrd"
        record_analysis(result, path)
        doc["recording"] = str(path)
        info(f"wrote {path} (open it with: {rerun_command()} {path})")
    if as_json:
        emit_json(doc)
        return
    click.echo(result.to_text())
    ctx = click.get_current_context()
    defaults = all(
        ctx.get_parameter_source(k) is click.core.ParameterSource.DEFAULT for k in ("profile", "requirements")
    )
    if defaults and any(e["ratio"] > 1.0 for e in doc["parameters"].values()):
        # The paper's own sequence misses under the defaults: say they are defaults, not the user's unit.
        click.echo(
            "these are the defaults, the paper's navigation-grade requirements under the navigation "
            "profile, not your unit's: give its --profile (its grade sets the requirements) or --requirements"
        )


def _analyze_by_hand(path, profile, requirements, with_terms, placement, view_path, reading, site):
    """``analyze --by-hand POSES`` (or a recorded LOG): the prediction of :mod:`seqdesign.hand.prediction`.

    ``placement`` a :class:`seqdesign.hand.prediction.Placement`, ``reading`` the log's reading options
    (:class:`seqdesign.cli.options.LogReading`), ``site`` its ``latitude_deg``, ``height_m`` and
    ``gravity_mps2`` as given (the latitude also the site of a pose list); returns the analysis.
    """
    from calib.hand.fit_options import HAND_REQUIREMENTS
    from calib.hand.poses import load_poses
    from calib.model.optional_terms import load_optional_terms
    from calib.model.requirements import load_requirements
    from calib.noise.profiles import load_profile
    from seqdesign.hand.prediction import analyze_hand

    if view_path is not None:
        raise CalibError(
            "--view is not recorded for a pose list", "--view", "leave out --view with --by-hand"
        )
    if not str(path).lower().endswith(".toml"):  # a recorded log: its own rests and moves
        from calib.nav.site import site_of
        from calib.runlog import read_run
        from seqdesign.hand.prediction import analyze_recording

        from .reading import run_notes

        where = {"latitude_deg": site["latitude_deg"], "height_m": site["height_m"]}
        run = read_run(path, site["allow_gaps"], **where, **reading.reader)
        say_filled(run, "before the analysis")
        gravity, notes = run_notes(run, site["gravity_mps2"])
        for note in notes:
            info(note)
        result = analyze_recording(
            run,
            site_of(run, gravity),
            load_profile(profile),
            load_requirements(requirements or HAND_REQUIREMENTS),
            load_optional_terms(with_terms, by_hand=True),
        )
    else:
        result = analyze_hand(
            load_poses(path),
            load_profile(profile),
            load_requirements(requirements or HAND_REQUIREMENTS),
            latitude_deg=45.0 if site["latitude_deg"] is None else site["latitude_deg"],
            placement=placement,
            extras=load_optional_terms(with_terms, by_hand=True),
        )
    return result


@click.command(short_help="Compare sequences side by side, or two calibrations of one unit.")
@click.argument("sequences", nargs=-1, required=True)
@options.profile()
@options.latitude("Site latitude, deg, for every sequence (default: each sequence's, else 40).")
@options.height("Site height, m, for every sequence (default: each sequence's, else 0).")
@options.tolerance()
@options.requirements
@options.as_json
@guarded
def compare(sequences, profile, latitude, height, tolerance_deg, requirements, as_json):
    """Analyse several sequences and print their 3 sigma / requirement ratios side by side.

    Given two calibration results (result TOML files) instead, put them side by
    side: each difference against the combined sigma, and a chi-square
    over all of them (the repeatability check of the paper's Table 3).
    """
    from calib.io.kinds import kind_of
    from calib.model.requirements import default_for, load_requirements
    from calib.noise.profiles import load_profile
    from seqdesign.analysis import analyze as run_analysis, compare_text, site_warnings

    kinds = {kind_of(s) for s in sequences}
    if "result" in kinds:
        if kinds != {"result"} or len(sequences) != 2:
            raise CalibError(
                "compare takes sequences, or exactly two result files",
                "compare",
                "give two results of calibrate (A B), or only sequences",
            )
        from seqdesign.repeatability import compare_results

        rep = compare_results(sequences)
        if as_json:
            emit_json(rep.to_json())
        else:
            click.echo(rep.to_text())
        return

    prof = load_profile(profile)
    requirements, chosen = default_for(prof, requirements)  # the profile's grade, when not given
    if chosen:
        info(chosen)
    req = load_requirements(requirements)
    analyses = [
        run_analysis(
            s, prof, latitude_deg=latitude, height_m=height, tolerance_deg=tolerance_deg, requirements=req
        )
        for s in sequences
    ]
    warnings = site_warnings(analyses)
    for w in warnings:
        info(f"warning: {w}")
    if as_json:  # "warnings" only when there are some (the document of one site is unchanged)
        emit_json(
            {"sequences": [a.to_json() for a in analyses]} | ({"warnings": warnings} if warnings else {})
        )
        return
    click.echo(compare_text(analyses))
