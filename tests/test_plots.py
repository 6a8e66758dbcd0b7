"""The comparison figure: looks per estimator, readable log axes, nothing clipped, final errors, ellipses."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure

from online_slam.compare import CompareConfig, Comparison, compare
from online_slam.evaluation.scoring import position_errors
from online_slam.pipeline import ReplayConfig, replay
from online_slam.reports.palette import COLORS, rgb_colors
from online_slam.reports.plots import comparison_figure, log_axis, looks, plot_comparison, title


@pytest.fixture(scope="module")
def square() -> Comparison:
    return compare("square", CompareConfig(windows=(10, 20)))


@pytest.fixture(scope="module")
def figure(square: Comparison) -> Figure:
    fig = comparison_figure(square)
    fig.canvas.draw()  # lays out the figure and fills in the tick labels
    return fig


def axes(fig: Figure, label: str) -> Any:
    (found,) = [ax for ax in fig.axes if ax.get_label() == label]
    return found


def labelled_ticks(ax: Any) -> list[str]:
    """The y tick labels shown inside the axes' limits."""
    low, high = ax.get_ylim()
    return [t.get_text() for t in ax.get_yticklabels() if t.get_text() and low <= t.get_position()[1] <= high]


def same(color: Any, expected: Any) -> bool:
    return np.allclose(to_rgb(color), to_rgb(expected))


def test_every_estimator_has_its_own_colour_and_line_style() -> None:
    names = ["odometry", "ekf", "smoother W=10 K=1", "smoother W=20 K=1", "smoother W=50 K=5", "batch"]
    colors = rgb_colors(names)
    assert len(set(colors.values())) == len(names)
    assert colors["smoother W=10 K=1"] == COLORS["smoother"]  # the first smoother looks like "smoother"
    drawn = looks(names)
    assert len({(look.color, str(look.dashes)) for look in drawn.values()}) == len(names)
    assert len({str(look.dashes) for look in drawn.values()}) == len(names)  # told apart without colour too


def test_map_lines_differ_by_colour_and_style(square: Comparison, figure: Figure) -> None:
    ax, drawn = axes(figure, "map"), set()
    for name, estimate in square.results.estimates.items():
        color, path = looks(list(square.results.estimates))[name].color, estimate.poses[:, :2]
        same_path = [
            ln for ln in ax.lines if ln.get_xydata().shape == path.shape and np.allclose(ln.get_xydata(), path)
        ]
        (line,) = [ln for ln in same_path if same(ln.get_color(), color)]
        drawn.add((to_rgb(line.get_color()), line.get_linestyle(), line.get_marker()))
    assert len(drawn) == len(square.results.estimates)


def test_error_axes_are_log_with_three_labelled_ticks_and_no_zero(figure: Figure) -> None:
    for label in ("final error", "nees", "latency"):
        ax = axes(figure, label)
        assert ax.get_yscale() == "log"
        ticks = labelled_ticks(ax)
        assert len(ticks) >= 3, (label, ticks)
        assert "0" not in ticks


def test_log_axis_spans_a_decade_and_labels_it() -> None:
    fig = Figure()
    ax = fig.add_subplot()
    low, high = log_axis(ax, [np.array([0.11, 0.12, 0.14, 0.0, np.nan])])  # zero and NaN are not plotted
    fig.canvas.draw()
    assert high / low >= 10 and low <= 0.11 and high >= 0.14
    assert len(labelled_ticks(ax)) >= 3


def test_latency_axis_shows_the_slowest_step(square: Comparison, figure: Figure) -> None:
    slowest = max(float(np.nanmax(s.step_ms)) for s in square.results.series.values())
    low, high = axes(figure, "latency").get_ylim()
    assert high >= slowest and low <= min(float(np.nanmin(s.step_ms)) for s in square.results.series.values())


def test_legend_is_outside_the_map(figure: Figure) -> None:
    (legend,) = figure.legends
    box = legend.get_window_extent()
    for ax in figure.axes:
        assert not box.overlaps(ax.get_window_extent()), ax.get_label()


