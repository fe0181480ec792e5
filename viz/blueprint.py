"""The layouts a recording opens with (rerun blueprints): which views, where, named how."""

from __future__ import annotations

from calib.model import params as P

from .charts import BAR_LENGTH, COLUMN_LABEL_LEVELS, COLUMN_LABEL_STEP, LABEL_LIFT, NAME_X, VALUE_GAP
from .rrd import TIMELINE
from .scene import GALLERY_STEP


def _panels():
    """Side panels folded away (the views get the room) and the time panel on ``time``, paused."""
    import rerun.blueprint as rrb

    return [
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline=TIMELINE, play_state="paused", state="collapsed"),
    ]


def _events_view():
    """The positions and flips as text: time and message only (no entity or level columns,
    so that the message gets the view's width).
    """
    import rerun.blueprint as rrb
    from rerun.blueprint.encodings import TextLogColumn, TextLogColumnKind, TimelineColumn

    return rrb.TextLogView(
        origin="events",
        name="positions and flips",
        columns=rrb.archetypes.TextLogColumns(
            timeline_columns=[TimelineColumn(TIMELINE)],
            text_log_columns=[
                TextLogColumn(TextLogColumnKind.EntityPath, visible=False),
                TextLogColumn(TextLogColumnKind.LogLevel, visible=False),
                TextLogColumn(TextLogColumnKind.Body),
            ],
        ),
    )


def _bars_view(origin: str, name: str):
    """A 2D view of :func:`labelled_bars`: names on the left, bars to the right."""
    import rerun.blueprint as rrb

    return rrb.Spatial2DView(
        origin=origin,
        name=name,
        visual_bounds=rrb.VisualBounds2D(
            x_range=(NAME_X - 1.5, BAR_LENGTH + 2.0 * VALUE_GAP), y_range=(-1.5, P.N_PARAMS + 1.5)
        ),
    )


def _matrix_view(origin: str, name: str):
    """A 2D view of :func:`labelled_matrix`, the names around it in view."""
    import rerun.blueprint as rrb

    return rrb.Spatial2DView(
        origin=origin,
        name=name,
        visual_bounds=rrb.VisualBounds2D(
            x_range=(-3.0, P.N_PARAMS + 0.5),
            y_range=(-1.5 - LABEL_LIFT - COLUMN_LABEL_STEP * COLUMN_LABEL_LEVELS, P.N_PARAMS + 1.0),
        ),
    )


def _scene_view(origin: str, name: str):
    """A 3D view looking at the gimbal from the south-east, a little above."""
    import rerun.blueprint as rrb

    return rrb.Spatial3DView(
        origin=origin,
        name=name,
        eye_controls=rrb.EyeControls3D(
            position=(5.0, -6.5, 3.5), look_target=(0.0, 0.0, -0.4), eye_up=(0.0, 0.0, 1.0)
        ),
    )


def _whole_run(duration_s: float):
    """Time axis of a time-series view showing the whole run (not just the latest seconds)."""
    import rerun.blueprint as rrb

    return rrb.TimeAxis(
        view_range=rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seconds=0.0),
            end=rrb.TimeRangeBoundary.absolute(seconds=float(duration_s)),
        )
    )


def run_blueprint(duration_s: float, with_results: bool = True):
    """The layout a run recording opens with: 3D | signals | residuals | results."""
    import rerun.blueprint as rrb

    def plot(origin, name):
        return rrb.TimeSeriesView(origin=origin, name=name, axis_x=_whole_run(duration_s))

    scene = rrb.Vertical(_scene_view("world", "gimbal and IMU"), _events_view(), row_shares=[3, 1])
    signals = rrb.Vertical(
        plot("signals/gyro_dps", "gyro rate, deg/s"),
        plot("signals/accel_mps2", "specific force, m/s^2"),
        plot("attitude/gimbal_deg", "gimbal angles, deg"),
        plot("sequence", "rest position (0 = turning)"),
        row_shares=[3, 3, 2, 1],
    )
    residuals = rrb.Vertical(
        plot("residuals/before", "velocity error before calibration, m/s"),
        plot("residuals/after", "velocity error after calibration, m/s (pale: ±3σ of the noise)"),
        plot("attitude/nav_minus_gimbal_arcsec", "navigation - gimbal attitude, arcsec"),
    )
    columns: list[rrb.Container | rrb.View] = [scene, signals, residuals]
    if with_results:
        columns.append(
            rrb.Vertical(
                _bars_view("results/ratio", "3 sigma / requirement"),
                _bars_view("results/error_over_requirement", "|error| / requirement (truth)"),
                rrb.Tabs(
                    _matrix_view("results/correlation", "correlation (blue -1, red +1)"),
                    rrb.TextDocumentView(origin="results/table", name="result"),
                    rrb.TextDocumentView(origin="about", name="about"),
                ),
                row_shares=[3, 3, 3],
            )
        )
    else:
        columns.append(rrb.TextDocumentView(origin="about", name="about"))
    return rrb.Blueprint(rrb.Horizontal(*columns, column_shares=[3, 3, 3, 3][: len(columns)]), *_panels())


def analysis_blueprint(duration_s: float, over: str = "", drawn: str = "nominal mounting"):
    """The layout an analysis recording opens with; the views say where their figures come from
    (``over``: the ratios, e.g. each parameter's worst over the box) and which mounting they draw.
    """
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                _scene_view("world", f"sequence (nominal), {drawn}"), _events_view(), row_shares=[3, 1]
            ),
            rrb.Spatial3DView(
                origin="positions",
                name=f"rest positions, {drawn}",
                eye_controls=rrb.EyeControls3D(
                    position=(GALLERY_STEP, -GALLERY_STEP - 23.0, 34.0),
                    look_target=(GALLERY_STEP, -GALLERY_STEP, 0.0),
                    eye_up=(0.0, 0.0, 1.0),
                ),
            ),
            rrb.Vertical(
                _bars_view(
                    "analysis/ratio", f"3 sigma / requirement, {over}" if over else "3 sigma / requirement"
                ),
                _matrix_view("analysis/correlation", f"correlation at the {drawn} (blue -1, red +1)"),
            ),
            rrb.Tabs(
                rrb.TextDocumentView(origin="analysis/table", name="analysis"),
                rrb.TextDocumentView(origin="about", name="about"),
            ),
            column_shares=[3, 3, 3, 3],
        ),
        *_panels(),
    )
