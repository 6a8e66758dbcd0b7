"""The comparison table: the replay's table (:mod:`~online_slam.reports.table`), then the Monte Carlo figures."""

from __future__ import annotations

from online_slam.compare import Comparison, MonteCarlo
from online_slam.reports.table import notes, robot_rows, table_lines
from online_slam.wording import counted


def format_comparison(comparison: Comparison) -> str:
    """Render a comparison as plain text.

    Args:
        comparison: What :func:`online_slam.compare.compare` returned.

    Returns:
        Lines of text, ending without a newline.
    """
    out = table_lines(comparison.results, robot_rows(comparison.results, comparison.rows))
    mc = comparison.monte_carlo
    if mc is not None:  # the table above the Monte Carlo figures is one run of them
        out.insert(0, f"seed {mc.seeds[0]}, the first of the {counted(mc.runs, 'Monte Carlo run')} summed up below:")
    extra = [*_smoother_names(comparison), *notes(comparison.results), *_same_smoothers(comparison)]
    if extra:
        out += ["", *extra]
    if comparison.monte_carlo is not None:
        out += ["", *_monte_carlo(comparison.monte_carlo)]
    return "\n".join(out)


def _smoother_names(comparison: Comparison) -> list[str]:
    """How a smoother row's name reads, once, when the table has one."""
    if not any(name.startswith("smoother W=") for name in comparison.rows):
        return []
    return [
        "smoother W=a..b D=d K=k: at least a poses, more until their path spans d m, at most b; solved every k steps"
        " (W=a alone: exactly a poses).",
        "  a last word names the prior's --smoother-linearization (FEJ, invariant; none: standard); see"
        " docs/estimators.md#smoother.",
    ]


def _same_smoothers(comparison: Comparison) -> list[str]:
    """A line per group of smoother configurations whose figures are identical: their windows held the same poses
    (a window sized by distance keeps more than W poses where the robot moves little per pose)."""
    groups: dict[tuple, list[str]] = {}
    for name, row in comparison.rows.items():
        if name.startswith("smoother"):
            key = (row.online_rmse_m, row.final_rmse_m, row.landmark_rmse_m, row.nees_mean)
            groups.setdefault(key, []).append(name)
    same = [names for names in groups.values() if len(names) > 1]
    return [
        line
        for names in same
        for line in (
            f"identical figures: {', '.join(names)}",
            "  their windows held the same poses: a window sized by distance keeps more than W poses where the robot"
            " moves little per pose; --window-distance 0 keeps exactly W",
        )
    ]


def _monte_carlo(mc: MonteCarlo) -> list[str]:
    """Mean +- std of the figures over runs, and the average-NEES test."""
    low, high = mc.anees_bounds
    out = [f"Monte Carlo: {counted(mc.runs, 'run')} (seeds {mc.seeds[0]}..{mc.seeds[-1]}); mean +- std over runs"]
    keys = ("online_rmse_m", "final_rmse_m", "landmark_rmse_m", "nees_mean")
    width = max(len("estimator"), *map(len, mc.mean)) + 2
    out.append(f"{'estimator':<{width}}" + "".join(f"{k:>24}" for k in keys))
    for name in mc.mean:
        cells = []
        for k in keys:
            m, s = mc.mean[name].get(k), mc.std[name].get(k)
            cells.append("-" if m is None else f"{m:.4f} +- {s:.4f}" if s is not None else f"{m:.4f}")
        out.append(f"{name:<{width}}" + "".join(f"{c:>24}" for c in cells))
    first, last = mc.scored_steps
    out.append(
        f"over steps {first}..{last}: NEES averaged over runs (ANEES; 95% band for {counted(mc.runs, 'run')}: "
        f"{low:.2f} .. {high:.2f}), RMS errors over runs:"
    )
    out.append(
        f"  {'estimator':<{width}}{'ANEES':>8}{'verdict':>13}{'in band':>9}{'landmark ANEES':>16}"
        f"{'position RMSE m':>17}{'heading RMSE rad':>18}"
    )
    for name, value in mc.anees.items():
        verdict = "consistent" if low <= value <= high else "optimistic" if value > high else "pessimistic"
        landmark = mc.landmark_anees[name]
        out.append(
            f"  {name:<{width}}{value:>8.2f}{verdict:>13}{100 * mc.anees_in_bounds[name]:>8.0f}%"
            f"{'-' if landmark is None else f'{landmark:.2f}':>16}{mc.position_rmse_m[name]:>17.4f}"
            f"{mc.heading_rmse_rad[name]:>18.4f}"
        )
    out.append("  (pose ANEES: 3 = consistent; landmark ANEES, over the final map: 2 = consistent)")
    return out