def test_final_error_drawn_for_every_estimator_with_the_tables_alignment(square: Comparison, figure: Figure) -> None:
    ax = axes(figure, "final error")
    r = square.results
    for name, estimate in r.estimates.items():
        error = position_errors(estimate.poses, r.truth_poses, r.alignment)
        table = r.odometry.rmse_m if name == "odometry" else r.estimators[name].final_rmse_m
        assert np.sqrt(np.nanmean(error**2)) == pytest.approx(table, rel=1e-12)
        color = looks(list(r.estimates))[name].color
        drawn = [ln for ln in ax.lines if same(ln.get_color(), color)]
        assert len(drawn) == 1, name  # batch included
        y = np.asarray(drawn[0].get_ydata(), dtype=float)
        assert np.allclose(y[np.isfinite(y)], error[np.isfinite(y)])
        assert np.isfinite(y).sum() >= len(error) - 1  # only the anchored pose (zero error) is left out


def test_online_error_strips_have_the_bound_as_a_band(square: Comparison, figure: Figure) -> None:
    for name, series in square.results.series.items():
        ax = axes(figure, f"online error {name}")
        color = looks(list(square.results.estimates))[name].color
        assert len(ax.collections) == 1 and same(ax.collections[0].get_facecolor()[0][:3], color)
        assert ax.collections[0].get_alpha() < 0.5  # a light band, not a line
        (line,) = ax.lines
        assert np.nanmax(line.get_ydata()) == pytest.approx(np.nanmax(series.position_error_m))


def test_map_has_pose_and_landmark_ellipses(square: Comparison, figure: Figure) -> None:
    ax = axes(figure, "map")
    r = square.results
    rings = [
        ln for ln in ax.lines if len(ln.get_xydata()) == 25 and np.allclose(ln.get_xydata()[0], ln.get_xydata()[-1])
    ]
    ekf = looks(list(r.estimates))["ekf"].color
    assert sum(same(ln.get_color(), ekf) for ln in rings) == len(r.estimates["ekf"].landmarks) + 1  # + last pose
    for name, series in r.series.items():  # each online estimator: its last pose's 2-sigma ellipse around it
        color = looks(list(r.estimates))[name].color
        centred = [ln for ln in rings if same(ln.get_color(), color)
                   and np.allclose(ln.get_xydata()[:-1].mean(axis=0), series.poses[-1, :2])]  # fmt: skip
        assert centred, name
        radius = np.linalg.norm(centred[-1].get_xydata() - series.poses[-1, :2], axis=1).max()
        assert radius == pytest.approx(2 * np.sqrt(np.linalg.eigvalsh(series.position_cov[-1]).max()))


def test_nees_panel_keeps_its_chi_square_band(figure: Figure) -> None:
    ax = axes(figure, "nees")
    (band,) = [p for p in ax.patches]
    low, high = band.get_y(), band.get_y() + band.get_height()
    assert low == pytest.approx(0.2158, abs=1e-3) and high == pytest.approx(9.348, abs=1e-3)


def test_title_names_the_source_by_its_short_name_and_robot(square: Comparison) -> None:
    assert title(square.results).startswith("square: 25 poses")
    moved = replace(square.results, source="/data/streams/mrclam6_robot1.jsonl.gz", robot=1)
    assert title(moved).startswith("mrclam6_robot1.jsonl.gz, robot 1: 25 poses")


def test_results_carry_the_robot_of_the_stream_header(mrclam_head: Path) -> None:
    results = replay(mrclam_head, ReplayConfig(estimators=("ekf",)))
    assert results.robot == 1
    assert replay("square", ReplayConfig(estimators=("ekf",))).robot is None


@pytest.mark.slow
def test_figure_without_truth_or_online_estimators_is_written(square: Comparison, tmp_path: Path) -> None:
    blind = replace(square.results, truth_poses=None, truth_landmarks={})
    width, height = plot_comparison(replace(square, results=blind), tmp_path / "blind.png")
    assert (tmp_path / "blind.png").stat().st_size > 0 and width >= 1000 and height >= 800
    batch_only = replace(square.results, series={})  # no online estimator: one empty strip says so
    plot_comparison(replace(square, results=batch_only), tmp_path / "batch.png")
