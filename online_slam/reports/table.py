"""The replay table, laid out like the article's: one column per estimator, odometry first."""

from __future__ import annotations

from online_slam.evaluation.results import EstimatorResult, Results
from online_slam.wording import counted


def _metres(value: float | None) -> str:
    return "-" if value is None or value != value else f"{value:.3f} m"


def _number(value: float | None) -> str:
    return "-" if value is None or value != value else f"{value:.2f}"


def _latency(result: EstimatorResult) -> str:
    if result.step_ms is None:
        return "-"
    return f"{result.step_ms.median:.2f} / {result.step_ms.p95:.2f}"


def _association(result: EstimatorResult) -> str:
    a = result.association
    if a is None:
        return "-"
    right = "-" if a.accuracy is None else f"{a.accuracy:.3f}"
    return f"{right}, {a.landmarks_mapped}/{'-' if a.landmarks_true is None else a.landmarks_true}"


def format_results(results: Results) -> str:
    """Render results as a plain-text table.

    Args:
        results: What :func:`online_slam.replay` returned.

    Returns:
        Lines of text, ending without a newline.
    """
    columns = ["Odometry only", *results.estimators]
    est = list(results.estimators.values())
    odo = results.odometry
    rows: list[tuple[str, list[str]]] = [
        ("Position RMSE over the path", [_metres(odo.rmse_m)] + [_metres(r.final_rmse_m) for r in est]),
        ("Estimated end-to-start gap", [_metres(odo.endpoint_gap_m)] + [_metres(r.endpoint_gap_m) for r in est]),
        ("Landmark RMSE", [_metres(odo.landmark_rmse_m)] + [_metres(r.landmark_rmse_m) for r in est]),
        ("Online position RMSE", [_metres(odo.rmse_m)] + [_metres(r.online_rmse_m) for r in est]),
        ("Pose NEES, mean (3 = consistent)", ["-"] + [_number(r.nees_mean) for r in est]),
        ("Step time median / p95 (ms)", ["-"] + [_latency(r) for r in est]),
        ("Total time", ["-"] + [f"{r.total_s:.3f} s" for r in est]),
    ]
    if any(r.association is not None for r in est):
        rows.append(("Association right, landmarks mapped/true", ["-"] + [_association(r) for r in est]))
    label_width = max(len("Metric"), *(len(label) for label, _ in rows))
    widths = [max(len(c), *(len(cells[k]) for _, cells in rows)) for k, c in enumerate(columns)]
    title = (
        f"{results.source}: {counted(results.poses, 'pose')}, {counted(results.landmarks, 'landmark')}, "
        f"{counted(results.observations, 'observation')}"
    )
    lines = [title, ""]
    lines.append("  ".join(["Metric".ljust(label_width), *(c.rjust(w) for c, w in zip(columns, widths))]))
    lines.append("  ".join(["-" * label_width, *("-" * w for w in widths)]))
    for label, cells in rows:
        lines.append("  ".join([label.ljust(label_width), *(c.rjust(w) for c, w in zip(cells, widths))]))
    notes = []
    if results.alignment != "anchor":
        notes.append(f"errors after {results.alignment} alignment")
    for name, result in results.estimators.items():
        d = result.details
        if "iterations" in d:
            state = "converged" if d.get("converged") else "NOT converged"
            notes.append(
                f"{name}: {state} in {counted(d['iterations'], 'iteration')} "
                f"(cost {d['initial_cost']:.6g} -> {d['final_cost']:.6g})"
            )
        o = result.outliers
        if o is not None and (o.rejected or o.true_outliers):
            scored = (
                f"; of {o.true_outliers} marked outliers {o.caught} caught, {o.inliers_lost} inliers lost"
                if o.true_outliers is not None
                else ""
            )
            notes.append(f"{name}: {o.rejected} of {counted(o.sightings, 'sighting')} rejected as outliers{scored}")
    if results.input.skipped_lines:
        reasons = ", ".join(f"{k}: {v}" for k, v in sorted(results.input.skipped_by_reason.items()))
        notes.append(f"input: {counted(results.input.skipped_lines, 'bad line')} skipped ({reasons})")
    if results.error:
        notes.append(f"stopped early at bad input; figures cover the {counted(results.poses, 'pose')} before it")
    if notes:
        lines.append("")
        lines.extend(notes)
    return "\n".join(lines)
