"""The smoother's state as data: :class:`SmootherState` holds every group a checkpoint keeps.

The groups are dataclasses (:class:`~.window.Window`, :class:`~.prior.Prior`, :class:`Progress`,
:class:`~.global_solve.Relinearization`, :class:`AssociationState`); the generic serializer
(:func:`~online_slam.checkpoint.to_tree`, :func:`~online_slam.checkpoint.from_tree`) writes and reads them, so a
new state field is one edit: the field, with its default.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from online_slam.estimators.adaptation import Adaptation
from online_slam.estimators.landmark_book import LandmarkBook
from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.smoother.covariance import Solved
from online_slam.estimators.smoother.global_solve import Relinearization
from online_slam.estimators.smoother.prior import Prior
from online_slam.estimators.smoother.window import Window
from online_slam.frontend.steps import Step


@dataclass
class Progress:
    """How far the smoother got: counts, and what the newest step did."""

    steps: int = 0
    """Steps consumed."""
    solves: int = 0
    """Window solves."""
    marginalized: int = 0
    """Poses marginalized."""
    released: int = 0
    """Landmarks let go from the prior because the window's sightings contradicted it (consensus)."""
    robot_unfolded: int = 0
    """Robot sightings left out of the prior: when one of their poses left the window, the other was not its
    robot's oldest window pose (several robots)."""
    step_report: dict[str, int | float] = field(default_factory=dict)
    """The newest step's last solve and global relinearization figures (iteration counts are ints)."""
    step_marginalized: list[int] = field(default_factory=list)
    """The poses the newest step marginalized."""
    fixes: dict[int, list[bool]] = field(default_factory=dict)
    """Each pose's absolute fixes in the order they came: used (True), or refused by the gate."""


@dataclass(eq=False)
class AssociationState:
    """Association's state, and the last solve's information it reads."""

    book: LandmarkBook
    """Tentative landmarks and each sighting's label."""
    resolved: Step | None = None
    """The newest step with associated ids, when association changed it."""
    solved: Solved | None = None
    """The last solve's factored information, while the state has not moved."""
    stream: ProblemLog | None = None
    """Every step as it came, ids ignored, when association pairs every sighting (the final pairs them all
    again); None otherwise."""


@dataclass(eq=False)
class SmootherState:
    """Everything the smoother knows (a checkpoint holds exactly this; a pending global solve finished first)."""

    window: Window
    """The window's poses and factors, the poses that left it, every landmark."""
    relinearization: Relinearization
    """Every factor seen so far, the outlier decisions, the global relinearizations (a pending one's result)."""
    association: AssociationState
    """Tentative landmarks, the newest step as associated, the last solve's factored information."""
    prior: Prior | None = None
    """The marginal prior on the oldest window pose and the landmarks it touched, once a pose left the window."""
    progress: Progress = field(default_factory=Progress)
    """Counts, and what the newest step did."""
    adaptation: Adaptation = field(default_factory=Adaptation)
    """The adapted noise scales (``--adapt-noise``; 1 and 1 when off)."""
