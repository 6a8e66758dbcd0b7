"""MRCLAM Dataset 6, each robot: the default smoother's online and final ATE beside GTSAM iSAM2 + Huber.

iSAM2 also runs without a kernel (plain least squares, the core of our default cost): the difference between its
two figures is what the loss does, apart from the back-end.

Both run on the same front-end steps of our conversion (poses at sighting times, odometry integrated from the
commands, its noise along the axes of the pose reached). iSAM2: relinearization threshold 0.01 every step, a
Huber kernel of 1.345 sigmas on the sightings; its between factors take our odometry covariance rotated into their
frame (:func:`~online_slam.gtsam_peer.between_covariance`). Errors: position RMSE against Vicon at the poses
Vicon covers, in the dataset's frame (the start pose is Vicon's), each pose as estimated when newest (online) and
at the end (final).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.ekf import drive
from online_slam import gtsam_peer
from online_slam.estimators.smoother import SlidingWindowSmoother
from online_slam.importers.resolve import open_source

HUBER = 1.345
"""iSAM2's Huber kernel width (sigmas): the usual 95%-efficiency constant."""


@dataclass(frozen=True)
class RobotRow:
    """One robot's figures."""

    robot: int
    """MRCLAM robot number."""
    poses: int
    """Poses (steps) in the stream."""
    online_m: float
    """Default smoother: RMSE of each pose as estimated when newest."""
    final_m: float
    """Default smoother: RMSE of its final estimate."""
    median_ms: float
    """Default smoother: median step time."""
    peer_online_m: float | None
    """iSAM2 + Huber: online RMSE (None without gtsam)."""
    peer_final_m: float | None
    """iSAM2 + Huber: final RMSE."""
    peer_median_ms: float | None
    """iSAM2 + Huber: median step time."""
    plain_online_m: float | None
    """iSAM2 without a kernel (plain least squares): online RMSE."""
    plain_final_m: float | None
    """iSAM2 without a kernel: final RMSE."""


def _rmse(poses: np.ndarray, truth: np.ndarray, rows: list[int]) -> float:
    return float(np.sqrt(np.mean(np.sum((poses[rows, :2] - truth[:, :2]) ** 2, axis=1))))


def run_robot(folder: str | Path, robot: int) -> RobotRow:
    """Replay one robot with the default smoother and (when gtsam is there) iSAM2 + Huber on the same steps."""
    _, events = open_source(str(folder), robot=robot)
    smoother = SlidingWindowSmoother()
    seconds, ours, steps, truth_by_index = drive(smoother, events)
    final = smoother.finish().poses
    rows = [k for k, s in enumerate(steps) if s.index in truth_by_index]
    truth = np.array([truth_by_index[steps[k].index] for k in rows])
    peer = plain = None
    if gtsam_peer.available():
        peer, plain = gtsam_peer.isam2_online(steps, huber=HUBER), gtsam_peer.isam2_online(steps)
    return RobotRow(
        robot,
        len(steps),
        _rmse(ours, truth, rows),
        _rmse(final, truth, rows),
        1e3 * float(np.median(seconds)),
        None if peer is None else _rmse(peer.poses, truth, rows),
        None if peer is None else _rmse(peer.final_poses, truth, rows),
        None if peer is None else 1e3 * float(np.median(peer.step_s)),
        None if plain is None else _rmse(plain.poses, truth, rows),
        None if plain is None else _rmse(plain.final_poses, truth, rows),
    )
