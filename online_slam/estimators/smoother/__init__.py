"""Sliding-window least-squares smoother with Schur-complement marginalization.

The smoother keeps the W newest poses and *every* landmark as variables. Each step adds the new pose
(propagated by odometry from the latest estimate), new landmarks (inverse observation model) and their
factors. Every K steps, and at the end of the stream, it relinearizes all factors in the window and iterates
Levenberg-Marquardt to convergence. A pose is never marginalized before it has been optimized at least once.

When the window holds more than W poses, the oldest is marginalized: its factors (odometry to the next pose,
its observations, a start prior) are linearized and folded into the marginal prior, a Gaussian in covariance
form over the oldest window pose and every landmark it has touched, and its 3 variables are eliminated
(:mod:`.prior`). The prior's quadratic is never relinearized: by default it is re-centred (exactly) at the
current estimate before new factors are folded in and those are linearized there;
``first_estimate_jacobians=True`` instead linearizes them at the prior's first estimates (FEJ). FEJ diverges
where first estimates are far off before a loop closure, so it is not the default. Landmarks are never
marginalized, so a re-observation long after the poses that saw a landmark left the window (a loop closure)
still corrects the map and the current pose.

Each solve eliminates from the prior the landmarks no window pose observes and recovers them afterwards from
their conditional mean, so each iteration factors a system over the window poses and the observed landmarks
only (:mod:`.window`). Per-step cost depends on W and the size of the map, not on the length of the
trajectory. A global relinearization, in the background, re-solves every factor now and then and moves the
prior to the revised history (:mod:`.global_solve`, :mod:`.relinearize`). Association reads its covariances
from the last solve (:mod:`.covariance`).

Parts: :mod:`.config` (settings), :mod:`.window` (variables, factors, the window system, consensus),
:mod:`.prior` (the marginal prior), :mod:`.covariance` (covariance recovery), :mod:`.global_solve` (the
background global relinearization), :mod:`.relinearize` (its whole-history math), :mod:`.state` (the state as
data), :mod:`.core` (the estimator).
"""

from online_slam.estimators.smoother.config import GlobalConfig, RobustConfig, SmootherConfig, WindowConfig
from online_slam.estimators.smoother.core import SlidingWindowSmoother

__all__ = ["GlobalConfig", "RobustConfig", "SlidingWindowSmoother", "SmootherConfig", "WindowConfig"]
