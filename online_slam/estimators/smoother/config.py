"""Settings of the sliding-window smoother, and the constants of its global relinearization schedule."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from online_slam.estimators.adaptation_config import AdaptationConfig
from online_slam.estimators.association_config import AssociationConfig
from online_slam.estimators.ekf_config import POSE_COVARIANCES
from online_slam.factors.robust import RobustLoss, outlier_threshold
from online_slam.solvers.config import SolverConfig

LINEARIZATIONS = ("standard", "fej", "invariant")
"""Where the smoother may evaluate the Jacobians of the prior's variables (:attr:`SmootherConfig.linearization`)."""
GLOBAL_GROWTH = 20
"""Global relinearizations start at most every N / 20 steps after N steps: each costs O(N), so this keeps their
amortized cost per step bounded on long runs."""
GLOBAL_DELAY_GROWTH = 50
"""A background global solve is handed over at least N / 50 steps after it starts at step N: its cost grows with N
while a step's does not, so a fixed delay would make the hand-over wait for it on long runs."""
GLOBAL_FALSE_ALARM = 1e-3
"""A global relinearization is kept unless the history's pull on the re-anchored prior exceeds the chi-square
bound a consistent history exceeds with this probability."""
GLOBAL_JUMP_TURN = 0.05
"""A window solve that turns the window's oldest pose (the prior's) by more than this (rad) has revised the past
by more than the history and the prior's linearization can follow (back from a blind stretch, or a landmark seen
again far from where it was mapped): the global relinearization runs at once (benchmarks/RESULTS.md, "A global
solve after a jump")."""


@dataclass(frozen=True)
class WindowConfig:
    """Which poses the window keeps as variables; older ones are marginalized into the prior."""

    size: int = 20
    """W: poses kept as variables at least (>= 1)."""
    distance: float = 18.0
    """The window also keeps poses beyond W until the path from its second-oldest pose to its newest is at least
    this long (metres, by odometry; up to ``max_poses``): sized by motion, it spans W poses where the robot moves
    far per pose and more where it creeps, so that the poses it freezes have seen enough geometry. Default 18 m:
    what W=20 spans at 1 m per pose. 0: W poses."""
    max_poses: int = 120
    """Most poses the window keeps to span ``distance`` (never fewer than W; ignored when that is 0)."""

    def __post_init__(self) -> None:
        if self.size < 1:
            raise ValueError("window must be >= 1")
        if not 0.0 <= self.distance < math.inf or self.max_poses < 1:
            raise ValueError("window_distance must be finite and >= 0, window_max >= 1")


@dataclass(frozen=True)
class RobustConfig:
    """How the smoother treats sightings that do not fit."""

    loss: RobustLoss | None = field(default_factory=lambda: RobustLoss("tail", math.sqrt(outlier_threshold(1e-6))))
    """Robust loss on observations, re-evaluated at every relinearization, or None for plain least squares.
    Default: least squares while a sighting's squared whitened residual is within 27.6 (the chi-square bound
    an inlier exceeds with probability 1e-6), a Cauchy tail beyond it, so a clean window solves exactly as
    least squares."""
    consensus: bool = True
    """After each solve, move a landmark to the consensus of its window sightings when they agree with each
    other but not with it (placed by a wrong association), releasing it from the prior if the prior holds it.
    Agreeing means three or more sightings within the rejection bound of their median: a loose cluster of
    wrong-id sightings (different true landmarks a metre apart) once moved a well-placed landmark 12 m. Two are
    enough when they outnumber the sightings supporting the landmark where it is (one wrong id placed it)."""
    reject_false_alarm: float = 1e-3
    """Marginalization never folds into the prior a sighting whose squared whitened residual at the current
    estimate exceeds the chi-square bound this inlier would exceed with this probability (13.8 for 1e-3):
    it is judged an outlier and dropped. 0 folds every sighting in."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.reject_false_alarm < 1.0:
            raise ValueError("the smoother's reject false alarm must be in [0, 1)")


@dataclass(frozen=True)
class GlobalConfig:
    """The global relinearization: every factor seen so far re-solved from the current estimate."""

    every: int = 200
    """Relinearize globally every this many steps, or every N / 20 steps after N steps if that is longer (0:
    never): re-solve every factor seen so far from the current estimate (``iterations`` Levenberg-Marquardt
    iterations), write the revised poses into the history and move the prior to them (see
    :mod:`~online_slam.estimators.smoother.relinearize`); at once after a window solve that turns the window's
    oldest pose by more than :data:`GLOBAL_JUMP_TURN`. Keeps every factor. Default 200, chosen on the simulated
    worlds and the real datasets: it brings the final estimate to the batch's."""
    iterations: int = 3
    """Levenberg-Marquardt iterations of each global relinearization (warm-started: few are needed)."""
    delay: int = 50
    """Steps between starting a global relinearization (in a background thread, from a copy of the state) and
    handing its result over, or N / 50 steps after N steps if that is longer (the solve's cost grows with N, a
    step's does not); the hand-over waits for the solve if it is not done, so results never depend on timing.
    0 solves at once, inside the step."""
    information_max: int = 0
    """Re-anchoring also relinearizes the prior's information (its covariance: the history's exact marginal at
    the revised estimate) while the prior holds at most this many landmarks (one sparse solve with 2 L + 3
    right-hand sides and a dense inverse of that size); otherwise only its mean moves and its covariance keeps
    the linearization of each fold-in. Default 0 (never): it helped the online error on some datasets and hurt
    it on others, and its dense inverse makes hand-overs slow where the prior holds many landmarks."""

    def __post_init__(self) -> None:
        if self.every < 0 or self.iterations < 1 or self.delay < 0:
            raise ValueError("global_every and global_delay must be >= 0, global_iterations >= 1")
        if self.information_max < 0:
            raise ValueError("global_information_max must be >= 0")


