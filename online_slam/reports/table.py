"""The results table that ``replay`` and ``compare`` both print: one row per estimator (dead reckoning first), the
same columns and labels, a short legend of the metrics under it, then notes (convergence, outliers, input)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from online_slam.evaluation.results import INTERRUPTED, EstimatorResult, LandmarkCoverage, Results, Row
from online_slam.evaluation.scoring import nees_bounds
from online_slam.wording import counted

CLOSED_SHARE = 0.01
"""A true path is closed when its end lies within this share of its length of its start: only then does the
estimated end-to-start gap measure drift, and the table shows it."""


def _m(value: float | None) -> str:
    return "-" if value is None or value != value else f"{value:.3f}"


def _n(value: float | None) -> str:
    return "-" if value is None or value != value else f"{value:.2f}"


def _share(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.0f}%"


def _band(row: Row) -> str:
    band = row.nees_band
    if band is None or row.nees_mean is None:
        return "-"
    return f"{band.low:.2f}..{band.high:.2f}"


def _nis(row: Row) -> str:
    return "-" if row.nis_mean is None else f"{_n(row.nis_median)}/{_n(row.nis_mean)}"


def _latency(row: Row) -> str:
    if row.step_median_ms is None:
        return "-"
    return f"{row.step_median_ms:.2f}/{row.step_p95_ms:.2f}/{row.step_max_ms:.2f}"


def _association(result: EstimatorResult | None) -> str:
    a = None if result is None else result.association
    if a is None:
        return "-"
    right = "-" if a.accuracy is None else f"{a.accuracy:.3f}"
    return f"{right}, {a.landmarks_mapped}/{'-' if a.landmarks_true is None else a.landmarks_true}"


Cell = Callable[[str, Row], str]

COLUMNS: tuple[tuple[str, Cell], ...] = (
    ("online RMSE m", lambda name, row: _m(row.online_rmse_m)),
    ("final RMSE m", lambda name, row: _m(row.final_rmse_m)),
    ("landmark RMSE m", lambda name, row: _m(row.landmark_rmse_m)),
    ("end gap m", lambda name, row: _m(row.endpoint_gap_m)),
    ("NEES", lambda name, row: _n(row.nees_mean)),
    ("NEES band", lambda name, row: _band(row)),
    ("steps in band", lambda name, row: _share(row.nees_in_bounds)),
    ("NIS med/mean", lambda name, row: _nis(row)),
    ("step ms med/p95/max", lambda name, row: _latency(row)),
    ("total s", lambda name, row: "-" if name.split()[0] == "odometry" else f"{row.total_s:.3f}"),
)
"""The table's columns after the estimator's name: header, and the cell of a row (``end gap m`` only on closed
paths, see :func:`path_closure`)."""


@dataclass(frozen=True)
class Closure:
    """How far the true path ends from its start."""

    gap_m: float
    """Distance between the last and first true positions, metres."""
    length_m: float
    """Length of the true path, metres."""

    @property
    def closed(self) -> bool:
        """Whether the path returns to its start (its gap is at most :data:`CLOSED_SHARE` of its length)."""
        return self.gap_m <= CLOSED_SHARE * self.length_m


def path_closure(results: Results) -> Closure | None:
    """The true path's end-to-start gap and length (positions with truth, in step order); None without truth,
    and with several robots (their paths, interleaved, are no one path)."""
    truth = results.truth_poses
    if truth is None or any(r.robots for r in results.estimators.values()):
        return None
    xy = truth[np.isfinite(truth[:, :2]).all(axis=1), :2]
    if len(xy) < 2:
        return None
    length = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))
    return Closure(float(np.linalg.norm(xy[-1] - xy[0])), length)


def title(results: Results) -> str:
    """The table's first line: source, robot (when the stream names one) and sizes."""
    robot = "" if results.robot is None else f", robot {results.robot}"
    robots = [counted(len(set(results.step_robots)), "robot")] if results.step_robots else []
    size = [*robots, counted(results.poses, "pose"), counted(results.landmarks, "landmark")]
    sightings = counted(results.observations, "landmark observation" if robots else "observation")
    return f"{results.source}{robot}: {', '.join([*size, sightings])}"


def table_lines(results: Results, rows: Mapping[str, Row]) -> list[str]:
    """The table of ``rows`` (by estimator name, ``odometry`` first), its title and its legend.

    Args:
        results: The replay the rows come from (title, truth, association scores, step count).
        rows: One row per estimator.
    """
    closure = path_closure(results)
    several = any(r.robots for r in results.estimators.values())
    shown = not several and (closure is None or closure.closed)
    columns = [c for c in COLUMNS if c[0] != "end gap m" or shown]
    header = ["estimator", *(h for h, _ in columns)]
    cells = [[name, *(cell(name, row) for _, cell in columns)] for name, row in rows.items()]
    if any(r.association is not None for r in results.estimators.values()):
        header.append("association right, mapped/true")
        for line in cells:
            line.append(_association(results.estimators.get(line[0])))
    widths = [max(len(h), *(len(line[k]) for line in cells)) for k, h in enumerate(header)]

    def laid(line: list[str]) -> str:
        return "  ".join([line[0].ljust(widths[0]), *(c.rjust(w) for c, w in zip(line[1:], widths[1:]))])

    out = [title(results), "", laid(header), "  ".join("-" * w for w in widths)]
    out += [laid(line) for line in cells]
    return [*out, "", *legend(results, rows, closure)]


def legend(results: Results, rows: Mapping[str, Row], closure: Closure | None) -> list[str]:
    """What the columns mean, one line per idea: online vs final, NEES and its band, the end gap."""
    lines = [
        "online: each pose as estimated when it was the newest (what the robot knew then); final: the last estimate."
    ]
    if any(row.nees_mean is not None for row in rows.values()):
        one_low, one_high = nees_bounds(1)
        lines += [
            "NEES: 3 if consistent; band: its 95% band for one run, consecutive steps' correlation counted, a lower "
            "bound on its",
            "width (errors the whole run shares widen it: compare --runs measures them); steps in band: each within "
            f"{one_low:.2f}..{one_high:.2f}.",
            "NIS: median/mean over steps of their sightings' NIS, 2 if consistent.",
        ]
    if any(r.association is not None for r in results.estimators.values()):
        lines += ["association right: share of sightings paired with the mapped landmark most of whose sightings "
                  "carry their id", "(a sighting left unused counts as wrong); mapped/true: landmarks mapped / true "
                  "landmarks sighted."]  # fmt: skip
    if any(r.robots for r in results.estimators.values()):
        lines.append("robot N: that robot's poses, in the frame of the figures over all robots; the map is shared.")
    elif closure is None:
        lines.append("end gap: estimated end to start; without truth it measures drift only if the robot came back.")
    elif closure.closed:
        lines.append(
            f"end gap: estimated end to start, shown as the true path closes (ends {closure.gap_m:.3f} m from its "
            f"start, within {CLOSED_SHARE:.0%} of its {closure.length_m:.1f} m)."
        )
    else:
        lines.append(
            f"end gap: not shown, the true path does not close (ends {closure.gap_m:.3f} m from its start, "
            f"{closure.gap_m / closure.length_m:.0%} of its {closure.length_m:.1f} m; "
            f"closed: within {CLOSED_SHARE:.0%})."
        )
    return lines


def notes(results: Results) -> list[str]:
    """Lines after the legend: alignment, convergence, outliers, sightings without ids, skipped input, an early
    stop."""
    out = []
    if results.alignment != "anchor":
        out.append(f"errors after {results.alignment} alignment")
    if results.map is not None and results.map.loaded:
        m = results.map
        how = "held fixed" if m.fixed else "one prior, joint covariance" if m.joint else "independent priors"
        out.append(f"started from a map of {counted(m.loaded, 'landmark')}{f' ({m.path})' if m.path else ''}: {how}")
    for name, result in results.estimators.items():
        d = result.details
        if name in ("ekf", "smoother") and "linearization" in d:  # compare's smoother rows name theirs (`` FEJ``)
            several = ""
            if d["linearization"] == "invariant" and result.robots:
                several = " (standard updates: several robots)" if name == "ekf" else " (re-centred: several robots)"
            linear = (
                ", pose covariance as linearized (--pose-covariance linear)"
                if d.get("pose_covariance") == "linear"
                else ""
            )
            out.append(f"{name}: {d['linearization']} linearization{several}{linear}")
        if rival := (d.get("association") or {}).get("rival_scans_sightings"):
            out.append(f"{name}: scans left out with {counted(rival, 'sighting')}: another pairing put the robot "
                       "elsewhere about as likely (--rival)")  # fmt: skip
        if "fixes_rejected" in d:
            out.append(f"{name}: fixes {d.get('fixes_used', 0)} used, {d['fixes_rejected']} refused by the gate")
        if d.get("global_failures"):
            failures = d["global_failures"]
            out.append(f"{name}: {counted(len(failures), 'background global solve')} failed, results kept without "
                       f"{'it' if len(failures) == 1 else 'them'} (first: {failures[0]})")  # fmt: skip
        if (again := d.get("paired_again")) and d.get("taken"):
            out.append(f"{name}: took the {d['initial']}'s final as it is (every sighting paired again there)")
        elif again:
            moved, dropped = counted(again["moved"], "sighting"), again["landmarks_dropped"]
            added = again.get("landmarks_added", 0)
            out.append(f"{name}: every sighting paired again at the end: {moved} paired otherwise than online, "
                       f"{dropped} landmarks dropped, {added} added ({again['solve_s']:.1f} s)")  # fmt: skip
        if "iterations" in d:
            state = "converged" if d.get("converged") else "NOT converged"
            out.append(
                f"{name}: {state} in {counted(d['iterations'], 'iteration')} "
                f"(cost {d['initial_cost']:.6g} -> {d['final_cost']:.6g})"
            )
        for robot, bias in (d.get("odometry_bias") or {}).items():
            out.append(f"{name}: odometry bias{'' if robot is None else f' of robot {robot}'}: {_bias_text(*bias)}")
        if "odometry_bias" not in d and _bias_beside(results, name):
            out.append(f"{name}: odometry taken as logged (only the EKF estimates its bias)")
        if "adapted_noise" in d and tuple(d["adapted_noise"]) != (1.0, 1.0):
            odometry, sensor = d["adapted_noise"]
            out.append(f"{name}: noise adapted to its innovations: odometry covariance x{odometry:.3g}, sensor "
                       f"x{sensor:.3g} (1: as declared; --no-adapt-noise: as declared throughout)")  # fmt: skip
        o = result.outliers
        if o is not None and (o.rejected or o.true_outliers):
            scored = (
                f"; of {o.true_outliers} marked outliers {o.caught} caught, {o.inliers_lost} inliers lost"
                if o.true_outliers is not None
                else ""
            )
            out.append(f"{name}: {o.rejected} of {counted(o.sightings, 'sighting')} rejected as outliers{scored}")
        w = result.without_id
        if w is not None and w.associated:
            out.append(f"{name}: {w.associated} of {counted(w.sightings, 'sighting')} without an id associated, "
                       f"{w.sightings - w.associated} not used")  # fmt: skip
        elif w is not None:
            out.append(f"{name}: {counted(w.sightings, 'sighting')} without an id not used (nothing associated them: "
                       "it pairs by id; the EKF and the smoother associate them)")  # fmt: skip
    out += coverage_notes(results)
    for name in results.left:
        out.append(f"{name}: left out, it takes one robot at a time and this stream has several")
    if results.input.skipped_lines:
        reasons = ", ".join(f"{k}: {v}" for k, v in sorted(results.input.skipped_by_reason.items()))
        out.append(f"input: {counted(results.input.skipped_lines, 'line')} skipped ({reasons})")
    if results.input.after_last_odometry:
        n = results.input.after_last_odometry
        out.append(f"input: {counted(n, 'sighting')} after the last odometry line, put on the last pose")
    if results.error == INTERRUPTED:
        out.append(f"stopped early: interrupted; figures cover the {counted(results.poses, 'pose')} before it")
    elif results.error:
        out.append(f"stopped early at bad input; figures cover the {counted(results.poses, 'pose')} before it")
    return out


