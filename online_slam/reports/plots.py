"""Comparison figures (matplotlib, light theme): the map, position error, NEES and step latency."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.stats import chi2

from online_slam.compare import Comparison
from online_slam.evaluation.scoring import NEES_DOF
from online_slam.reports.palette import palette
from online_slam.sinks.geometry import ellipses


def _fit(ax: object, values: list[np.ndarray], floor: float, ceiling: float) -> None:
    """Log-scale y limits fitted to the plotted data (1st-99th percentile), never hiding the reference band."""
    data = np.concatenate([v[np.isfinite(v) & (v > 0)] for v in values]) if values else np.zeros(0)
    if len(data):
        low, high = np.percentile(data, [1, 99])
        ax.set_ylim(min(low, floor) / 2.0, max(high, ceiling) * 2.0)  # type: ignore[attr-defined]


def plot_comparison(comparison: Comparison, path: str | Path, dpi: int = 100) -> tuple[int, int]:
    """Write the four panels to one PNG.

    Args:
        comparison: What :func:`online_slam.compare.compare` returned.
        path: Output ``.png``.
        dpi: Resolution.

    Returns:
        (width, height) in pixels of the written image.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = comparison.results
    colors = palette(["truth", *r.estimates])
    color_of = colors.__getitem__
    fig, axes = plt.subplots(2, 2, figsize=(12, 9), constrained_layout=True)
    ax_map, ax_err, ax_nees, ax_lat = axes.ravel()
    # (1) the map, like the article's figure
    if r.truth_poses is not None:
        ax_map.plot(*r.truth_poses[:, :2].T, "--", color="0.35", lw=1.4, label="truth")
    for name, estimate in r.estimates.items():
        style = "o-" if len(estimate.poses) <= 60 else "-"
        ax_map.plot(*estimate.poses[:, :2].T, style, color=color_of(name), ms=3, lw=1.1, label=name)
    if r.truth_landmarks:
        truth_lm = np.array(list(r.truth_landmarks.values()))
        ax_map.scatter(*truth_lm.T, marker="x", color="0.2", s=40, label="true landmarks", zorder=3)
    for name, estimate in r.estimates.items():
        if name != "odometry" and len(estimate.landmarks):
            ax_map.scatter(*estimate.landmarks.T, marker="+", color=color_of(name), s=45, zorder=3)
    for name, estimate in r.estimates.items():
        if estimate.landmark_covs is not None and len(estimate.landmarks):
            for ring in ellipses(estimate.landmarks, estimate.landmark_covs):
                ax_map.plot(*ring.T, color=color_of(name), lw=0.7, alpha=0.8)
    ax_map.set(xlabel="x (m)", ylabel="y (m)", title=f"{r.source}: trajectories and maps")
    ax_map.set_aspect("equal", adjustable="datalim")
    ax_map.legend(fontsize=9, loc="best")
    # (2) position error with its 2-sigma bound
    for name, s in r.series.items():
        step = np.arange(len(s.t))
        # steps whose estimate has no uncertainty (a fixed start pose) say nothing about consistency: not drawn
        certain = np.isfinite(s.position_sigma_m) & (s.position_sigma_m <= 1e-9)
        ax_err.plot(step, np.where(certain, np.nan, s.position_error_m), color=color_of(name), lw=1.0, label=name)
        if np.isfinite(s.position_sigma_m).any():
            sigma = np.where(certain, np.nan, 2 * s.position_sigma_m)
            ax_err.plot(step, sigma, ":", color=color_of(name), lw=1.0, label=f"{name} 2-sigma")
    ax_err.set(xlabel="step", ylabel="position error (m)", title="online position error and 2-sigma bound")
    ax_err.set_yscale("symlog", linthresh=0.05)
    ax_err.legend(fontsize=9, ncol=2)
    # (3) NEES with chi-square bounds, only at steps where the estimate has an uncertainty (not the fixed start)
    low, high = chi2.ppf([0.025, 0.975], NEES_DOF)
    shown = []
    for name, s in r.series.items():
        uncertain = np.isfinite(s.position_sigma_m) & (s.position_sigma_m > 1e-9) & np.isfinite(s.nees)
        if name != "odometry" and uncertain.any():
            nees = np.where(uncertain, s.nees, np.nan)
            ax_nees.plot(np.arange(len(s.t)), nees, color=color_of(name), lw=0.9, label=name)
            shown.append(nees)
    ax_nees.axhline(low, color="0.4", ls="--", lw=1, label="95% chi-square bounds (3 dof)")
    ax_nees.axhline(high, color="0.4", ls="--", lw=1)
    ax_nees.set(xlabel="step", ylabel="pose NEES", title="pose NEES (3 = consistent)")
    ax_nees.set_yscale("log")
    _fit(ax_nees, shown, low, high)
    ax_nees.legend(fontsize=9)
    # (4) step latency
    latencies = []
    for name, s in r.series.items():
        if name != "odometry":
            ax_lat.plot(np.arange(len(s.t)), s.step_ms, color=color_of(name), lw=0.8, label=name)
            latencies.append(s.step_ms)
    ax_lat.set(xlabel="step", ylabel="ms", title="step latency")
    finite = np.concatenate([v[np.isfinite(v)] for v in latencies]) if latencies else np.zeros(0)
    if len(finite):  # fitted to the bulk: a rare spike is clipped rather than flattening every curve
        ax_lat.set_ylim(0.0, 1.3 * float(np.percentile(finite, 99)))
    ax_lat.legend(fontsize=9)
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    fig.savefig(path, dpi=dpi)
    width, height = fig.canvas.get_width_height()
    plt.close(fig)
    return int(width * dpi / fig.dpi), int(height * dpi / fig.dpi)
