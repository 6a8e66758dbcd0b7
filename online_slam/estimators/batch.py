"""The batch solver: every pose and landmark at once — the reference every online estimator is compared with.

With several robots it solves every robot's poses together: each robot's odometry chain and start, landmark
sightings from any robot, and a range-bearing factor between two poses for each sighting of a robot. Robot
sightings are tested for outliers with the landmark sightings (one false-alarm rate over both)."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.batch_config import BatchConfig
from online_slam.estimators.problem import LoggedEstimator, ProblemLog
from online_slam.estimators.protocol import Estimate
from online_slam.factors.fixes import fix_gate_ratio, fix_report, fix_rows, without_fixes
from online_slam.factors.graph import (
    FactorGraph,
    evaluate,
    observation_chi2,
    robot_sighting_chi2,
    without_observations,
    without_robot_sightings,
)
from online_slam.factors.robust import outlier_threshold
from online_slam.models.observation import landmark_from_sighting
from online_slam.solvers.least_squares import SolveResult, solve
from online_slam.sources.events import GeneratedId
from online_slam.sources.landmark_map import LandmarkMap

Array = NDArray[np.float64]


def paired_ids(ids: tuple, origin: NDArray[np.int64]) -> tuple:
    """The ids of a pairing's landmarks: ``ids[origin]``, and for a landmark it added (origin -1) a fresh one,
    numbered after the highest :class:`~online_slam.sources.events.GeneratedId` in ``ids``."""
    first = 1 + max((lid.number for lid in ids if isinstance(lid, GeneratedId)), default=-1)
    added = np.cumsum(origin < 0) - 1
    return tuple(ids[o] if o >= 0 else GeneratedId(first + int(k)) for o, k in zip(origin, added))


def median_landmarks(graph: FactorGraph, poses: NDArray[np.float64], landmarks: NDArray[np.float64]) -> NDArray:
    """Each landmark at the coordinate-wise median of where its sightings put it from the given poses."""
    points = landmark_from_sighting(poses[graph.obs_pose], graph.obs_z, graph.obs_model)
    out = landmarks.copy()
    order = np.argsort(graph.obs_landmark, kind="stable")
    ids, starts = np.unique(graph.obs_landmark[order], return_index=True)
    for j, group in zip(ids, np.split(order, starts[1:])):
        out[j] = np.median(points[group], axis=0)
    out[graph.lp_landmark] = graph.lp_mean  # a map's landmark starts where the map puts it
    return out


ROBUST_MARGIN = 0.05
"""A batch that starts from another estimator's estimate keeps the outlier decisions that estimate implies
(:func:`trimmed` from it) unless the robust pass ends at a :func:`truncated_cost` lower by more than this fraction.
The online estimators judged each sighting with what came before and after it; a lower truncated cost is no proof
of a better estimate under structured contamination (20% wrong ids: 1.2% lower at twice the error), while a start
that lost the robot costs twice as much (benchmarks/RESULTS.md, "The batch judges from its start")."""
FIX_ROUNDS = 10
"""Most fixes the batch refuses after its solution, one at a time, the farthest off first (the others are refused at
the estimate it starts from, when another estimator's)."""
TRIMMED_ROUNDS = 3
"""Most times :func:`trimmed` judges the sightings again at its least-squares solution."""


def truncated_cost(
    graph: FactorGraph, poses: NDArray[np.float64], landmarks: NDArray[np.float64], bound: float
) -> float:
    """Half the squared whitened residuals with each sighting's (landmark or robot) capped at ``bound``: the cost
    of a solution together with its outlier decisions (an outlier costs the bound), which compares solutions that
    reject different sightings (Torr & Zisserman's MSAC)."""
    r = evaluate(graph, poses, landmarks)
    split = 3 * len(graph.prior_pose) + 3 * len(graph.odo_from)
    end = len(r) - 2 * len(graph.lp_landmark)  # landmark priors (a map): never capped
    s = np.sum(r[split:end].reshape(-1, 2) ** 2, axis=1)
    quadratic = float(r[:split] @ r[:split]) + float(r[end:] @ r[end:])
    return 0.5 * quadratic + 0.5 * float(np.minimum(s, bound).sum())


def trimmed(
    graph: FactorGraph, poses: Array, landmarks: Array, bound: float, cfg: BatchConfig
) -> tuple[SolveResult, NDArray[np.bool_], NDArray[np.bool_], float]:
    """Trimmed least squares from an estimate: sightings whose residual there exceeds ``bound`` are outliers, least
    squares on the rest, judged again at that solution until the decisions hold (at most :data:`TRIMMED_ROUNDS`).

    Returns the solution, the rejected landmark and robot sightings, and its :func:`truncated_cost`.
    """
    rejected = observation_chi2(graph, poses, landmarks) > bound
    rejected_robots = robot_sighting_chi2(graph, poses) > bound
    for _ in range(TRIMMED_ROUNDS):
        kept = without_robot_sightings(without_observations(graph, rejected), rejected_robots)
        result = solve(kept, poses, landmarks, cfg.solver)
        poses, landmarks = result.poses, result.landmarks
        judged = observation_chi2(graph, poses, landmarks) > bound
        judged_robots = robot_sighting_chi2(graph, poses) > bound
        if np.array_equal(judged, rejected) and np.array_equal(judged_robots, rejected_robots):
            break
        rejected, rejected_robots = judged, judged_robots
    return result, rejected, rejected_robots, truncated_cost(graph, poses, landmarks, bound)


class BatchEstimator(LoggedEstimator):
    """Collects every step; solves the full problem once, at the end of the stream.

    Until then its snapshots report the initial values it will start from (composed odometry, landmarks from
    their first observation). It starts from those unless ``finish`` is given other initial values.
    """

    name = "batch"
    online = False

    def __init__(self, config: BatchConfig | None = None) -> None:
        self.config = config or BatchConfig()
        self.log = ProblemLog(use_ids=self.config.use_ids)

    def load_map(self, landmark_map: LandmarkMap, fixed: bool = False) -> None:
        """Start from a map: a prior factor per landmark (see :meth:`ProblemLog.load_map`)."""
        self.log.load_map(landmark_map, fixed)

    def finish(self, initial: Estimate | None = None) -> Estimate:
        """Solve the full problem, from composed odometry or from another estimate (same poses, same ids).

        Without ids (``use_ids`` False) the initial estimate must carry ``info["labels"]``: the landmark id of
        each sighting (None: not used), whose landmarks it also gives. With ids, a sighting without one takes the
        landmark its label gives, where the initial estimate associated every such sighting (one label each, in
        order); otherwise it is not used.
        """
        started = time.perf_counter()
        if not self.config.use_ids:
            return self._finish_associated(initial, started)
        index = self.log.sightings()[1]
        ids, landmarks = list(self.log.landmark_ids), list(self.log.landmarks)
        labels = None if initial is None else initial.info.get("labels")
        without = np.flatnonzero(index < 0)
        if labels is not None and len(labels) == len(without) and len(without):
            assert initial is not None  # it gave the labels
            index = index.copy()
            where, given = {lid: k for k, lid in enumerate(ids)}, {lid: k for k, lid in enumerate(initial.landmark_ids)}
            for row, lid in zip(without, labels):
                if lid is None or lid not in given:
                    continue
                if lid not in where:  # a landmark the initial estimate made from sightings without ids
                    where[lid] = len(ids)
                    ids.append(lid)
                    landmarks.append(initial.landmarks[given[lid]])
                index[row] = where[lid]
        graph = self.log.graph(labels=index, n_landmarks=len(ids), ids=ids)
        poses = np.array(self.log.poses).reshape(-1, 3)
        estimate = self._solve(graph, poses, np.array(landmarks).reshape(-1, 2), tuple(ids), initial, started)
        if not len(without):
            return estimate
        used = index >= 0
        rejected = np.zeros(len(used), dtype=bool)  # per sighting given; one not used is not rejected
        rejected[used] = estimate.info["rejected"]
        labels = [ids[k] if k >= 0 else None for k in index[without]]  # as an estimator's: those without ids
        return replace(estimate, info={**estimate.info, "rejected": rejected, "labels": labels})

    def _finish_associated(self, initial: Estimate | None, started: float) -> Estimate:
        """Solve with the associations (and values) of another estimate, then pair every sighting again: first those
        it used, then, after a solve with that pairing, all (:func:`~online_slam.solvers.pairing.repair`). An estimate
        that did this already over the same stream (``info["paired_again"]``: the smoother's final) is taken as it
        is: annealing again from it lands elsewhere, not nearer (benchmarks/RESULTS.md "Pairing again at the end")."""
        labels = None if initial is None else initial.info.get("labels")
        n_sightings = len(self.log.sightings()[0])
        if initial is None or labels is None or len(labels) != n_sightings:
            raise ValueError("batch without ids needs the associations of an estimator that saw every sighting")
        if "paired_again" in initial.info:  # this procedure's answer already, over the same stream: taken as it is
            info = {"initial": initial.estimator, "taken": True, "labels": list(labels),
                    "paired_again": initial.info["paired_again"], "solve_s": time.perf_counter() - started}  # fmt: skip
            return Estimate(self.name, initial.poses.copy(), initial.landmark_ids, initial.landmarks.copy(), info)
        where = {lid: k for k, lid in enumerate(initial.landmark_ids)}
        index = np.array([where.get(lid, -1) if lid is not None else -1 for lid in labels], dtype=np.int64)
        graph = self.log.graph(labels=index, n_landmarks=len(initial.landmark_ids), ids=initial.landmark_ids)
        ids = tuple(initial.landmark_ids)
        landmarks = initial.landmarks.copy()
        plain = Estimate(initial.estimator, initial.poses, ids, landmarks)
        estimate = self._solve(graph, initial.poses.copy(), landmarks, ids, plain, started)
        bound = outlier_threshold(self.config.reject_false_alarm)
        used = np.flatnonzero(index >= 0)  # first the sightings the estimate used, then every one
        for only in (used, None) if len(used) else ():  # (the log holds each sighting once, in the stream's order)
            paired = self.log.pair_again(estimate.poses, estimate.landmarks, bound, self.config.solver, only)
            if paired is None:
                break
            ids = paired_ids(estimate.landmark_ids, paired.origin)
            likeliest = np.full(n_sightings, -1, dtype=np.int64)
            likeliest[used if only is not None else slice(None)] = paired.likeliest
            labels = [ids[k] if k >= 0 else None for k in likeliest]
            if only is None:
                estimate = replace(estimate, poses=paired.poses, landmark_ids=ids, landmarks=paired.landmarks)
                break
            graph = self.log.graph(labels=likeliest, n_landmarks=len(ids), ids=ids)
            start = Estimate(initial.estimator, paired.poses, ids, paired.landmarks)
            estimate = self._solve(graph, paired.poses.copy(), paired.landmarks.copy(), ids, start, started)
        return replace(estimate, info={**estimate.info, "labels": list(labels)})

    def _solve(
        self,
        graph: FactorGraph,
        poses: NDArray[np.float64],
        landmarks: NDArray[np.float64],
        landmark_ids: tuple,
        initial: Estimate | None,
        started: float,
    ) -> Estimate:
        """Levenberg-Marquardt on the graph (with the robust pass where the residuals call for one)."""
        if initial is not None:
            if len(initial.poses) != len(poses):
                raise ValueError("initial estimate has a different number of poses")
            poses = initial.poses.copy()
            where = {lid: k for k, lid in enumerate(initial.landmark_ids)}
            for k, lid in enumerate(landmark_ids):
                if lid in where:
                    landmarks[k] = initial.landmarks[where[lid]]
        cfg = self.config
        widened = self.log.fix_widenings()
        refused = np.zeros(len(graph.prior_pose), dtype=bool)
        if initial is not None:  # another estimator's estimate: fixes far off it are refused at once
            refused = fix_gate_ratio(graph, poses, widened) > 1.0
        result = solve(without_fixes(graph, refused), poses, landmarks, cfg.solver, loss=cfg.loss)
        for _ in range(FIX_ROUNDS):  # a GPS jump the solution bent to (its neighbours then read off too: worst first)
            ratio = fix_gate_ratio(without_fixes(graph, refused), result.poses, widened)
            if ratio.max(initial=0.0) <= 1.0:
                break
            refused[np.argmax(ratio)] = True
            result = solve(without_fixes(graph, refused), result.poses, result.landmarks, cfg.solver, loss=cfg.loss)
        graph = without_fixes(graph, refused)
        rejected = np.zeros(len(graph.obs_pose), dtype=bool)
        rejected_robots = np.zeros(len(graph.rob_from), dtype=bool)
        robust_pass = False
        if cfg.outliers == "auto" and cfg.loss is None and len(rejected) + len(rejected_robots):
            chi2_values = np.concatenate(
                [observation_chi2(graph, result.poses, result.landmarks), robot_sighting_chi2(graph, result.poses)]
            )
            bound = outlier_threshold(cfg.outlier_false_alarm / len(chi2_values))
            if chi2_values.max() > bound:  # contaminated: drop the outliers, least squares on the rest
                robust_pass = True
                reject_bound = outlier_threshold(cfg.reject_false_alarm)
                start = median_landmarks(graph, poses, landmarks)  # a first sight may be a wrong one
                robust = solve(graph, poses, start, cfg.solver, loss=cfg.outlier_loss)
                chosen = trimmed(graph, robust.poses, robust.landmarks, reject_bound, cfg)
                if initial is not None:  # another estimator's judgement: its estimate decides unless clearly worse
                    judged = trimmed(graph, poses, landmarks, reject_bound, cfg)
                    chosen = chosen if chosen[3] < (1.0 - ROBUST_MARGIN) * judged[3] else judged
                result, rejected, rejected_robots, _ = chosen
        info = {
            "iterations": result.iterations,
            "converged": result.converged,
            "initial_cost": result.initial_cost,
            "final_cost": result.final_cost,
            "message": result.message,
            "solve_s": time.perf_counter() - started,
            "initial": "odometry" if initial is None else initial.estimator,
            "robust_pass": robust_pass,
            "rejected": rejected,
            **fix_report(int((fix_rows(graph) & ~refused).sum()), int(refused.sum())),
        }
        if len(rejected_robots):
            info["robot_sightings"] = len(rejected_robots)
            info["robot_sightings_rejected"] = int(rejected_robots.sum())
        ids, positions = landmark_ids, result.landmarks
        if rejected.any():  # a landmark whose every sighting is an outlier is no landmark: leave it out of the map
            supported = np.zeros(len(ids), dtype=bool)
            supported[graph.obs_landmark[~rejected]] = True
            supported[graph.lp_landmark] = True  # a map's landmark stays
            ids, positions = tuple(lid for lid, ok in zip(ids, supported) if ok), positions[supported]
            info["landmarks_dropped"] = int((~supported).sum())
        return Estimate(self.name, result.poses, ids, positions, info)
