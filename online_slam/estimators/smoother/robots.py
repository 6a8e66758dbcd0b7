"""Several robots in the smoother: robot sightings into the window, marginalization of interleaved pose chains.

See :mod:`online_slam.estimators.smoother` for the design. With one robot nothing here runs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.smoother.prior import Prior, RobotFold, Sightings, initial_prior, marginalize
from online_slam.estimators.smoother.state import SmootherState
from online_slam.factors.graph import robot_sighting_residual_with_jacobians, sqrt_information
from online_slam.geometry.angles import wrap
from online_slam.geometry.pose_moments import reported
from online_slam.sources.events import RobotId

Array = NDArray[np.float64]


def with_start(prior: Prior, index: int, start: tuple[Array, Array | None], value: Array) -> Prior:
    """The prior with a robot's start pose added (independent of the rest: its start prior), before its last pose.

    Args:
        prior: The prior.
        index: The start pose.
        start: Its prior mean and covariance (None: fixed).
        value: Its current estimate, shape (3,).
    """
    n = len(prior.mu)
    order = np.r_[np.arange(n - 3), np.arange(n, n + 3), np.arange(n - 3, n)]
    mean, cov = start
    d = mean - value
    d[2] = wrap(d[2])
    Sigma = np.zeros((n + 3, n + 3))
    Sigma[:n, :n] = prior.Sigma
    Sigma[n:, n:] = 0.0 if cov is None else cov
    x_lin, mu = np.r_[prior.x_lin, value], np.r_[prior.mu, d]
    others = np.r_[prior.others, index].astype(np.int64)
    return Prior(prior.pose, prior.landmarks, x_lin[order], mu[order], Sigma[np.ix_(order, order)], others)


def with_last(prior: Prior, pose: int) -> Prior:
    """The prior with ``pose`` (one of its ``others``) as its last pose: rows and columns permuted."""
    if pose == prior.pose:
        return prior
    n, first = len(prior.mu), 2 * len(prior.landmarks)
    k = int(np.flatnonzero(prior.others == pose)[0])
    blocks = [first + 3 * j for j in range(len(prior.others)) if j != k] + [n - 3, first + 3 * k]
    order = np.r_[np.arange(first), (np.array(blocks, dtype=np.int64)[:, None] + np.arange(3)).reshape(-1)]
    others = np.r_[np.delete(prior.others, k), prior.pose].astype(np.int64)
    Sigma = np.ascontiguousarray(prior.Sigma[np.ix_(order, order)])
    return Prior(pose, prior.landmarks, prior.x_lin[order], prior.mu[order], Sigma, others)


class SeveralRobots:
    """The smoother's handling of several robots (a mixin of
    :class:`~online_slam.estimators.smoother.core.SlidingWindowSmoother`)."""

    several_robots = True
    state: SmootherState
    _reject_bound: float
    config: Any
    solve: Callable[..., dict[str, float]]
    _sightings_to_fold: Callable[[int], Sightings | None]

    def robot_poses(self) -> dict[RobotId | None, tuple[int, float, Array, Array]]:
        """Each robot's newest pose by robot: (its step index, its time, ``[x, y, theta]`` (3,), its covariance (3, 3)),
        copies. The covariance is the window's newest pose's for that pose, otherwise as it was when the robot's
        pose stopped being the window's newest (reported as :attr:`~.SmootherConfig.pose_covariance` says)."""
        w = self.state.window
        out = {}
        for robot, t in zip(w.robots, w.robot_times):
            g = w.newest(robot)
            cov = w.pose_cov if g == w.indices[-1] else w.robot_cov.get(g, w.pose_cov)
            out[robot] = (g, t, w.poses[g].copy(), reported(cov, self.config.pose_covariance))
        return out

    def _link_robot_sightings(self, final: bool = False) -> None:
        """Add to the window the log's robot sightings whose seen pose is settled (their time is past, or the stream
        ended: ``final``); those linking no pose, or a pose gone from the window, are left out of it."""
        w, seen = self.state.window, self.state.relinearization.log.seen
        fresh = list(range(w.sightings_read, len(seen.pose)))
        w.sightings_read = len(seen.pose)
        waiting = []
        for k in w.sightings_waiting + fresh:
            if not final and k in seen.open:
                waiting.append(k)
            elif seen.seen_pose[k] >= 0 and seen.pose[k] in w.poses and seen.seen_pose[k] in w.poses:
                z, cov = np.asarray(seen.z[k], dtype=float), np.asarray(seen.cov[k], dtype=float)
                w.robot_factors.append((seen.pose[k], seen.seen_pose[k], z, sqrt_information(cov), k))
                w.unsolved.update((seen.pose[k], seen.seen_pose[k]))
                self.state.association.solved = None
        w.sightings_waiting = waiting

    def _marginalize_several(self, marginalized: list[int]) -> bool:
        """Marginalize the oldest window pose that is not its robot's newest; False when there is none."""
        w = self.state.window
        newest: dict[Any, int] = {}
        for g in w.indices:
            newest[w.robot_of[g]] = g
        o = next((g for g in w.indices if newest[w.robot_of[g]] != g), None)
        if o is None:
            return False
        if w.unsolved:  # never marginalize a pose before it was optimized
            self.solve()
        self._marginalize_pose(o, marginalized, frozenset())
        return True

    def _marginalize_pose(self, o: int, marginalized: list[int], busy: frozenset[int]) -> None:
        """Marginalize pose o (its robot's oldest window pose): first, for each robot sighting linking it to a
        pose p that is not its robot's oldest, that robot's poses older than p (so that the sighting links two
        poses the prior holds); then o's factors are folded into the prior and o eliminated."""
        w = self.state.window
        busy = busy | {o}
        for p in [f[1] if f[0] == o else f[0] for f in w.robot_factors if o in f[:2]]:
            while p in w.poses and (q := w.chain(w.robot_of[p])[0]) != p and q not in busy:
                self._marginalize_pose(q, marginalized, busy)
        self.state.prior = self._holding(self.state.prior, o)
        fold = self._robot_fold(o)
        chain = w.chain(w.robot_of[o])
        n1 = chain[1]
        prior = self.state.prior
        assert prior is not None and prior.pose == o
        delta, _, W = w.odometry[n1]
        values = np.concatenate([w.poses[g] for g in prior.poses])
        self.state.prior = marginalize(
            prior,
            values,
            w.landmarks,
            self._sightings_to_fold(o),
            (delta, W),
            (n1, w.poses[n1]),
            self.config.robust.loss,
            self.config.linearization,
            fold,
            w.fixes.get(o),
        )
        w.drop(o, n1)
        self.state.progress.marginalized += 1
        marginalized.append(o)

    def _holding(self, prior: Prior | None, pose: int) -> Prior:
        """The prior holding ``pose`` (its robot's oldest window pose), the pose last: its robot's start is taken
        into it (the prior begins with it) if the prior holds no pose of that robot yet."""
        w = self.state.window
        if prior is not None and pose in prior.poses:
            return with_last(prior, pose)
        if w.start is not None and w.start[0] == pose:
            start, w.start = w.start[1:], None
        else:
            start = w.starts.pop(pose)
        if prior is None:
            return initial_prior((pose, *start), w.poses[pose], w.joint_map())
        return with_last(with_start(prior, pose, start, w.poses[pose]), pose)

    def _robot_fold(self, o: int) -> RobotFold | None:
        """o's robot sightings to fold into the prior (taking the other pose into it as need be), dropping them from
        the window: those judged outliers at the current estimate are recorded instead, those whose other pose is
        not its robot's oldest window pose are left out."""
        w, r = self.state.window, self.state.relinearization
        mine = [f for f in w.robot_factors if o in f[:2]]
        if not mine:
            return None
        w.robot_factors = [f for f in w.robot_factors if o not in f[:2]]
        self.state.association.solved = None
        folded = []
        for f in mine:
            p = f[1] if f[0] == o else f[0]
            if p not in w.poses or w.chain(w.robot_of[p])[0] != p:
                self.state.progress.robot_unfolded += 1
                continue
            e = robot_sighting_residual_with_jacobians(w.poses[f[0]][None], w.poses[f[1]][None], f[2][None])[0]
            whitened = f[3] @ e[0]
            if np.isfinite(self._reject_bound) and float(whitened @ whitened) > self._reject_bound:
                r.robot_rejected.append(f[4])
                continue
            if not self._fixed(p):  # a fixed start stays in the window alone: a constant of the sighting
                self.state.prior = with_last(self._holding(self.state.prior, p), o)
            folded.append(f)
            r.robot_folded.append(f[4])
        if not folded:
            return None
        prior = self.state.prior
        assert prior is not None
        first = {int(g): 2 * len(prior.landmarks) + 3 * k for k, g in enumerate(prior.poses)}
        return (
            np.array([first.get(f[0], -1) for f in folded], dtype=np.int64),
            np.array([first.get(f[1], -1) for f in folded], dtype=np.int64),
            np.array([f[2] for f in folded]),
            np.array([f[3] for f in folded]),
            np.array([[w.poses[f[0]], w.poses[f[1]]] for f in folded]),
        )

    def _fixed(self, pose: int) -> bool:
        """Whether a window pose is a start held fixed that the prior does not hold."""
        w = self.state.window
        if w.start is not None and w.start[0] == pose:
            return w.start[2] is None
        return pose in w.starts and w.starts[pose][1] is None

    def _robot_info(self) -> dict[str, int]:
        """What became of the robot sightings (nothing with one robot)."""
        w, r = self.state.window, self.state.relinearization
        if not w.several:
            return {}
        return {
            "robot_sightings_folded": len(r.robot_folded),
            "robot_sightings_rejected": len(r.robot_rejected),
            "robot_sightings_unfolded": self.state.progress.robot_unfolded,
            "robot_sightings_in_window": len(w.robot_factors),
        }
