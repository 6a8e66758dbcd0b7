"""The recording's default layout in the viewer, made for comparing estimators.

Left: the map with every estimate (each estimator in its own colour, its name beside its current pose). Right:
position error, NEES, step time (and the smoothers' costs) side by side, one line per estimator with a legend,
above the event log. Views list their entities explicitly: an entity filter such as ``/metrics/*/nees`` selects
nothing (rerun-sdk 0.41 supports ``*`` only as a trailing ``/**``).
"""

from __future__ import annotations

import rerun.blueprint as rrb

from online_slam.sinks.recording.layout import Layout


def _series(
    layout: Layout, names: tuple[str, ...], figure: str, title: str, extra: tuple[str, ...] = ()
) -> rrb.TimeSeriesView:
    contents = [f"/{layout.metrics(n)}/{figure}" for n in names] + list(extra)
    return rrb.TimeSeriesView(origin="/metrics", contents=contents, name=title)


def blueprint(layout: Layout) -> rrb.Blueprint:
    """Map | (position error, NEES, step time, smoother cost) over the event log."""
    estimated = tuple(n for n in layout.online if n != "odometry")
    views = [
        _series(layout, estimated, "position_error_m", "position error (m)"),
        _series(
            layout,
            estimated,
            "nees",
            "pose NEES (3 = consistent), EKF NIS (2)",
            tuple(f"/{layout.metrics(n)}/nis" for n in estimated if n.startswith("ekf")),
        ),
        _series(layout, estimated, "step_ms", "step time (ms)"),
    ]
    smoothers = tuple(n for n in estimated if n.startswith("smoother"))
    if smoothers:
        views.append(_series(layout, smoothers, "cost_after", "smoother cost after each solve"))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(origin="/world", name="map"),
            rrb.Vertical(
                rrb.Grid(*views, grid_columns=2, name="figures"),
                rrb.TextLogView(origin="/events", name="events"),
                row_shares=[4, 1],
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )
