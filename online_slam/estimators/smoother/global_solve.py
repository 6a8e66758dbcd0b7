"""The smoother's global relinearization: when it runs, the background job, and what its result revises.

Every ``global_every`` steps (or N / 20 after N steps) every factor seen so far is re-solved from a copy of the
current estimate (:func:`~online_slam.estimators.smoother.relinearize.solve_all`), in a background thread
started here (:func:`start_job`); its result is handed over ``global_delay`` steps later (or N / 50), waiting for the
thread if need be (:func:`finish_job`). The outcome does not depend on timing because the job reads a copy, is
joined at a fixed step, and factors sparse (plain C, no threaded BLAS whose sums could depend on the other thread;
:func:`~online_slam.estimators.smoother.relinearize.solve_all`). A job that raises is reported, not dropped
(``Relinearization.failures``, the step's ``global_failed``, the estimate's ``global_failures``). The hand-over
revises the history and re-anchors the prior at the revised values (:func:`revise`). All threading of the smoother
is in this module.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.smoother.config import (
    GLOBAL_DELAY_GROWTH,
    GLOBAL_GROWTH,
    GLOBAL_JUMP_TURN,
    SmootherConfig,
)
from online_slam.estimators.smoother.prior import Prior, reanchored
from online_slam.estimators.smoother.relinearize import (
    history_graph,
    inlier_graph,
    refine_recent,
    rejudged,
    robot_rows,
    several_history_graph,
    solve_all,
)
from online_slam.estimators.smoother.window import Window
from online_slam.factors.graph import FactorGraph, observation_chi2
from online_slam.factors.robust import RobustLoss
from online_slam.geometry.se2 import between, compose, rotation
from online_slam.solvers.least_squares import SolverConfig, SolveResult

Array = NDArray[np.float64]
Decisions = list[tuple[int, NDArray[np.bool_]]]
"""(pose, which of its sightings were judged outliers) for each pose when it left the window."""


@dataclass(eq=False)
class GlobalJob:
    """A global solve running in the background (or finished, or restored from a checkpoint: a checkpoint holds a
    finished job, its result or its error)."""

    handover: int
    """Step count at which its result is applied."""
    n_poses: int
    """Poses in the state it started from (0 .. n_poses - 1)."""
    result: SolveResult | None = None
    """Its solution, once solved."""
    error: str | None = None
    """Why it gave no solution, if it failed."""
    released: int = 0
    """Landmarks released from the prior when it started (``Progress.released``). If consensus released more
    before the hand-over, its solution is of a map since corrected: the hand-over solves again at once instead
    (a stale solution, applied, pulled the online estimate back to the wrong map for hundreds of steps;
    benchmarks/RESULTS.md, "Refused hand-overs judged again")."""
    thread: threading.Thread | None = field(default=None, init=False)
    """The thread solving it, until it is joined (:func:`finish_job`)."""


@dataclass(eq=False)
class Relinearization:
    """What global relinearizations need and how they went."""

    log: ProblemLog
    """Every factor seen so far."""
    decisions: Decisions = field(default_factory=list)
    """The sightings judged outliers when their pose left the window (left out of global solves)."""
    since: int = 0
    """Steps since the last global relinearization started."""
    job: GlobalJob | None = None
    """The pending background solve."""
    solves: int = 0
    """Global relinearizations kept."""
    rejections: int = 0
    """Global relinearizations not kept (the solve did not reconcile the history)."""
    robot_folded: list[int] = field(default_factory=list)
    """The robot sightings folded into the prior (their numbers in the log's sightings)."""
    robot_rejected: list[int] = field(default_factory=list)
    """The robot sightings judged outliers when they left the window (left out of global solves)."""
    failures: list[str] = field(default_factory=list)
    """The errors of background solves that raised, in order (the smoother went on without their results)."""

    def __deepcopy__(self, memo: dict[int, Any]) -> Relinearization:
        """A copy sharing what never changes in place: the log's arrays, the decisions' arrays, and the job (a
        copy that finishes it joins the same thread and reads the same result)."""
        folded, rejected = list(self.robot_folded), list(self.robot_rejected)
        return replace(self, log=self.log.frozen(), decisions=list(self.decisions), robot_folded=folded,
                       robot_rejected=rejected, failures=list(self.failures))  # fmt: skip


@dataclass(frozen=True)
class GlobalInputs:
    """What a global solve needs, copied from the smoother (safe to read in another thread)."""

    log: ProblemLog
    """The log, frozen."""
    decisions: Decisions
    """The outlier decisions so far."""
    poses: Array
    """Every pose's current estimate, shape (N, 3)."""
    landmarks: Array
    """Every landmark's current estimate, shape (M, 2)."""
    robot_rejected: tuple[int, ...] = ()
    """The robot sightings judged outliers so far."""


@dataclass(frozen=True)
class Revision:
    """A global solution applied to the smoother's state."""

    history: Array
    """Revised estimates of the poses that left the window, shape (N - P, 3)."""
    landmarks: Array
    """Revised landmark estimates, shape (M, 2)."""
    prior: Prior | None
    """The re-anchored prior, or None when the prior does not move (none, or not on the oldest window pose)."""


def global_solver(config: SmootherConfig) -> SolverConfig:
    """The window's solver settings with ``global_iterations`` iterations."""
    return replace(config.solver, max_iterations=config.global_solve.iterations)


def is_due(config: SmootherConfig, state: Relinearization, steps: int, window: Window) -> bool:
    """Whether a global relinearization is to start after ``steps`` steps (none pending, every pose solved)."""
    every = config.global_solve.every and max(config.global_solve.every, steps // GLOBAL_GROWTH)
    due = every and state.since >= every and len(window.history) and not window.unsolved
    return bool(due) and state.job is None


def jumped(config: SmootherConfig, turn: float) -> bool:
    """Whether a window solve that turned the window's oldest pose by ``turn`` (rad) jumped
    (:data:`~.config.GLOBAL_JUMP_TURN`); never with global relinearization off."""
    return bool(config.global_solve.every) and abs(turn) > GLOBAL_JUMP_TURN


def log_matches(log: ProblemLog, window: Window) -> bool:
    """Whether the log's variables are the smoother's: every pose (history and window) and landmark."""
    poses = len(window.history) + len(window.indices)
    return len(log.poses) == poses and log.landmark_ids == tuple(window.landmark_ids)


def global_inputs(state: Relinearization, window: Window) -> GlobalInputs | None:
    """What a global solve needs, copied; None when the log does not match the window's variables."""
    log = state.log
    if not log_matches(log, window):
        return None
    poses = window.all_poses()
    return GlobalInputs(
        log.frozen(), list(state.decisions), poses, window.landmarks.copy(), tuple(state.robot_rejected)
    )


def solve_now(inputs: GlobalInputs, solver: SolverConfig, loss: RobustLoss | None) -> SolveResult:
    """Every factor but the judged outliers, solved from the given values (pure: safe in a thread)."""
    return solve_all(inputs.log, inputs.decisions, inputs.poses, inputs.landmarks, solver, loss, inputs.robot_rejected)


def start_job(inputs: GlobalInputs, config: SmootherConfig, steps: int, name: str, released: int) -> GlobalJob:
    """Solve every factor in a background thread; the result is to be handed over ``global_delay`` steps (or
    N / 50 after N steps) after step ``steps``; ``released``: landmarks released from the prior so far."""
    solver = global_solver(config)
    delay = max(config.global_solve.delay, steps // GLOBAL_DELAY_GROWTH)
    job = GlobalJob(handover=steps + delay, n_poses=len(inputs.poses), released=released)

    def work() -> None:
        try:
            job.result = solve_now(inputs, solver, config.robust.loss)
        except Exception as exc:  # noqa: BLE001 - handed over as "no result"; the smoother goes on without it
            job.error = repr(exc)

    job.thread = threading.Thread(target=work, name=f"{name} global relinearization", daemon=True)
    job.thread.start()
    return job


def finish_job(job: GlobalJob | None) -> GlobalJob | None:
    """The job, finished (its thread joined); None if there is none."""
    if job is not None and job.thread is not None:
        job.thread.join()
        job.thread = None
    return job


def revise(
    result: SolveResult,
    n_poses: int,
    at_once: bool,
    window: Window,
    prior: Prior | None,
    state: Relinearization,
    config: SmootherConfig,
    decisions: Decisions | None = None,
) -> Revision | None:
    """The history revised with a global solution over poses ``0..n_poses-1``, and the prior re-anchored.

    ``at_once``: the solution is of the current state (window poses and landmarks take its values too);
    otherwise it is of an earlier one (handed over from the background): window poses and landmark estimates
    keep their newer values, poses marginalized since keep theirs, and the prior is re-anchored at the
    revised history and the current oldest window pose. ``decisions``: the outlier decisions the history's
    factors are taken with (default: the state's).

    Returns:
        The revision, or None when the re-anchored prior is rejected
        (:func:`~online_slam.estimators.smoother.prior.reanchored`).
    """
    if window.several:
        return revise_several(result, n_poses, at_once, window, prior, state, config)
    oldest = window.indices[0]
    history, oldest_value, landmarks = followed(result, n_poses, at_once, window)
    if prior is None or prior.pose != oldest:
        return Revision(history, landmarks, None)
    past = history_graph(inlier_graph(state.log, state.decisions if decisions is None else decisions), oldest)
    values = np.vstack([history, oldest_value[None]])
    if not at_once and oldest >= n_poses:  # bring the poses that left since to agree with the solution
        values, landmarks = refine_recent(past, n_poses, values, landmarks, global_solver(config), config.robust.loss)
        history = values[:-1]
    return _revision(history, landmarks, prior, past, values, at_once, window, config)


def information_max(config: SmootherConfig) -> int:
    """Most landmarks the prior may hold for re-anchoring to relinearize its covariance: every count with
    First-Estimates Jacobians (its linearization point moves, so its information must follow), else the
    setting."""
    return np.iinfo(np.int64).max if config.fej else config.global_solve.information_max


def _revision(
    history: Array,
    landmarks: Array,
    prior: Prior,
    past: FactorGraph,
    values: Array,
    at_once: bool,
    window: Window,
    config: SmootherConfig,
) -> Revision | None:
    """The revision with the prior re-anchored over the history's factors ``past`` at ``values`` (None: refused)."""
    landmarks_at = anchor_landmarks(landmarks, at_once, window, config)
    anchored = reanchored(
        prior, past, values, landmarks_at, config.robust.loss, information_max(config), config.carried
    )
    return None if anchored is None else Revision(history, landmarks, anchored)


def anchor_landmarks(landmarks: Array, at_once: bool, window: Window, config: SmootherConfig) -> Array:
    """The landmark values the prior is re-anchored at: the solution's (``landmarks``), or with First-Estimates
    Jacobians and a solve handed over from the background, the window's current ones. The window keeps its newer
    landmark values then, and FEJ takes their Jacobians at the prior's point: at the solution's values, which wrong
    sightings judged since may have left far behind, its solves diverged (``grid``, 10% wrong ids)."""
    return window.landmarks if config.fej and not at_once else landmarks


def followed(result: SolveResult, n_poses: int, at_once: bool, window: Window) -> tuple[Array, Array, Array]:
    """(history, oldest window pose, landmarks) with the solution's values where it has them.

    Poses that left the window after the solve started, and landmarks first seen since, follow the solution
    rigidly: their geometry relative to the last solved pose is kept (it holds newer data).
    """
    oldest = window.indices[0]
    history = window.history.view().copy()
    revised = min(oldest, n_poses)
    history[:revised] = result.poses[:revised]
    landmarks = window.landmarks.copy()
    landmarks[: len(result.landmarks)] = result.landmarks
    oldest_value = result.poses[oldest] if at_once else window.poses[oldest].copy()
    if not at_once and oldest >= n_poses:
        anchor = n_poses - 1
        before, after = window.history.view()[anchor], result.poses[anchor]
        history[anchor + 1 :] = compose(after, between(before, window.history.view()[anchor + 1 :]))
        oldest_value = compose(after, between(before, oldest_value))
        new = landmarks[len(result.landmarks) :]
        if len(new):
            local = (new - before[:2]) @ rotation(before[2])  # R(before)^T (l - t)
            landmarks[len(result.landmarks) :] = local @ rotation(after[2]).T + after[:2]
    return history, oldest_value, landmarks


def revise_several(
    result: SolveResult,
    n_poses: int,
    at_once: bool,
    window: Window,
    prior: Prior | None,
    state: Relinearization,
    config: SmootherConfig,
) -> Revision | None:
    """:func:`revise` with several robots: the history takes the solution's values, the prior is re-anchored at
    them over the factors it folded in (:func:`~.relinearize.several_history_graph`).

    Poses the solution does not have (that began after it started) follow their robot's last solved pose rigidly,
    and are not re-solved; landmarks first seen since keep their values. The prior's poses (window poses) take the
    solution's values only ``at_once``.
    """
    values = window.all_poses().copy()
    current = values.copy()
    left = np.array(window.left, dtype=np.int64)
    solved = left[left < n_poses]
    values[solved] = result.poses[solved]
    kept = np.zeros(0, dtype=np.int64) if prior is None else prior.poses
    if at_once:
        values[kept] = result.poses[kept]
    names = state.log.robots[: len(values)]
    code = {robot: k for k, robot in enumerate(dict.fromkeys(names))}
    robots = np.array([code[robot] for robot in names], dtype=np.int64)
    for robot in np.unique(robots[n_poses:]):
        mine = np.flatnonzero(robots == robot)
        before = mine[mine < n_poses]
        later = np.intersect1d(mine[mine >= n_poses], np.r_[left, kept])
        if len(before) and len(later):
            anchor = before[-1]
            values[later] = compose(result.poses[anchor], between(current[anchor], current[later]))
    landmarks = window.landmarks.copy()
    landmarks[: len(result.landmarks)] = result.landmarks
    if prior is None:
        return Revision(values[left], landmarks, None)
    log = state.log
    graph = inlier_graph(log, state.decisions, state.robot_rejected)
    past = several_history_graph(graph, left, kept, robot_rows(log.seen, state.robot_folded))
    return _revision(values[left], landmarks, prior, past, values, at_once, window, config)


def rejudged_solve(
    result: SolveResult,
    n_poses: int,
    at_once: bool,
    window: Window,
    prior: Prior | None,
    r: Relinearization,
    config: SmootherConfig,
    reject_bound: float,
) -> tuple[SolveResult, Revision, Decisions] | None:
    """A global solution that does not reconcile the history, tried once more: the history's sightings judged
    again at it (a sighting judged an outlier when its pose left the window, at an estimate a wrong association
    had pulled, comes back if the solution agrees with it; one folded in goes out if it does not; chi-square
    ``reject_bound``), and every factor solved now with those decisions. None when no decision changes, without a
    robust loss, with several robots (not tried yet), or when that solution does not reconcile the history
    either."""
    loss = config.robust.loss
    if loss is None or not np.isfinite(reject_bound) or not r.decisions or window.several:
        return None
    if not log_matches(r.log, window):
        return None
    history, _, landmarks = followed(result, n_poses, at_once, window)
    values = np.vstack([history, result.poses[len(history) :] if at_once else window.values()])
    graph = r.log.graph()
    judged = rejudged(graph, r.decisions, observation_chi2(graph, values, landmarks) > reject_bound)
    if all(np.array_equal(a, b) for (_, a), (_, b) in zip(r.decisions, judged)):
        return None
    again = solve_all(r.log, judged, values, landmarks, global_solver(config), loss)
    revision = revise(again, len(values), True, window, prior, r, config, judged)
    return None if revision is None else (again, revision, judged)
