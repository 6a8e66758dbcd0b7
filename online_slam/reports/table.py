"""The replay table, laid out like the article's: one column per estimator, odometry first."""

from __future__ import annotations

from online_slam.evaluation.results import Results


def _metres(value: float | None) -> str:
    return "-" if value is None or value != value else f"{value:.3f} m"


def format_results(results: Results) -> str:
    """Render results as a plain-text table.

    Args:
        results: What :func:`online_slam.replay` returned.

    Returns:
        Lines of text, ending without a newline.
    """
    columns = ["Odometry only", *results.estimators]
    rows: list[tuple[str, list[str]]] = [
        (
            "Position RMSE over the path",
            [_metres(results.odometry.rmse_m)] + [_metres(r.final_rmse_m) for r in results.estimators.values()],
        ),
        (
            "Estimated end-to-start gap",
            [_metres(results.odometry.endpoint_gap_m)]
            + [_metres(r.endpoint_gap_m) for r in results.estimators.values()],
        ),
        (
            "Landmark RMSE",
            [_metres(results.odometry.landmark_rmse_m)]
            + [_metres(r.landmark_rmse_m) for r in results.estimators.values()],
        ),
        ("Time", ["-"] + [f"{r.total_s:.3f} s" for r in results.estimators.values()]),
    ]
    label_width = max(len("Metric"), *(len(label) for label, _ in rows))
    widths = [max(len(c), *(len(cells[k]) for _, cells in rows)) for k, c in enumerate(columns)]
    title = (
        f"{results.source}: {results.poses} poses, {results.landmarks} landmarks, {results.observations} observations"
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
                f"{name}: {state} in {d['iterations']} iterations "
                f"(cost {d['initial_cost']:.6g} -> {d['final_cost']:.6g})"
            )
    if results.error:
        notes.append(f"stopped early at bad input; figures cover the {results.poses} poses before it")
    if notes:
        lines.append("")
        lines.extend(notes)
    return "\n".join(lines)
