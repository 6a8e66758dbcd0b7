"""Comparison figures (matplotlib, light theme): the map, position error, NEES and step latency."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.stats import chi2

from online_slam.compare import NEES_DOF, Comparison
from online_slam.reports.palette import palette
from online_slam.sinks.geometry import ellipses


def plot_comparison(comparison: Comparison, path: str | Path, dpi: int = 110) -> tuple[int, int]:
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
    fig, axes = plt.subplots(2, 2, figsize=(13, 9.5), constrained_layout=True)
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
    ax_map.legend(fontsize=8, loc="best")
    # (2) position error with its 2-sigma bound
    for name, s in r.series.items():
        step = np.arange(len(s.t))
        ax_err.plot(step, s.position_error_m, color=color_of(name), lw=1.0, label=name)
        if np.isfinite(s.position_sigma_m).any():
            ax_err.plot(step, 2 * s.position_sigma_m, ":", color=color_of(name), lw=1.0, label=f"{name} 2-sigma")
    ax_err.set(xlabel="step", ylabel="position error (m)", title="online position error and 2-sigma bound")
    ax_err.set_yscale("symlog", linthresh=0.05)
    ax_err.legend(fontsize=8)
    # (3) NEES with chi-square bounds
    low, high = chi2.ppf([0.025, 0.975], NEES_DOF)
    for name, s in r.series.items():
        if name != "odometry" and np.isfinite(s.nees).any():
            ax_nees.plot(np.arange(len(s.t)), s.nees, color=color_of(name), lw=0.9, label=name)
    ax_nees.axhline(low, color="0.4", ls="--", lw=1, label="95% chi-square bounds (3 dof)")
    ax_nees.axhline(high, color="0.4", ls="--", lw=1)
    ax_nees.set(xlabel="step", ylabel="pose NEES", title="pose NEES (3 = consistent)")
    ax_nees.set_yscale("log")
    ax_nees.legend(fontsize=8)
    # (4) step latency
    for name, s in r.series.items():
        if name != "odometry":
            ax_lat.plot(np.arange(len(s.t)), s.step_ms, color=color_of(name), lw=0.8, label=name)
    ax_lat.set(xlabel="step", ylabel="ms", title="step latency")
    ax_lat.set_yscale("log")
    ax_lat.legend(fontsize=8)
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    fig.savefig(path, dpi=dpi)
    width, height = fig.canvas.get_width_height()
    plt.close(fig)
    return int(width * dpi / fig.dpi), int(height * dpi / fig.dpi)
