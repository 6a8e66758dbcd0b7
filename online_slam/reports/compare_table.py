"""The comparison table: one row per estimator, the figures users paste."""

from __future__ import annotations

from online_slam.compare import Comparison
from online_slam.evaluation.results import Row
from online_slam.wording import counted


def _m(value: float | None) -> str:
    return "-" if value is None or value != value else f"{value:.3f}"


def _n(value: float | None, digits: int = 2) -> str:
    return "-" if value is None or value != value else f"{value:.{digits}f}"


def _latency(row: Row) -> str:
    if row.step_median_ms is None:
        return "-"
    return f"{row.step_median_ms:.2f}/{row.step_p95_ms:.2f}/{row.step_max_ms:.2f}"


def format_comparison(comparison: Comparison) -> str:
    """Render a comparison as plain text.

    Args:
        comparison: What :func:`online_slam.compare.compare` returned.

    Returns:
        Lines of text, ending without a newline.
    """
    r = comparison.results
    header = [
        "estimator", "online RMSE m", "final RMSE m", "landmark RMSE m", "end gap m",
        "NEES mean", "NEES in 95%", "NIS mean", "step ms med/p95/max", "total s",
    ]  # fmt: skip
    lines = [[name,
              _m(row.online_rmse_m), _m(row.final_rmse_m), _m(row.landmark_rmse_m), _m(row.endpoint_gap_m),
              _n(row.nees_mean), "-" if row.nees_in_bounds is None else f"{100 * row.nees_in_bounds:.0f}%",
              _n(row.nis_mean),
              _latency(row),
              "-" if name == "odometry" else f"{row.total_s:.3f}"]
             for name, row in comparison.rows.items()]  # fmt: skip
    widths = [max(len(h), *(len(line[k]) for line in lines)) for k, h in enumerate(header)]
    size = [counted(r.poses, "pose"), counted(r.landmarks, "landmark"), counted(r.observations, "observation")]
    out = [f"{r.source}: {', '.join(size)}", ""]
    out.append("  ".join([header[0].ljust(widths[0]), *(h.rjust(w) for h, w in zip(header[1:], widths[1:]))]))
    out.append("  ".join("-" * w for w in widths))
    for line in lines:
        out.append("  ".join([line[0].ljust(widths[0]), *(c.rjust(w) for c, w in zip(line[1:], widths[1:]))]))
    if r.alignment != "anchor":
        out.append(f"\nerrors after {r.alignment} alignment")
    if r.input.skipped_lines:
        reasons = ", ".join(f"{k}: {v}" for k, v in sorted(r.input.skipped_by_reason.items()))
        out.append(f"input: {counted(r.input.skipped_lines, 'bad line')} skipped ({reasons})")
    mc = comparison.monte_carlo
    if mc is not None:
        low, high = mc.anees_bounds
        out.append("")
        out.append(
            f"Monte Carlo: {counted(mc.runs, 'run')} (seeds {mc.seeds[0]}..{mc.seeds[-1]}); mean +- std over runs"
        )
        keys = ("online_rmse_m", "final_rmse_m", "landmark_rmse_m", "nees_mean")
        out.append(f"{'estimator':<24}" + "".join(f"{k:>24}" for k in keys))
        for name in mc.mean:
            cells = []
            for k in keys:
                m, s = mc.mean[name].get(k), mc.std[name].get(k)
                cells.append("-" if m is None else f"{m:.4f} +- {s:.4f}" if s is not None else f"{m:.4f}")
            out.append(f"{name:<24}" + "".join(f"{c:>24}" for c in cells))
        out.append(f"average NEES over runs (95% bounds for {counted(mc.runs, 'run')}: {low:.2f} .. {high:.2f}):")
        for name, value in mc.anees.items():
            verdict = "consistent" if low <= value <= high else "optimistic" if value > high else "pessimistic"
            out.append(
                f"  {name:<22} ANEES {value:.2f} ({verdict}); steps inside bounds {100 * mc.anees_in_bounds[name]:.0f}%"
            )
    return "\n".join(out)
