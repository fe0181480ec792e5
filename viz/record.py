"""Rerun recordings (``.rrd``) of a calibration run and of a sequence analysis.

Two entry points, both pure (they read nothing but their arguments and write
only ``path``, atomically):

* :func:`record_run` -- one run log: the gimbal and IMU turning in 3D, the raw
  sensor signals, the navigation velocity errors before and after calibration,
  the attitude, the sequence's positions and flips, and the calibration result
  against its requirements (and against the truth of a simulated run).
* :func:`record_analysis` -- the observability analysis of a sequence: the
  correlation matrix as a heat map, 3 sigma / requirement bars, and the rest
  attitudes in 3D (animated over the sequence's nominal time line and as a
  static gallery of the positions).

Everything temporal is on the timeline ``time`` (a duration, seconds since
the run's first sample starts, ``time_s - (time_s[0] - (time_s[1] - time_s[0]))``,
the estimator's start instant),
written with explicit time columns through ``send_columns``. Nothing is
logged with per-sample ``log`` calls, so no wall-clock or tick timeline is
added and the recording's content depends only on the inputs (its row ids,
which rerun draws from the clock, differ from file to file).

Entity paths (run recording)::

    about                                   TextDocument: sources, units, decimation
    events                                  TextLog: "position k ..." at every rest start,
                                            "flip k ..." at every flip start (wrapped rows)
    world                                   ViewCoordinates RIGHT_HAND_Z_UP (x east, y north, z up)
    world/enu                               Arrows3D E, N, U (static)
    world/gravity                           Arrows3D: gravity (down), labelled with g in m/s^2
    world/label                             Points3D whose label is the current position / flip
    world/base                              Transform3D: the base mounting rotation R_mount (static);
                                            base plate and stand
    world/base/gimbal                       Transform3D: C_start (static)
    world/base/gimbal/outer                 Transform3D R_Z(outer) over time; outer ring
    world/base/gimbal/outer/middle          Transform3D R_X(middle) over time; middle ring
    world/base/gimbal/outer/middle/inner    Transform3D R_Y(inner) over time; inner ring
    world/base/gimbal/outer/middle/inner/imu       Boxes3D: the IMU
    world/base/gimbal/outer/middle/inner/imu/axes  Arrows3D: body X, Y, Z
    signals/gyro_dps                        Scalars x, y, z: dtheta/dt, deg/s (block means)
    signals/accel_mps2                      Scalars x, y, z: dv/dt, m/s^2 (block means)
    residuals/before/velocity_mps           Scalars E, N, U: navigation velocity (= error) of the raw
                                            increments from the coarse alignment, every sample
    residuals/after/velocity_mps            Scalars E, N, U: the same after compensating with the
                                            result, from its initial attitude, every sample
    residuals/after/noise_3sigma_mps        Scalars +3σ E, N, U, -3σ E, N, U: what the line above
                                            should stay inside if the calibration is right: the
                                            predicted noise envelope (calib.fit.replay.velocity_noise_sigma,
                                            the result's profile), on the fit's grid (1 s at rest,
                                            0.1 s turning)
    attitude/gimbal_deg                     Scalars outer, middle, inner (the scene's angles)
    attitude/nav_minus_gimbal_arcsec        Scalars E, N, U: rotation vector of C_nav C_scene^T
                                            (calibrated navigation vs the scene; needs a result)
    sequence/position                       Scalars: rest position number, 0 while turning
    results/ratio                           BarChart: 3 sigma / requirement, parameters in spec order;
                                            and LineStrips2D: the same as labelled horizontal bars
                                            (row i = parameter i, labels = names), with
      .../names, .../values                 Points2D whose labels are the names / the values,
      .../guide                             LineStrips2D at 0 and at the value 1, Points2D naming it
    results/error_over_requirement          the same for |estimate - truth| / requirement (with truth)
    results/error_over_sigma                the same for (estimate - truth) / sigma (with truth)
    results/correlation                     Tensor 21 x 21 (when the result carries it), with
      .../image                             Image 21 x 21 RGB, pixel (row i, column j); blue -1, red +1
      .../rows, .../columns                 Points2D labelled with the names, left of / above the image
      .../cells                             Points2D at every pixel, hidden labels "a / b: rho"
    results/table                           TextDocument: every parameter, value, sigma, ratio, truth

The IMU's attitude in the scene is ``R_mount C_start R_Z(outer) R_X(middle)
R_Y(inner)`` (conventions.md) with the transforms composed along the entity
path; the gimbal angles come from the run's encoder columns when it has
them, else from the sequence's nominal attitude (decomposed and unwrapped),
else from the navigation attitude.

Entity paths (analysis recording): ``about``, ``events``, the same ``world/...``
scene over the sequence's nominal time line, ``positions/p<k>`` (Transform3D
placing the IMU of rest position k in a 3 x 3 gallery with its attitude;
Boxes3D, ``positions/p<k>/axes`` Arrows3D), ``analysis/ratio``,
``analysis/sigma_over_requirement`` (BarCharts with labelled 2D bars, as
``results/ratio``), ``analysis/correlation`` (Tensor, 21 x 21, with the
labelled image of ``results/correlation``) and ``analysis/table`` (TextDocument).

Readable as it opens: BarChart and Tensor views show no category names, so
the views of the bars and of the matrix are 2D views of the labelled
drawings (the BarChart and Tensor stay, for programs). TextLog rows are
wrapped at ``EVENT_WIDTH`` characters (continuation rows indented) and the
events view shows only time and message, so nothing is cut at 1920 px.

The pieces: :mod:`viz.rrd` (the file: atomic writing, reading back),
:mod:`viz.events` (positions and flips), :mod:`viz.scene` (the 3D gimbal),
:mod:`viz.charts` (labelled bars and matrix), :mod:`viz.blueprint` (the
layouts), :mod:`viz.run` (raw signals, where the attitudes come from),
:mod:`viz.fit` (residuals and estimates), :mod:`viz.analysis` (the
analysis table and gallery); this module puts them together.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from calib.gimbal.encoders import rest_positions
from calib.nav import earth
from calib.nav.transform import rotvec_to_dcm
from calib.sequence.definition import nominal_attitude, timeline

from .analysis import about_analysis, analysis_figures, analysis_table, log_gallery, nominal_scene_times
from .blueprint import analysis_blueprint, run_blueprint
from .charts import labelled_bars, labelled_matrix
from .events import motion_events, sequence_events
from .fit import log_residuals, log_results
from .rrd import Summary, Writer, recording_id
from .run import RunContext, about_run, log_attitude_error, log_signals, scene_frames
from .scene import gimbal_from_attitudes, gimbal_matrix, log_scene, scene_indices


def record_run(
    run, path: str | os.PathLike, review, sequence=None, result=None, truth=None, *, name: str | None = None
) -> Summary:
    """Write a rerun recording of one run log (see the module docstring for its entities).

    Parameters
    ----------
    run : calib.runlog.Run
        The log.
    path : str or os.PathLike
        The ``.rrd`` to write (atomically: complete or untouched).
    review : calib.fit.replay.RunReview
        Its motion and navigations (:func:`calib.fit.replay.review_run`): viz
        only logs what it is given.
    sequence : calib.sequence.definition.Sequence, optional
        The sequence the run followed: names the positions and flips, and
        gives the gimbal angles when the run has no encoder columns.
    result : calib.calibration.result.CalibrationResult, optional
        Adds the results bars (the review carries its navigation).
    truth : calib.sim.gimbal_run.Truth, optional
        Adds the errors against the truth; its mounting rotation places the base.
    name : str, optional
        Recording name (default: the run's source).

    Returns
    -------
    Summary
        Entities and row counts, notes, where the scene came from.
    """
    n = run.n_samples
    g, dt = review.gravity_mps2, review.dt
    t_rel = run.time_s - review.t0
    dtheta, dv = run.dtheta_rad, run.dv_mps
    rid = recording_id(
        run.time_s[:: max(1, n // 1000)],
        dtheta,
        dv,
        None if result is None else result.values,
        None if sequence is None else sequence.name,
    )
    w = Writer(path, rid, name or Path(run.source).name, run_blueprint(float(t_rel[-1]), result is not None))
    try:
        for note in review.notes:
            w.note(note)
        moving, nav_before, nav_after = review.moving, review.before, review.after
        log_residuals(w, t_rel, review)

        block = log_signals(w, run, t_rel, dt)

        # Events: the sequence's nominal time line, else the gyros.
        events = (
            sequence_events(sequence) if sequence is not None else motion_events(t_rel, dt, dtheta, moving)
        )

        # The scene: gimbal angles from encoders, else the sequence, else navigation.
        keep = scene_indices(t_rel, dtheta)
        t_scene = t_rel[keep]
        nav_best = nav_after if nav_after is not None else nav_before
        context = RunContext(sequence, result, truth)
        angles, C_start, R_mount, scene_source, mount_source = scene_frames(
            run, keep, t_scene, context, nav_best, nav_after is not None, w
        )
        log_scene(w, t_scene, angles, R_mount, C_start, g, events)
        if nav_after is not None and scene_source.startswith(("encoders", "sequence")):
            C_scene = R_mount @ C_start @ gimbal_matrix(angles)
            log_attitude_error(w, t_scene, nav_after.C_b_n[keep + 1], C_scene)
        if result is not None:
            log_results(w, result, truth)
        w.summary.scene_source, w.summary.mount_source = scene_source, mount_source
        w.static(
            "about",
            w.rr.TextDocument(
                about_run(run, review, t_rel, block, len(keep), context, w.summary),
                media_type="text/markdown",
            ),
        )
    except BaseException:
        w.abort()
        raise
    return w.commit()


def record_analysis(
    analysis, path: str | os.PathLike, *, gravity_mps2: float | None = None, name: str | None = None
) -> Summary:
    """Write a rerun recording of a sequence's observability analysis.

    Parameters
    ----------
    analysis : seqdesign.analysis.Analysis
        What ``seqdesign analyze`` prints: the recording shows its figures
        (each parameter's worst over the mounting box, against its own
        requirements) and draws its worst mounting.
    path : str or os.PathLike
        The ``.rrd`` to write (atomically).
    gravity_mps2 : float, optional
        Only labels the gravity arrow (default: WGS-84 at the sequence's site or 40 deg).
    name : str, optional
        Recording name (default ``analysis of <sequence>``).

    Returns
    -------
    Summary
    """
    fig = analysis_figures(analysis)
    seq, drawn = fig.sequence, fig.drawn
    rid = recording_id(
        "analysis", seq.name, drawn.information, drawn.setup_rotvec, fig.sigma, fig.requirement
    )
    blueprint = analysis_blueprint(seq.duration_s, fig.over, fig.drawn_name)
    w = Writer(path, rid, name or f"analysis of {seq.name}", blueprint)
    try:
        rr = w.rr
        lat = math.radians(seq.latitude_deg if seq.latitude_deg is not None else 40.0)
        g = (
            gravity_mps2
            if gravity_mps2 is not None
            else earth.gravity(lat, seq.height_m if seq.height_m is not None else 0.0)
        )
        tl = timeline(seq)
        t_scene = nominal_scene_times(tl)
        angles = gimbal_from_attitudes(seq.C_start, nominal_attitude(tl, t_scene))
        R_mount = rotvec_to_dcm(np.asarray(drawn.setup_rotvec, dtype=float))
        events = sequence_events(seq)
        log_scene(w, t_scene, angles, R_mount, seq.C_start, g, events)

        log_gallery(w, rest_positions(seq), R_mount)

        ratio = np.where(np.isfinite(fig.ratio), fig.ratio, np.nan)
        labelled_bars(w, "analysis/ratio", ratio, (90, 170, 230), "1 = requirement")
        labelled_bars(
            w,
            "analysis/sigma_over_requirement",
            np.where(np.isfinite(fig.sigma), fig.sigma, np.nan) / fig.requirement,
            (120, 200, 120),
            "1 = requirement",
        )
        if drawn.covariance is not None:
            labelled_matrix(w, "analysis/correlation", drawn.correlation)
        else:
            w.note("rank deficient: no covariance, no correlation matrix")
        w.static("analysis/table", rr.TextDocument(analysis_table(fig), media_type="text/markdown"))
        w.summary.scene_source = f"sequence {seq.name!r} (nominal attitude, decomposed)"
        w.summary.mount_source = fig.mounting
        w.static(
            "about",
            rr.TextDocument(about_analysis(fig, len(t_scene), w.summary.notes), media_type="text/markdown"),
        )
    except BaseException:
        w.abort()
        raise
    return w.commit()
