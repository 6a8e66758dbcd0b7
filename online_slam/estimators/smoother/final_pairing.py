"""The smoother's final on a stream whose ids it ignores: every sighting paired again, as the batch pairs one.

Online, each pairing is decided from the estimate of its moment and the window then settles in the basin those
decisions dug (benchmarks/RESULTS.md, "Pairing again at the end"). At the end of the stream the smoother hands its
final estimate, with each sighting's label, and every sighting the stream gave (its ``stream`` log: those the window
left out too) to the batch's procedure for a run without ids (:meth:`BatchEstimator.finish
<online_slam.estimators.batch.BatchEstimator.finish>`: a solve with its pairing, then
:func:`~online_slam.solvers.pairing.repair` twice), and reports what that gives. Why the whole stream and the two
rounds, not the window's log alone: RESULTS, "The smoother's final paired again".
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from online_slam.estimators.batch import BatchEstimator
from online_slam.estimators.batch_config import BatchConfig
from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.protocol import Estimate
from online_slam.estimators.smoother.config import SmootherConfig


def paired_again(estimate: Estimate, stream: ProblemLog, config: SmootherConfig) -> Estimate:
    """The final ``estimate`` with every sighting of ``stream`` paired again (poses (N, 3), landmarks (M', 2), the
    labels); the smoother's other figures kept. Landmarks whose every sighting went elsewhere leave the map (with
    their covariances); the covariances of the others are the smoother's, at its own final values.

    ``info["paired_again"]``: sightings whose landmark changed, landmarks dropped, seconds taken.
    """
    labels = estimate.info.get("labels")
    if labels is None or not len(estimate.landmark_ids) or len(labels) != len(stream.sightings()[0]):
        return estimate
    started = time.perf_counter()
    settings = BatchConfig(solver=config.final_solver, use_ids=False)
    if config.robust.reject_false_alarm > 0:  # 0 (the smoother never rejects): the batch's default bound pairs
        settings = replace(settings, reject_false_alarm=config.robust.reject_false_alarm)
    batch = BatchEstimator(settings)
    batch.log = stream
    paired = batch.finish(estimate)
    where = {lid: k for k, lid in enumerate(estimate.landmark_ids)}
    kept = np.array([where[lid] for lid in paired.landmark_ids], dtype=np.int64)
    covs, joint = estimate.landmark_covs, estimate.landmark_joint
    if joint is not None:
        flat = np.stack([2 * kept, 2 * kept + 1], axis=1).ravel()
        joint = joint[np.ix_(flat, flat)]
    new_labels = list(paired.info["labels"])
    report = {
        "moved": sum(a != b for a, b in zip(labels, new_labels)),
        "landmarks_dropped": len(estimate.landmark_ids) - len(kept),
        "solve_s": time.perf_counter() - started,
    }
    return replace(
        estimate,
        poses=paired.poses,
        landmark_ids=paired.landmark_ids,
        landmarks=paired.landmarks,
        info={**estimate.info, "labels": new_labels, "paired_again": report},
        landmark_covs=None if covs is None else covs[kept],
        landmark_joint=joint,
    )
