"""The EKF's state as data: what :class:`~online_slam.estimators.ekf.EkfSlam` knows, and a checkpoint holds."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.adaptation import Adaptation
from online_slam.estimators.history import PoseHistory
from online_slam.estimators.landmark_book import LandmarkBook
from online_slam.sources.events import LandmarkId, RobotId

Array = NDArray[np.float64]


def _zeros(*shape: int, dtype: type = float) -> Any:
    """A default of zeros of the given shape."""
    return field(default_factory=lambda: np.zeros(shape, dtype=dtype))


@dataclass(eq=False)
class WaitingSighting:
    """A sighting of a robot waiting for the seen robot's pose of its time (several robots)."""

    pose: int
    """The sighting pose's step index."""
    robot: RobotId
    """The sighting robot."""
    seen: RobotId
    """The seen robot."""
    t: float
    """The sighting step's time."""
    z: Array
    """Range and bearing, shape (2,)."""
    cov: Array
    """Its covariance, shape (2, 2)."""


@dataclass(eq=False)
class EkfState:
    """Everything the filter knows (a checkpoint holds exactly this; filterpy's view of the last update aside)."""

    book: LandmarkBook
    """Association state (tentative landmarks, ids given out, each sighting's label)."""
    x: Array = _zeros(3, 1)
    """Mean ``[x, y, theta, l1x, l1y, ...]``, shape (n, 1); with several robots ``[pose of the active robot,
    the other robots' poses, landmarks]``."""
    P: Array = _zeros(3, 3)
    """Covariance, shape (n, n)."""
    Q: Array = _zeros(3, 3)
    """Covariance of the last odometry increment (filterpy's ``Q`` is this block, padded with zeros)."""
    landmark_ids: list[LandmarkId] = field(default_factory=list)
    """The M landmark ids in state order."""
    streak: NDArray[np.int64] = _zeros(0, dtype=np.int64)
    """Consecutive gated sightings per landmark, shape (M,)."""
    confirmed: NDArray[np.bool_] = _zeros(0, dtype=bool)
    """Per landmark: has passed the gate since it was (re)initialised, shape (M,)."""
    predicted: Array = _zeros(3)
    """The newest pose as predicted, before any update (its first estimate: FEJ's linearization point)."""
    first: Array = _zeros(0, 2)
    """Each landmark's position when it was placed (its first estimate), shape (M, 2)."""
    recent: dict[int, list[tuple[Array, Array]]] = field(default_factory=dict)
    """Recent gated sightings per landmark index, as (position (2,), its covariance (2, 2))."""
    agreement: list[tuple[int, int]] = field(default_factory=list)
    """(failing, passing) confirmed sightings of the last updates."""
    gated_total: int = 0
    """Sightings rejected by the gate so far."""
    reanchored: int = 0
    """Landmarks restarted from a sighting so far."""
    fixed: int = 0
    """The first ``fixed`` landmarks are a fixed map's (``--map-fixed``): zero covariance, never re-anchored."""
    history: PoseHistory = field(default_factory=PoseHistory)
    """Every pose before the newest, as it was when newest."""
    step_nis: list[Array] = field(default_factory=list)
    """NIS of the newest step's sightings, per update call."""
    step_gated: list[LandmarkId] = field(default_factory=list)
    """Landmarks whose sightings the gate rejected in the newest step."""
    step_new: list[LandmarkId] = field(default_factory=list)
    """Landmarks the newest step added."""
    step_ids: list[LandmarkId | None] = field(default_factory=list)
    """The newest step's sightings as paired (None: not used)."""
    rejected: list[NDArray[np.bool_]] = field(default_factory=list)
    """Sightings not used (gated, or kept back by association), per update call, in step order."""
    robots: list[RobotId | None] = field(default_factory=lambda: [None])
    """The robot of each pose block of ``x``, the active one first."""
    robot_steps: list[int] = field(default_factory=lambda: [0])
    """The step index of each block's pose."""
    robot_times: list[float] = field(default_factory=lambda: [0.0])
    """The time of each block's pose."""
    moved: list[int] = field(default_factory=list)
    """With several robots: the step index of each ``history`` row (rows come as robots move on)."""
    waiting: list[WaitingSighting] = field(default_factory=list)
    """Robot sightings waiting for the seen robot's pose of their time."""
    robot_sightings: dict[str, int] = field(default_factory=lambda: {"used": 0, "gated": 0, "dropped": 0})
    """Robot sightings used, rejected by the gate, and dropped (a pose they link had gone, or never came)."""
    fixes_used: int = 0
    """Absolute fixes of the newest step used so far."""
    fix_nis: list[float] = field(default_factory=list)
    """NIS of each fix used (whitened: chi-square with as many dof as the fix measures)."""
    fixes_rejected: int = 0
    """Fixes refused by the gate (their NIS beyond the chi-square quantile ``gate_probability``)."""
    adaptation: Adaptation = field(default_factory=Adaptation)
    """The adapted noise scales (``--adapt-noise``; 1 and 1 when off)."""
    biased: bool = False
    """``x`` holds each robot's odometry bias ``[s, w]`` after the poses (:mod:`~online_slam.estimators.ekf_bias`)."""
    index: dict[LandmarkId, int] = field(init=False)
    """State index of each landmark id."""

    def __post_init__(self) -> None:
        n, m = len(self.x), len(self.landmark_ids)
        sizes = (len(self.streak), len(self.confirmed), len(self.first))
        expected = (5 if self.biased else 3) * len(self.robots) + 2 * m
        if n != expected or self.P.shape != (n, n) or any(size != m for size in sizes):
            raise ValueError("x, P, landmark_ids and the per-landmark arrays disagree in size")
        self.index = {lid: j for j, lid in enumerate(self.landmark_ids)}

    def __deepcopy__(self, memo: dict[int, Any]) -> EkfState:
        """A copy sharing the arrays of ``rejected`` (one per update, never changed in place)."""
        memo.update((id(a), a) for a in self.rejected)
        clone = copy.copy(self)
        for f in fields(self):
            setattr(clone, f.name, copy.deepcopy(getattr(self, f.name), memo))
        return clone
