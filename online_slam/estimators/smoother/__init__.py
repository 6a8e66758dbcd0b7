"""Sliding-window least-squares smoother with Schur-complement marginalization.

The smoother keeps a window of the newest poses and *every* landmark as variables: at least W poses, and more
(up to ``max_poses``) until their path spans ``distance`` metres (:class:`.config.WindowConfig`). Each step adds
the new pose (propagated by odometry from the latest estimate), new landmarks (inverse observation model) and
their factors. Every K steps, and at the end of the stream, it relinearizes all factors in the window and runs
Levenberg-Marquardt, up to ``solver.max_iterations`` iterations or its tolerances (the last solve to tight ones).
A pose is never marginalized before it has been optimized at least once.

When the window holds more poses than it keeps, the oldest is marginalized: its factors (odometry to the next pose,
its observations, a start prior) are linearized and folded into the marginal prior, a Gaussian in covariance
form over the oldest window pose and every landmark it has touched, and its 3 variables are eliminated
(:mod:`.prior`). The prior's quadratic is never relinearized between global solves. Where the Jacobians of the
variables it holds are taken is :attr:`.config.SmootherConfig.linearization`: ``standard`` re-centres the prior
(exactly) at the current estimate before each fold-in and takes every Jacobian at the current estimate; ``fej``
(First-Estimates Jacobians) takes each such variable's Jacobian at the prior's linearization point, in the window's
solves and in later fold-ins alike, so the window cannot gain information along the directions no sighting
observes (global position and heading; Dong-Si & Mourikis, ICRA 2011), each global relinearization re-anchoring
those first estimates at its solution; ``invariant`` (the default) keeps every Jacobian at the current estimate and
carries the prior's covariance to each new linearization point, as the invariant EKF carries its own
(:func:`.prior.carry`). ``fej`` and ``invariant`` start window solves undamped. The decision and its evidence are
in benchmarks/RESULTS.md ("The invariant smoother prior"). Landmarks are never marginalized, so a
re-observation long after the poses that saw a landmark left the window (a loop closure) still corrects the map
and the current pose.

Each solve eliminates from the prior the landmarks no window pose observes and recovers them afterwards from
their conditional mean, so each iteration factors a system over the window poses and the observed landmarks
only (:mod:`.window`). Per-step cost depends on W and the size of the map, not on the length of the
trajectory. A global relinearization, in the background, re-solves every factor now and then and moves the
prior to the revised history (:mod:`.global_solve`, :mod:`.relinearize`). Association reads its covariances
from the last solve (:mod:`.covariance`). When it ignores the stream's ids, its final pairs every sighting of the
stream again as the batch does (:mod:`.final_pairing`).

Several robots (:mod:`.robots`). Each robot's poses form their own odometry chain from its own start (poses
are indexed over all robots in step order). The window holds the newest poses in step order, of every robot,
and is sized as with one robot (W poses, the ``distance`` path summed over all robots' odometry in the window,
``max_poses``): its cost per step stays that of one robot's window, each robot keeping about its share of it.
A robot's newest pose never leaves the window, so each chain keeps at least one pose. Marginalization takes the
oldest window pose that is not its robot's newest: it is its robot's oldest window pose, and the prior holds
the oldest window pose of each robot that has lost one (``Prior.others``, then the pose being marginalized
last) and every landmark they touched; a robot's start enters the prior with its start prior when its first
pose leaves (or when a robot sighting needs it there). A sighting of a robot (range and bearing to the seen
robot's pose) links the sighting pose to the seen robot's newest pose at the step's time, paired as the batch
pairs it (:class:`~online_slam.estimators.problem.RobotSightings` of the log), and enters the window as a
pose-to-pose factor once its time is past. When one of its poses leaves the window, the other must be its
robot's oldest window pose, which the prior then holds: that robot's older poses are marginalized first (they
are about as old); the sighting is then folded into the prior (a Kalman update of both poses, as a sighting of
a landmark the prior holds). A sighting whose other pose cannot be brought there is left out of the prior
(counted: ``robot_sightings_unfolded``). Robot sightings are judged like landmark sightings: the robust loss in
every solve, and one whose squared whitened residual exceeds the rejection bound when it leaves the window is
an outlier, never folded in and left out of global solves. Global relinearization solves the whole log, robot
sightings included, and re-anchors the prior over the factors it folded in, with every pose that left the
window eliminated (:func:`~.relinearize.several_history_graph`); poses that left after the solve started
follow their robot's last solved pose rigidly. A checkpoint keeps the new state as any other (robots, window
chains and robot sightings in :class:`~.window.Window`, the prior's poses, the folded and rejected sightings).

Parts: :mod:`.config` (settings), :mod:`.window` (variables, factors, the window system, consensus),
:mod:`.prior` (the marginal prior), :mod:`.covariance` (covariance recovery), :mod:`.global_solve` (the
background global relinearization), :mod:`.relinearize` (its whole-history math), :mod:`.final_pairing` (the
final without ids), :mod:`.state` (the state as data), :mod:`.robots` (several robots), :mod:`.core` (the
estimator).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from online_slam.lazy import lazy_exports

if TYPE_CHECKING:
    from online_slam.estimators.smoother.config import GlobalConfig, RobustConfig, SmootherConfig, WindowConfig
    from online_slam.estimators.smoother.core import SlidingWindowSmoother

_HOMES = {
    "GlobalConfig": "online_slam.estimators.smoother.config",
    "RobustConfig": "online_slam.estimators.smoother.config",
    "SmootherConfig": "online_slam.estimators.smoother.config",
    "WindowConfig": "online_slam.estimators.smoother.config",
    "SlidingWindowSmoother": "online_slam.estimators.smoother.core",
}
"""Each public name's module (imported on first use)."""

__all__ = ["GlobalConfig", "RobustConfig", "SlidingWindowSmoother", "SmootherConfig", "WindowConfig"]
__getattr__, __dir__ = lazy_exports(__name__, _HOMES)
