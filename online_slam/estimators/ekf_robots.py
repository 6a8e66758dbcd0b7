"""Several robots in one EKF (centralized): every robot's newest pose in the state, then the landmarks.

The state is ``[pose of the active robot, poses of the other robots..., l1x, l1y, ...]``: the robot whose step
runs is swapped into the first block (rows and columns of ``x`` and ``P`` permuted, exact), so that
prediction, landmark sightings and new landmarks work on it as with one robot. A robot's odometry predicts its
block alone (with its cross-covariances); a robot's start adds its block before the landmarks. A sighting of a
robot updates both robots' blocks (range and bearing to the seen position, gated on its NIS as landmark
sightings are). It links the sighting pose to the seen robot's newest pose at the step's time; when that pose
may still come (a pose of the same time later in step order) the sighting waits until it has come, or until
a step of a later time begins. With one robot, nothing here runs but the swap's no-op.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.ekf_state import EkfState, WaitingSighting
from online_slam.factors.graph import robot_sighting_residual_with_jacobians
from online_slam.frontend.steps import Step
from online_slam.geometry.angles import wrap
from online_slam.geometry.pose_moments import reported
from online_slam.sources.events import RobotId

Array = NDArray[np.float64]


def landmark_columns(indices: NDArray[np.int64], offset: int) -> NDArray[np.int64]:
    """State columns of landmarks by index, the landmarks starting at column ``offset``: (k,) -> (2k,)."""
    return (offset + 2 * indices[:, None] + np.arange(2)).reshape(-1)


class SeveralRobots:
    """The EKF's handling of several robots (a mixin of :class:`~online_slam.estimators.ekf.EkfSlam`)."""

    several_robots = True
    state: EkfState
    config: EkfConfig
    x: Array
    P: Array
    _gate: float

    _apply: Callable[[Array, Array, Array], None]
    """The filter's update (``x += K y``, ``P -= K S K^T``)."""
    _resized: Callable[[], None]
    """The filter's bookkeeping after the state's size changed."""
    _pose_end: int
    _offset: int
    _inserted: Callable[[int, Array, Array], None]
    _bias_block: Callable[[Step], Array]
    _swap_biases: Callable[[NDArray[np.int64], int], None]

    def _wrap_headings(self) -> None:
        """Wrap every robot's heading."""
        if len(self.state.robots) == 1:
            self.x[2, 0] = wrap(self.x[2, 0])
        else:
            self.x[2 : self._pose_end : 3, 0] = wrap(self.x[2 : self._pose_end : 3, 0])

    def _activate(self, robot: RobotId | None) -> None:
        """Swap the robot's block into the first one (a permutation of the state; nothing if it is there)."""
        robots = self.state.robots
        if len(robots) == 1 or robots[0] == robot:
            return
        k = robots.index(robot)
        order = np.arange(len(self.x))
        order[:3], order[3 * k : 3 * k + 3] = order[3 * k : 3 * k + 3], order[:3].copy()
        self._swap_biases(order, k)
        self.x = self.x[order]
        self.P = self.P[np.ix_(order, order)]
        columns: tuple[list[Any], ...] = (robots, self.state.robot_steps, self.state.robot_times)
        for column in columns:
            column[0], column[k] = column[k], column[0]

    def _add_robot(self, step: Step) -> None:
        """A robot begins: its start pose becomes a block after the poses (its bias, when modelled, after the
        biases), then the active one."""
        if len(self.state.robots) == 1:  # every pose so far was the first robot's, in step order
            self.state.moved = list(range(len(self.state.history)))
        if self.state.biased:
            self._inserted(self._offset, np.zeros(2), self._bias_block(step))
        prior_cov = np.zeros((3, 3)) if step.prior_cov is None else step.prior_cov
        self._inserted(self._pose_end, cast(Array, step.prior), prior_cov)
        self.state.robots.append(step.robot)
        self.state.robot_steps.append(step.index)
        self.state.robot_times.append(step.t)
        self._resized()
        self._activate(step.robot)

    def _moved_on(self) -> None:
        """The active robot's newest pose is complete: with several robots, remember which step it was."""
        if len(self.state.robots) > 1:
            self.state.moved.append(self.state.robot_steps[0])

    def robot_poses(self) -> dict[RobotId | None, tuple[int, float, Array, Array]]:
        """Each robot's newest pose by robot: (its step index, its time, ``[x, y, theta]`` (3,), its covariance
        (3, 3), as :attr:`~.EkfConfig.pose_covariance` says), copies."""
        out = {}
        for k, robot in enumerate(self.state.robots):
            block = slice(3 * k, 3 * k + 3)
            pose, cov = self.x[block, 0].copy(), reported(self.P[block, block], self.config.pose_covariance)
            out[robot] = (self.state.robot_steps[k], self.state.robot_times[k], pose, cov)
        return out

    def _robots_trajectory(self) -> Array:
        """Every pose in step order, each as it was when its robot moved on (the newest ones as they are)."""
        history, moved = self.state.history.view(), self.state.moved
        out = np.zeros((len(history) + len(self.state.robots), 3))
        out[moved] = history
        out[self.state.robot_steps] = self.x[: self._pose_end, 0].reshape(-1, 3)
        return out

    # -- robot sightings ---------------------------------------------------------------------------
    def _sight_robots(self, step: Step) -> None:
        """After the step's own update: waiting sightings of this robot's pose, then the step's sightings."""
        waiting = self.state.waiting
        now = [w for w in waiting if w.seen == step.robot and w.t == step.t]
        if now:
            self.state.waiting = [w for w in waiting if not (w.seen == step.robot and w.t == step.t)]
        for robot, z, R in zip(step.robots_seen, step.z_robots, step.z_robots_cov):
            # Cast: a step with robot sightings names its robot (a stream's robots are all named).
            sighting = WaitingSighting(step.index, cast(RobotId, step.robot), robot, step.t, z, R)
            known = robot in self.state.robots
            if known and self.state.robot_times[self.state.robots.index(robot)] == step.t:
                now.append(sighting)
            else:  # the seen robot's pose of this time may come later in step order
                self.state.waiting.append(sighting)
        for sighting in now:
            self._robot_update(sighting)

    def _sightings_before(self, t: float) -> None:
        """Apply the waiting sightings of times before ``t``: every pose of their time has come."""
        due = [w for w in self.state.waiting if w.t < t]
        self.state.waiting = [w for w in self.state.waiting if w.t >= t]
        for sighting in due:
            self._robot_update(sighting)

    def _robot_update(self, sighting: WaitingSighting) -> None:
        """Update both robots' blocks with one sighting (gated on its NIS); dropped if either pose is gone."""
        robots = self.state.robots
        if sighting.seen not in robots or self.state.robot_steps[robots.index(sighting.robot)] != sighting.pose:
            self.state.robot_sightings["dropped"] += 1
            return
        a, b = 3 * robots.index(sighting.robot), 3 * robots.index(sighting.seen)
        columns = np.r_[a : a + 3, b : b + 3]
        poses = self.x[columns, 0].reshape(2, 1, 3)
        e, J_a, J_b = robot_sighting_residual_with_jacobians(poses[0], poses[1], sighting.z[None])
        H = np.concatenate([J_a[0], J_b[0]], axis=1)
        PHt = self.P[:, columns] @ H.T
        S = H @ PHt[columns] + sighting.cov
        y = -e[0]
        nis = float(y @ np.linalg.solve(S, y))
        if not nis <= self._gate:
            self.state.robot_sightings["gated"] += 1
            return
        self._apply(PHt, S, y)
        self.state.robot_sightings["used"] += 1

    def _robot_info(self) -> dict[str, Any]:
        """What became of the robot sightings (nothing with one robot)."""
        if len(self.state.robots) == 1:
            return {}
        return {f"robot_sightings_{what}": count for what, count in self.state.robot_sightings.items()}