@dataclass(frozen=True)
class SmootherConfig:
    """Settings of the sliding-window smoother, by concern."""

    window: WindowConfig = field(default_factory=WindowConfig)
    """Which poses the window keeps."""
    relinearize_every: int = 1
    """K: relinearize and solve every K steps (and at the end); in between, new poses follow odometry."""
    solver: SolverConfig = field(
        default_factory=lambda: SolverConfig(
            max_iterations=10, relative_cost_tolerance=1e-5, step_tolerance=1e-5, model_tolerance=1e-4
        )
    )
    """Levenberg-Marquardt settings of each window solve during the stream (max iterations, tolerances)."""
    final_solver: SolverConfig = field(default_factory=SolverConfig)
    """Settings of the last solve, at the end of the stream (tight by default: it gives the final estimate)."""
    robust: RobustConfig = field(default_factory=RobustConfig)
    """Robust loss, consensus moves and the rejection of outliers at marginalization."""
    linearization: str = "invariant"
    """Where the Jacobians of the variables the marginal prior holds are evaluated. ``standard``: at the
    current estimate, like every other variable; the prior is re-centred (exactly) at the current estimate before
    new factors are folded in. ``fej`` (First-Estimates Jacobians): at the prior's linearization point, in the
    window's solves and in fold-ins alike, so that each variable has one linearization and the smoother gains no
    information along the unobservable directions (Dong-Si & Mourikis, ICRA 2011); each global relinearization
    re-anchors those first estimates at its solution and relinearizes the prior's covariance there (whatever
    ``global_solve.information_max``), so first estimates far off do not stay; and each window solve starts
    undamped (:attr:`window_solver`). ``invariant`` (default): at the current estimate, as ``standard``, but the prior's
    covariance is carried to each new linearization point as the invariant EKF carries its own after an update
    (:func:`~online_slam.estimators.linearization.transport`; re-centring before a fold-in, and re-anchoring that
    keeps the fold-in covariance), so its weak directions follow the estimate's unobservable ones; window solves
    start undamped; with several robots it re-centres exactly, as ``standard``. ``fej`` and ``invariant`` are
    consistent where ``standard`` is overconfident; ``invariant`` is the default, the more accurate of the two on
    real data (benchmarks/RESULTS.md, "The invariant smoother prior")."""
    global_solve: GlobalConfig = field(default_factory=GlobalConfig)
    """The periodic re-solve of the whole history."""
    association: AssociationConfig = field(default_factory=AssociationConfig)
    """How sightings are paired with landmarks: the stream's ids, or nearest neighbour / JCBB against the
    smoother's own belief (the window's information from the last solve, carried to the newest pose; the prior
    for landmarks the window does not see), with tentative landmarks. Associations are not revised later."""
    pose_covariance: str = "curved"
    """How the newest pose's covariance is reported (snapshots: NEES, recordings, ``--emit``, ``Slam``):
    ``curved``, the second moment of the belief read as an arc about the pivot its heading correlation implies
    (:mod:`~online_slam.geometry.pose_moments`); ``linear``, the covariance as linearized. The estimate, and
    the covariance the estimator works with, are the same either way."""

    adaptation: AdaptationConfig = field(default_factory=AdaptationConfig)
    """Inflate the declared odometry and sensor covariances of new steps when the newest pose's predicted
    sightings show a sustained mismatch (:mod:`~online_slam.estimators.adaptation`); off by default."""

    def __post_init__(self) -> None:
        if self.relinearize_every < 1:
            raise ValueError("relinearize_every must be >= 1")
        if self.linearization not in LINEARIZATIONS:
            raise ValueError(f"smoother linearization must be one of {', '.join(LINEARIZATIONS)}")
        if self.pose_covariance not in POSE_COVARIANCES:
            raise ValueError(f"pose_covariance must be one of {', '.join(POSE_COVARIANCES)}")

    @property
    def carried(self) -> bool:
        """The prior's covariance is carried to each new linearization point (``linearization == "invariant"``)."""
        return self.linearization == "invariant"

    @property
    def fej(self) -> bool:
        """First-Estimates Jacobians (``linearization == "fej"``)."""
        return self.linearization == "fej"

    @property
    def window_solver(self) -> SolverConfig:
        """The settings of each window solve during the stream: ``solver``, started undamped with ``fej`` and
        ``invariant``.

        Levenberg-Marquardt's first damping is relative to the diagonal of the normal equations, which a stiff
        odometry (a near-zero lateral variance) makes huge: the damped step then barely moves along the weakly
        observed directions, its quadratic model holds, and ``model_tolerance`` ends the solve short of the
        optimum, overconfident. FEJ and the invariant prior start with a Gauss-Newton step (damping only after a
        step that fails). The standard smoother keeps the damped start: undamped, it is less overconfident but less
        accurate online on real data (benchmarks/RESULTS.md, "Re-centred prior versus First-Estimates Jacobians").
        """
        return self.solver if self.linearization == "standard" else replace(self.solver, initial_lambda=0.0)
