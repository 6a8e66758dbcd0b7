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
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.linalg import splu

from online_slam.estimators.batch import BatchEstimator
from online_slam.estimators.batch_config import BatchConfig
from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.protocol import Estimate
from online_slam.estimators.smoother.config import SmootherConfig
from online_slam.factors.graph import layout, linearize

Array = NDArray[np.float64]
Index = NDArray[np.int64]

UNSEEN = 1e-12
"""Information added to every variable, so that a landmark whose sightings all went elsewhere leaves the rest
invertible (negligible beside any factor's)."""


def born_covariances(stream: ProblemLog, paired: Estimate, labels: list, born: Index) -> Array:
    """Covariances (b, 2, 2) of ``paired``'s landmarks ``born`` (b,): the inverse of the whole run's information
    (``J^T J`` of every factor, its sightings on ``labels``) at ``paired``'s values."""
    where = {lid: k for k, lid in enumerate(paired.landmark_ids)}
    index = np.array([where.get(lid, -1) if lid is not None else -1 for lid in labels], dtype=np.int64)
    graph = stream.graph(labels=index, n_landmarks=len(paired.landmark_ids), ids=paired.landmark_ids)
    sparse = layout(graph)
    _, J = linearize(graph, sparse, paired.poses, paired.landmarks)
    columns = np.stack([sparse.landmark_column[born], sparse.landmark_column[born] + 1], axis=1).ravel()
    unit = np.zeros((J.shape[1], len(columns)))
    unit[columns, np.arange(len(columns))] = 1.0
    information = (J.T @ J + sp.identity(J.shape[1]) * UNSEEN).tocsc()  # a landmark nothing sees stays apart
    solved = splu(information).solve(unit)[columns]
    return np.stack([solved[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] for k in range(len(born))])


def paired_again(estimate: Estimate, stream: ProblemLog, config: SmootherConfig) -> Estimate:
    """The final ``estimate`` with every sighting of ``stream`` paired again (poses (N, 3), landmarks (M', 2), the
    labels); the smoother's other figures kept. Landmarks whose every sighting went elsewhere, or that were merged,
    leave the map (with their covariances); the covariances of the others are the smoother's, at its own final
    values, and those of landmarks the pairing added are the whole run's (:func:`born_covariances`; the joint
    covariance is then left out).

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
    kept = np.array([where.get(lid, -1) for lid in paired.landmark_ids], dtype=np.int64)
    covs, joint = estimate.landmark_covs, estimate.landmark_joint
    new_labels = list(paired.info["labels"])
    born = np.flatnonzero(kept < 0)  # the ids the pairing gave
    dropped = len(estimate.landmark_ids) - (len(kept) - len(born))
    if len(born):  # landmarks the pairing added: covariances of the whole run's information; no joint
        joint = None
        if covs is not None:
            covs = np.concatenate([covs, born_covariances(stream, paired, new_labels, born)])
            kept[born] = len(estimate.landmark_ids) + np.arange(len(born))
    elif joint is not None:
        flat = np.stack([2 * kept, 2 * kept + 1], axis=1).ravel()
        joint = joint[np.ix_(flat, flat)]
    report = {
        "moved": sum(a != b for a, b in zip(labels, new_labels)),
        "landmarks_dropped": dropped,
        "landmarks_added": len(born),
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