def coverage_notes(results: Results) -> list[str]:
    """Which landmarks the landmark RMSE leaves out: once when every estimator leaves out the same, else each's."""
    left = {name: r.landmarks for name, r in results.estimators.items()}
    told = {name: c for name, c in left.items() if c is not None and (c.without_truth or c.not_estimated)}
    if not told:
        return []
    same = len({(c.scored, c.without_truth, c.not_estimated) for c in left.values() if c is not None}) == 1
    pairs = (
        [("landmark RMSE", next(iter(told.values())))]
        if same
        else [(f"{n}: landmark RMSE", c) for n, c in told.items()]
    )
    return [f"{who}: over {counted(c.scored, 'landmark')}; {_left_out(c)}" for who, c in pairs]


def _left_out(coverage: LandmarkCoverage) -> str:
    """The landmarks a landmark RMSE leaves out, a few ids each."""

    def ids(values: tuple) -> str:
        shown = ", ".join(map(str, values[:5]))
        return shown + (", ..." if len(values) > 5 else "")

    parts = []
    if coverage.without_truth:
        parts.append(f"left out {len(coverage.without_truth)} without truth ({ids(coverage.without_truth)})")
    if coverage.not_estimated:
        parts.append(f"{len(coverage.not_estimated)} with truth never mapped ({ids(coverage.not_estimated)})")
    return "; ".join(parts)


def format_results(results: Results) -> str:
    """Render results as a plain-text table (``online-slam replay``).

    Args:
        results: What :func:`online_slam.replay` returned.

    Returns:
        Lines of text, ending without a newline.
    """
    extra = notes(results)
    return "\n".join([*table_lines(results, robot_rows(results)), *([""] + extra if extra else [])])


def robot_rows(results: Results, rows: Mapping[str, Row] | None = None) -> dict[str, Row]:
    """The table's rows (``rows``, default the results'): each estimator's, followed by its rows per robot
    (``  robot 1``) when it has them."""
    out: dict[str, Row] = {}
    for name, row in (results.rows() if rows is None else rows).items():
        out[name] = row
        result = results.odometry if name == "odometry" else results.estimators.get(name)
        for robot, figures in ({} if result is None else result.robots).items():
            out[f"{name}  robot {robot}"] = figures.row()
    return out


def _bias_text(s: float, w: float, sd_s: float, sd_w: float) -> str:
    """A robot's odometry bias as the report says it (a part with no spread was not modelled)."""
    distance = f"distances read {abs(100 * s):.2f} +- {100 * sd_s:.2f}% {'long' if s >= 0 else 'short'}"
    if sd_s == 0.0:
        distance = "distances not modelled"
    turn = f"turns {abs(1e3 * w):.2f} +- {1e3 * sd_w:.2f} mrad/s {'counter-clockwise' if w >= 0 else 'clockwise'}"
    if sd_w == 0.0:
        turn = "turns not modelled"
    return f"{distance}, {turn} (each increment corrected by the estimate so far)"


def _bias_beside(results: Results, name: str) -> bool:
    """Whether another estimator of the run estimated the odometry bias while ``name`` did not."""
    return any("odometry_bias" in r.details for r in results.estimators.values())
