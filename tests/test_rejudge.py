"""The smoother's outlier decisions judged again when a global solution does not reconcile the history."""

from __future__ import annotations

import dataclasses

import numpy as np

from online_slam.engine import Engine
from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.smoother.relinearize import outlier_mask, rejudged
from online_slam.factors.graph import observation_chi2
from online_slam.sources.worlds import square_world


def _square_graph_at_truth():
    engine = Engine([])
    steps = [r.step for e in square_world() for r in engine.push(e)]
    last = engine.close()
    steps += [last.step] if last is not None else []
    log = ProblemLog()
    for step in steps:
        log.add(step)
    truth = engine.frontend.truth
    poses = np.array([truth.poses[s.index] for s in steps])
    landmarks = np.array([truth.landmarks[j] for j in log.landmark_ids])
    return log.graph(), poses, landmarks


def test_decisions_judged_again_follow_the_values_they_are_judged_at() -> None:
    graph, poses, landmarks = _square_graph_at_truth()
    seen = np.unique(graph.obs_pose)[:4]
    wrong = int(np.searchsorted(graph.obs_pose, seen[1]))  # the first sighting of the second pose: made wrong
    z = graph.obs_z.copy()
    z[wrong] += [3.0, 1.0]
    graph = dataclasses.replace(graph, obs_z=z)
    counts = [int(np.sum(graph.obs_pose == g)) for g in seen]
    # judged at a pulled estimate: every sighting of the first pose out, the wrong one in
    decisions = [(int(g), np.full(n, k == 0)) for k, (g, n) in enumerate(zip(seen, counts))]
    decisions.append((int(seen[-1]) + 1000, np.zeros(2, dtype=bool)))  # a pose the graph does not reach: kept
    outliers = observation_chi2(graph, poses, landmarks) > 13.8
    judged = rejudged(graph, decisions, outliers)
    assert not judged[0][1].any()  # the correct sightings come back
    assert judged[1][1][0] and not judged[1][1][1:].any()  # the wrong one goes out
    assert judged[-1][1] is decisions[-1][1]
    assert outlier_mask(graph, judged).sum() == 1
