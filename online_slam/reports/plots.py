"""Comparison figure (matplotlib, light theme): map, online and final position error, NEES and step latency.

Every estimator keeps one look across the panels: its colour (:mod:`online_slam.reports.palette`, shared with
Rerun recordings), a line style and a marker of its own, so that two estimators never differ by hue alone.
Uncertainty is drawn as light bands and thin ellipses of the estimator's colour, never as a line that could be
read as another estimator. Logarithmic axes are fitted to every value drawn (nothing is clipped), span at least
a decade and are labelled at 1, 2, 5 x 10^k (more sparsely on tall spans).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from online_slam.compare import Comparison, MonteCarlo, Row
from online_slam.evaluation.results import Results
from online_slam.evaluation.scoring import NEES_DOF, position_errors
from online_slam.reports.palette import palette
from online_slam.reports.table import title as table_title
from online_slam.sinks.geometry import ellipses
from online_slam.wording import counted

Array = NDArray[np.float64]

_DOTTED = (0, (1, 1.5))
_LOOKS: dict[str, tuple[Any, str]] = {
    "odometry": ((0, (6, 2, 1, 2)), "D"),
    "ekf": ("-", "o"),
    "smoother": ((0, (5, 2)), "s"),
    "batch": (_DOTTED, "^"),
}
"""Line style and marker by estimator name."""
_EXTRA_LOOKS: list[tuple[Any, str]] = [
    ((0, (3, 1, 1, 1, 1, 1)), "v"),
    ((0, (9, 2, 2, 2)), "P"),
    ((0, (2, 2)), "X"),
    ((0, (12, 3)), "*"),
]
"""Looks of further estimators (more smoother configurations), in order of appearance."""
_TRUTH = (0.45, 0.45, 0.45)
_MARKED_POSES = 60
"""Trajectories of at most this many poses mark each pose."""
_EXACT_M = 1e-9
"""Errors below this are exact by construction (the pose the alignment anchors on): not drawn on a log axis."""


@dataclass(frozen=True)
class Look:
    """How one estimator is drawn in every panel."""

    color: tuple[float, float, float]
    """Matplotlib RGB, from the shared palette."""
    dashes: Any
    """Matplotlib line style."""
    marker: str
    """Marker for short trajectories and for the last pose."""
    width: float
    """Line width, points (dotted lines are drawn a little thicker to stay visible)."""


def looks(names: list[str]) -> dict[str, Look]:
    """One look per estimator: its palette colour and a line style and marker no other estimator has.

    The first estimator without a style of its own (usually the one smoother configuration) takes the smoother's,
    as :func:`~online_slam.reports.palette.rgb_colors` gives it the smoother's colour.
    """
    colors = palette(names)
    taken = {_LOOKS[name] for name in names if name in _LOOKS}
    free = [look for look in (_LOOKS["smoother"], *_EXTRA_LOOKS) if look not in taken]
    out = {}
    for k, name in enumerate(names):
        if name in _LOOKS:
            dashes, marker = _LOOKS[name]
        else:
            dashes, marker = free.pop(0) if free else _EXTRA_LOOKS[k % len(_EXTRA_LOOKS)]
        out[name] = Look(colors[name], dashes, marker, 1.7 if dashes == _DOTTED else 1.2)
    return out


def title(results: Results) -> str:
    """The figure's title: the source's short name, its robot when the stream names one, and its size."""
    name = Path(results.source).name or results.source
    return table_title(replace(results, source=name))


def _ticks(low: float, high: float, subs: tuple[float, ...]) -> int:
    """How many of ``subs`` x 10^k lie in [low, high]."""
    powers = 10.0 ** np.arange(np.floor(np.log10(low)), np.ceil(np.log10(high)) + 1)
    return int(sum(((powers * m >= low) & (powers * m <= high)).sum() for m in subs))


def log_axis(ax: Any, values: list[Array], keep: tuple[float, ...] = (), most: int = 8) -> tuple[float, float]:
    """Put ``ax``'s y axis on a log scale that shows every positive value given (and ``keep``), unclipped.

    The limits span at least one decade, so at least three ticks are labelled (1, 2, 5 x 10^k); taller spans
    are labelled more sparsely (1, 3 x 10^k, then powers of ten) to keep at most about ``most`` labels.

    Returns:
        The y limits set (unchanged when there is no positive value).
    """
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    data = np.concatenate([np.asarray(v, dtype=float).ravel() for v in values] + [np.asarray(keep, dtype=float)])
    data = data[np.isfinite(data) & (data > 0)]
    if not len(data):
        return ax.get_ylim()
    low, high = float(data.min()), float(data.max())
    if high / low < 10.0:  # less than a decade: widen around the middle so that ticks are labelled
        middle = np.sqrt(low * high)
        low, high = middle / np.sqrt(10.0), middle * np.sqrt(10.0)
    low, high = low / 1.25, high * 1.25
    ax.set_yscale("log")
    ax.set_ylim(low, high)
    subs = next((s for s in ((1.0, 2.0, 5.0), (1.0, 3.0)) if _ticks(low, high, s) <= most), (1.0,))
    ax.yaxis.set_major_locator(LogLocator(base=10.0, subs=subs, numticks=most + 2))
    ax.yaxis.set_minor_locator(LogLocator(base=10.0, subs=tuple(range(1, 10)), numticks=30))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(NullFormatter())
    return low, high


def _apart(xy: Array, robots: tuple) -> Array:
    """Positions (N, 2) as one line per robot, NaN rows between them (where matplotlib breaks a line); as given with
    one robot (``robots``: the robot of each step, or empty)."""
    if not robots:
        return xy
    column = np.array(robots[: len(xy)], dtype=object)
    return np.concatenate(
        [np.vstack([xy[column == robot], np.full((1, 2), np.nan)]) for robot in dict.fromkeys(robots)]
    )


def _draw_last(ax: Any, r: Results, look: dict[str, Look]) -> None:
    """Each robot's newest pose with its uncertainty as each online estimator knew it at the end, marked ``last
    step`` (``robot <id>``, with several robots)."""
    robots = r.step_robots
    ends = {robot: len(robots) - 1 - robots[::-1].index(robot) for robot in dict.fromkeys(robots)} or {None: -1}
    for robot, k in ends.items():
        last = None
        for name, series in r.series.items():
            if not len(series.t) or k >= len(series.t) or not np.isfinite(series.position_cov[k]).all():
                continue
            s, last = look[name], series.poses[[k], :2]
            ax.plot(*ellipses(last, series.position_cov[[k]])[0].T, color=s.color, lw=1.6, zorder=5)
            ax.scatter(*last.T, marker=s.marker, color=s.color, s=30, edgecolor="black", lw=0.6, zorder=6)
        if last is not None:
            text = "last step" if robot is None else f"robot {robot}"
            ax.annotate(text, last[0], xytext=(18, -18), textcoords="offset points", fontsize=9,
                        arrowprops={"arrowstyle": "-", "color": "0.3", "lw": 0.8}, zorder=6)  # fmt: skip


def draw_map(ax: Any, r: Results, look: dict[str, Look]) -> None:
    """Final trajectories and landmarks against truth, with 2-sigma ellipses of the landmarks and of the last pose."""
    if r.truth_poses is not None:
        xy = _apart(r.truth_poses[:, :2], r.step_robots)
        ax.plot(*xy.T, color=_TRUTH, lw=3.0, alpha=0.45, solid_capstyle="round", zorder=1)
    if r.truth_landmarks:
        truth_lm = np.array(list(r.truth_landmarks.values()))
        ax.scatter(*truth_lm.T, marker="x", color="0.15", s=45, lw=1.4, zorder=4)
    for name, estimate in r.estimates.items():
        s = look[name]
        marker = s.marker if len(estimate.poses) <= _MARKED_POSES else None
        xy = _apart(estimate.poses[:, :2], r.step_robots)
        ax.plot(*xy.T, color=s.color, ls=s.dashes, lw=s.width, marker=marker, ms=3.5, zorder=2)
        if name != "odometry" and len(estimate.landmarks):
            ax.scatter(*estimate.landmarks.T, marker="+", color=s.color, s=55, lw=1.3, zorder=3)
        if estimate.landmark_covs is not None and len(estimate.landmarks):
            for ring in ellipses(estimate.landmarks, estimate.landmark_covs):
                ax.plot(*ring.T, color=s.color, lw=0.9, zorder=3)
    _draw_last(ax, r, look)
    ax.set(xlabel="x (m)", ylabel="y (m)", title="final trajectories and landmarks; 2-sigma ellipses at the last step")
    ax.set_aspect("equal", adjustable="datalim")


def _note(ax: Any, text: str = "no ground truth in this stream") -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes)


def draw_online_error(axes: list[Any], r: Results, look: dict[str, Look]) -> list[Array]:
    """Each online estimator in its own strip: its error as estimated when newest, over a band up to 2 sigma.

    Args:
        axes: One axes per series of ``r`` (top to bottom).

    Returns:
        The values drawn (to give every error axis the same limits).
    """
    drawn: list[Array] = []
    for ax, (name, s) in zip(axes, r.series.items()):
        step, st = np.arange(len(s.t)), look[name]
        # steps whose estimate has no uncertainty (a fixed start pose) say nothing about consistency: not drawn
        certain = np.isfinite(s.position_sigma_m) & (s.position_sigma_m <= 1e-9)
        error = np.where(certain | (s.position_error_m < _EXACT_M), np.nan, s.position_error_m)
        bound = np.where(certain, np.nan, 2 * s.position_sigma_m)
        ax.fill_between(step, _EXACT_M, bound, color=st.color, alpha=0.2, lw=0, zorder=1)
        ax.plot(step, error, color=st.color, ls=st.dashes, lw=st.width, zorder=3)
        ax.text(0.01, 0.95, name, color=st.color, fontweight="bold", va="top", transform=ax.transAxes)
        ax.set_ylabel("error (m)")
        drawn += [bound, error]
    axes[0].set_title("online error of the newest pose (band: up to its 2-sigma bound)")
    axes[-1].set_xlabel("step")
    if not r.series:
        _note(axes[0], "no online estimator")
    elif r.truth_poses is None:
        _note(axes[0])
    return drawn


def draw_final_error(ax: Any, r: Results, look: dict[str, Look]) -> list[Array]:
    """Each pose's error in the final estimate (batch and odometry included), aligned as the table aligns it.

    Returns:
        The values drawn (to give every error axis the same limits).
    """
    drawn: list[Array] = []
    for name, estimate in r.estimates.items():
        error = position_errors(estimate.poses, r.truth_poses, r.alignment, r.truth_offsets, r.truth_starts)
        error[error < _EXACT_M] = np.nan  # the pose the alignment anchors on
        s = look[name]
        ax.plot(np.arange(len(error)), error, color=s.color, ls=s.dashes, lw=s.width)
        drawn.append(error)
    ax.set(xlabel="step", ylabel="position error (m)", title="final error (each pose in the final estimate)")
    if r.truth_poses is None:
        _note(ax)
    return drawn


def draw_nees(ax: Any, r: Results, look: dict[str, Look]) -> None:
    """Pose NEES at steps where the estimate has an uncertainty, over the 95% chi-square band."""
    low, high = chi2.ppf([0.025, 0.975], NEES_DOF)
    ax.axhspan(low, high, color="0.55", alpha=0.18, lw=0, zorder=0)
    ax.axhline(NEES_DOF, color="0.4", lw=0.8, ls=_DOTTED, zorder=0)
    shown = []
    for name, s in r.series.items():
        uncertain = np.isfinite(s.position_sigma_m) & (s.position_sigma_m > 1e-9) & np.isfinite(s.nees)
        uncertain &= ~(s.position_error_m < _EXACT_M)  # the anchored pose: no error by construction, NEES ~ 0
        if name != "odometry" and uncertain.any():
            nees = np.where(uncertain, s.nees, np.nan)
            ax.plot(np.arange(len(s.t)), nees, color=look[name].color, ls=look[name].dashes, lw=look[name].width)
            shown.append(nees)
    ax.set(
        xlabel="step",
        ylabel="pose NEES",
        title=f"pose NEES (grey: 95% chi-square band, {NEES_DOF} dof; dotted: its mean)",
    )
    if shown:
        log_axis(ax, shown, keep=(low, high))
    else:
        _note(ax)


def draw_anees(ax: Any, mc: MonteCarlo, look: dict[str, Look]) -> None:
    """Pose NEES averaged over the Monte Carlo runs, step by step, over its 95% band (esde's Fig. 2)."""
    low, high = mc.anees_bounds
    first, last = mc.scored_steps
    ax.axhspan(low, high, color="0.55", alpha=0.18, lw=0, zorder=0)
    ax.axhline(NEES_DOF, color="0.4", lw=0.8, ls=_DOTTED, zorder=0)
    ax.axvspan(first, last, color="0.85", alpha=0.25, lw=0, zorder=0)
    top = high
    for name, values in mc.anees_per_step.items():
        average = np.asarray(values, dtype=float)
        ax.plot(np.arange(len(average)), average, color=look[name].color, ls=look[name].dashes, lw=look[name].width)
        top = max(top, float(np.nanmax(average)))
    ax.set_ylim(0.0, 1.05 * top)
    ax.set(
        xlabel="step",
        ylabel="pose NEES, mean over runs",
        title=f"pose NEES averaged over {counted(mc.runs, 'run')} (grey: its 95% band; light: steps {first}..{last} "
        "scored)",
    )


def draw_latency(ax: Any, r: Results, look: dict[str, Look]) -> None:
    """Wall time of every step on a log axis (every spike shown), each estimator's slowest step marked."""
    drawn = []
    for k, (name, s) in enumerate(r.series.items()):
        step, ms, st = np.arange(len(s.t)), s.step_ms, look[name]
        ax.plot(step, ms, color=st.color, lw=0.7, alpha=0.85)
        if np.isfinite(ms).any():
            worst = int(np.nanargmax(ms))
            ax.scatter([worst], [ms[worst]], marker=st.marker, color=st.color, s=36, edgecolor="black", zorder=4)
            ax.annotate(f"{ms[worst]:.1f} ms", (worst, ms[worst]), xytext=(7, -10 * k), textcoords="offset points",
                        va="center", fontsize=8, color=st.color)  # fmt: skip
        drawn.append(ms)
    ax.set(xlabel="step", ylabel="ms (log scale)", title="step latency, every step (marker: slowest)")
    log_axis(ax, drawn)


def _m(value: float | None) -> str:
    return "-" if value is None or value != value else f"{value:.3f}"


def _label(name: str, row: Row | None) -> str:
    if row is None or row.final_rmse_m is None:
        return name
    if row.online_rmse_m is None or name == "odometry":
        return f"{name}: RMSE {_m(row.final_rmse_m)} m"
    return f"{name}: RMSE online {_m(row.online_rmse_m)}, final {_m(row.final_rmse_m)} m"


def legend(fig: Any, comparison: Comparison, look: dict[str, Look]) -> Any:
    """One legend for the whole figure, below the panels: estimators (with the table's RMSEs) and the symbols."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    r = comparison.results
    handles: list[Line2D | Patch] = [
        Line2D([], [], color=s.color, ls=s.dashes, lw=s.width + 0.3, marker=s.marker, ms=5,
               label=_label(name, comparison.rows.get(name)))
        for name, s in look.items()
    ]  # fmt: skip
    if r.truth_poses is not None:
        handles.append(Line2D([], [], color=_TRUTH, lw=3.0, alpha=0.45, label="truth"))
    if r.truth_landmarks:
        handles.append(Line2D([], [], color="0.15", marker="x", ls="", ms=7, label="true landmarks"))
    handles += [
        Line2D([], [], color="0.3", marker="+", ls="", ms=8, label="estimated landmarks (estimator's colour)"),
        Line2D([], [], color="0.3", lw=1.0, label="2-sigma ellipse (map) or band (online error)"),
        Patch(color="0.55", alpha=0.3, lw=0, label=f"95% NEES band ({NEES_DOF} dof)"),
    ]
    return fig.legend(handles=handles, loc="outside lower center", ncol=3, fontsize=9, frameon=False)


def comparison_figure(comparison: Comparison) -> Any:
    """The comparison figure, not yet written (a :class:`matplotlib.figure.Figure`, no pyplot state).

    Layout: the map on the left (two rows tall); on the right one strip of online error per online estimator,
    then the final error of every estimator, both on the same log scale; NEES and step latency below; one legend
    under everything. Each axes is labelled (``map``, ``online error <name>``, ``final error``, ``nees``,
    ``latency``) for tests and further editing.
    """
    from matplotlib.figure import Figure

    r = comparison.results
    mc = comparison.monte_carlo
    look = looks([*r.estimates, *(n for n in (mc.anees if mc else ()) if n not in r.estimates)])  # and the peers
    more = max(0, len(r.series) - 3)  # strips beyond three make the figure taller rather than thinner
    fig = Figure(figsize=(14, 13 + 1.1 * more), layout="constrained")
    grid = fig.add_gridspec(3, 2, height_ratios=(1.0 + 0.35 * more, 1.0, 0.9))
    ax_map = fig.add_subplot(grid[0:2, 0], label="map")
    ax_final = fig.add_subplot(grid[1, 1], label="final error")
    strips = grid[0, 1].subgridspec(max(1, len(r.series)), 1)
    names = list(r.series) or [""]
    cells = [strips[k] for k in range(len(names))]  # one row each
    online = [fig.add_subplot(cell, sharex=ax_final, label=f"online error {n}") for cell, n in zip(cells, names)]
    ax_nees, ax_lat = fig.add_subplot(grid[2, 0], label="nees"), fig.add_subplot(grid[2, 1], label="latency")
    draw_map(ax_map, r, look)
    errors = draw_online_error(online, r, look) + draw_final_error(ax_final, r, look)
    for ax in online:  # the final error's limits, labelled sparsely in these short strips
        log_axis(ax, errors, most=3)
    log_axis(ax_final, errors)
    if comparison.monte_carlo is not None and comparison.monte_carlo.anees_per_step:
        draw_anees(ax_nees, comparison.monte_carlo, look)
    else:
        draw_nees(ax_nees, r, look)
    draw_latency(ax_lat, r, look)
    for ax in online[:-1]:
        ax.tick_params(labelbottom=False)
    for ax in (ax_map, *online, ax_final, ax_nees, ax_lat):
        ax.grid(alpha=0.3)
        ax.grid(which="minor", alpha=0.1)
    fig.suptitle(title(r), fontsize=14)
    legend(fig, comparison, look)
    return fig


def plot_comparison(comparison: Comparison, path: str | Path, dpi: int = 100) -> tuple[int, int]:
    """Write :func:`comparison_figure` to one PNG.

    Args:
        comparison: What :func:`online_slam.compare.compare` returned.
        path: Output ``.png``.
        dpi: Resolution.

    Returns:
        (width, height) in pixels of the written image.
    """
    fig = comparison_figure(comparison)
    fig.savefig(path, dpi=dpi)
    width, height = fig.canvas.get_width_height()
    return int(width * dpi / fig.dpi), int(height * dpi / fig.dpi)
