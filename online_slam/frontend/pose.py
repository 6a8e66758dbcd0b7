"""A step (one pose with what the estimators may know of it), the pending pose it is frozen from, and the truth
the front-end sets aside."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.models.observation import SIGHTING
from online_slam.sources.events import Heading, LandmarkId, Position, RobotId

Array = NDArray[np.float64]

_NO_ROBOT_Z = np.zeros((0, 2))
_NO_ROBOT_Z.flags.writeable = False
_NO_ROBOT_Z_COV = np.zeros((0, 2, 2))
_NO_ROBOT_Z_COV.flags.writeable = False


@dataclass(frozen=True)
class Step:
    """One pose of the trajectory with what the estimators may know about it.

    Step 0 carries the start pose (``prior``); every later step carries the odometry increment from the
    previous step. ``k`` is the number of observations.
    """

    index: int
    """Pose index, 0-based, consecutive."""
    t: float
    """Time of the pose, seconds."""
    odometry: Array | None
    """Increment ``[dx, dy, dtheta]`` from the previous pose in its frame, shape (3,); None for step 0."""
    odometry_cov: Array | None
    """Covariance of ``odometry``, shape (3, 3); None for step 0."""
    landmarks: tuple[LandmarkId | None, ...]
    """Ids of the observed landmarks (None: unknown, for the estimator to associate), length k."""
    z: Array
    """Observations, shape (k, 2): ``[range, bearing]``, or ``[dx, dy]`` in the robot frame (see ``z_model``)."""
    z_cov: Array
    """Observation covariances, shape (k, 2, 2)."""
    prior: Array | None = None
    """Start pose, shape (3,); only on step 0."""
    prior_cov: Array | None = None
    """Covariance of the start pose, shape (3, 3); None means the start pose is held fixed."""
    merged: int = 1
    """How many odometry events this step's increment stands for (keyframing)."""
    robot: RobotId | None = None
    """The robot this pose is of (its lines' ``robot``); None for a stream that names no robot."""
    robots_seen: tuple[RobotId, ...] = ()
    """Robots sighted from this pose (the sightings' ``robot_seen``), length m; each sighting relates this pose to
    the seen robot's newest pose at the step's time."""
    z_robots: Array = field(default_factory=lambda: _NO_ROBOT_Z)
    """Range and bearing to each seen robot's position, shape (m, 2)."""
    z_robots_cov: Array = field(default_factory=lambda: _NO_ROBOT_Z_COV)
    """Their covariances, shape (m, 2, 2)."""
    z_model: NDArray[np.int8] = None  # type: ignore[assignment]  # not given: __post_init__ puts zeros, never None
    """Model tag of each observation (:mod:`online_slam.models.observation`), shape (k,); not given: every
    observation is range-bearing (the step then holds zeros)."""
    sensors: tuple[str | None, ...] = ()
    """The sensor of each observation (its line's ``sensor``; None: the robot's centre), length k, when the stream
    declares sensors; empty when it declares none (every sighting is then the centre's)."""
    fixes: tuple[Position | Heading, ...] = ()
    """Absolute fixes of this pose (``position`` and ``heading`` lines at its time), in stream order."""
    z_widened: bool = False
    """The source declares (header ``sightings_correlated``) the sightings' covariances widened for errors
    correlated in time: their innovations read smaller than declared, and no adaptation shrinks them."""
    z_widening: Array = None  # type: ignore[assignment]  # not given: __post_init__ puts ones, never None
    """How many times each sighting's ``z_cov`` variances exceed its own (its line's ``widened``), shape (k, 2),
    each >= 1; not given: ones. Noise adaptation judges innovations by ``z_cov / sqrt(f f^T)``."""
    odometry_bias: Array | None = None
    """On a robot's first step (with ``prior``): the prior standard deviations ``[s, w]`` (2,) of its odometry bias,
    which the EKF estimates (:mod:`~online_slam.estimators.ekf_bias`; ``FrontEndConfig.odometry_bias``, or the
    header's ``odometry_bias``); None: not modelled."""

    def __post_init__(self) -> None:
        if self.z_model is None:
            object.__setattr__(self, "z_model", np.zeros(len(self.landmarks), dtype=np.int8))
        if self.z_widening is None:
            object.__setattr__(self, "z_widening", np.ones((len(self.landmarks), 2)))

    def z_own_cov(self) -> Array:
        """The sightings' own covariances (``z_cov`` without :attr:`z_widening`; ``z_cov`` itself when no sighting
        is widened), shape (k, 2, 2)."""
        if (self.z_widening == 1.0).all():
            return self.z_cov
        d = 1.0 / np.sqrt(self.z_widening)
        return self.z_cov * d[:, :, None] * d[:, None, :]


SIGHTING_ARRAYS = ("z", "z_cov", "z_model", "z_widening")
"""The :class:`Step` arrays with a row per landmark sighting (a step keeping some of its sightings keeps their rows
of each)."""


@dataclass
class GroundTruth:
    """Truth gathered from the stream for evaluation: poses by step index and landmarks by id."""

    poses: dict[int, Array] = field(default_factory=dict)
    """True pose ``[x, y, theta]`` of a step, where the stream has one at the step's time."""
    landmarks: dict[LandmarkId, Array] = field(default_factory=dict)
    """True landmark positions ``[x, y]``."""
    outliers: dict[int, str] = field(default_factory=dict)
    """Sightings a simulator corrupted, by sighting number (0-based, in step order over the whole stream)."""
    sighting_landmarks: dict[int, LandmarkId] = field(default_factory=dict)
    """True landmark of a sighting whose stream gives it as hidden truth (``truth_landmark``), by sighting number."""
    offsets: dict[int, Array] = field(default_factory=dict)
    """Position-only truth of a robot-frame point ``[dx, dy]`` (a GPS antenna), by step: scoring compares that
    point of the estimated pose (:func:`online_slam.evaluation.scoring.scored_poses`)."""
    starts: dict[int, Array] = field(default_factory=dict)
    """The start prior's pose ``[x, y, theta]`` of a robot's first step, by step: the frame the stream gives every
    estimator, where scoring anchors (:func:`online_slam.evaluation.scoring.evaluate`)."""

    def __deepcopy__(self, memo: dict[int, Any]) -> GroundTruth:
        """A copy sharing the arrays, which no one changes in place."""
        return GroundTruth(*(dict(getattr(self, f.name)) for f in fields(self)))


@dataclass
class PendingStep:
    """The newest pose, still open for observations (``freeze`` gives its step as it stands)."""

    index: int
    t: float
    t_begin: float  # time of the previous pose: where this step's increment begins
    odometry: Array | None
    odometry_cov: Array | None
    prior: Array | None = None
    prior_cov: Array | None = None
    odometry_bias: Array | None = None
    merged: int = 1
    landmarks: list[LandmarkId | None] = field(default_factory=list)
    z: list[tuple[float, float]] = field(default_factory=list)
    z_noise: list[Any] = field(default_factory=list)  # per sighting: its sigma (2,) or its covariance (2, 2)
    z_model: list[int] = field(default_factory=list)  # per sighting: its model's tag
    z_mount: list[tuple[float, ...]] = field(default_factory=list)  # per sighting: its sensor's pose, if ``mounted``
    z_sensor: list[str | None] = field(default_factory=list)  # per sighting: its sensor's name, if ``mounted``
    z_widening: list[Any] = field(default_factory=list)  # per sighting: its ``widened`` (2,) or None
    mounted: bool = False  # the stream declares sensors: the step's models carry each sighting's mounting
    widened: bool = False  # the stream declares its sighting covariances widened for correlation (Step.z_widened)
    sealed: bool = False  # an estimator has seen this pose: keyframing may no longer move it
    full_covariance: bool = False  # some sighting gave a full covariance (not sigma)
    robot: RobotId | None = None
    robots_seen: list[RobotId] = field(default_factory=list)
    z_robots: list[tuple[float, float]] = field(default_factory=list)
    z_robots_cov: list[Array] = field(default_factory=list)
    fixes: list[Position | Heading] = field(default_factory=list)
    closed: bool = False  # its robot's next pose has begun: no line can reach it any more
    # freeze's cache: (observations, merges, robot sightings, fixes) and the step frozen then
    _frozen: tuple[tuple[int, int, int, int], Step] | None = field(default=None, init=False, repr=False, compare=False)

    def z_covariances(self) -> Array:
        """Observation covariances, shape (k, 2, 2): ``diag(sigma^2)`` (vectorized) or the full matrix given."""
        k = len(self.z_noise)
        out = np.zeros((k, 2, 2))
        if k == 0:
            return out
        if not self.full_covariance:  # every sighting gave sigma: one vectorized diag(sigma^2)
            variances = np.array(self.z_noise, dtype=float)
            variances *= variances
            out.reshape(k, 4)[:, ::3] = variances  # the diagonal of each 2x2 block
            return out
        diagonal = [len(n) == 2 and not isinstance(n[0], (tuple, list, np.ndarray)) for n in self.z_noise]
        for i, (noise, is_sigma) in enumerate(zip(self.z_noise, diagonal)):
            out[i] = np.diag(np.square(np.array(noise, dtype=float))) if is_sigma else np.array(noise, dtype=float)
        return out

    def freeze(self) -> Step:
        """The step as it stands (cached until an observation or a merge changes it)."""
        key = (len(self.landmarks), self.merged, len(self.robots_seen), len(self.fixes))
        if self._frozen is not None and self._frozen[0] == key:
            return self._frozen[1]
        step = self._freeze()
        self._frozen = (key, step)
        return step

    def _freeze(self) -> Step:
        k = len(self.landmarks)
        return Step(
            index=self.index,
            t=self.t,
            odometry=self.odometry,
            odometry_cov=self.odometry_cov,
            landmarks=tuple(self.landmarks),
            z=np.array(self.z, dtype=float).reshape(k, 2),
            z_cov=self.z_covariances(),
            prior=self.prior,
            prior_cov=self.prior_cov,
            odometry_bias=self.odometry_bias,
            merged=self.merged,
            **self._robot_fields(),
            z_model=self._models(),
            sensors=tuple(self.z_sensor),
            fixes=tuple(self.fixes),
            z_widened=self.widened,
            z_widening=self._widening(),  # type: ignore[arg-type]  # None: Step puts ones
        )

    def _widening(self) -> Array | None:
        """The sightings' :attr:`Step.z_widening` (None when none gave one: ones)."""
        if not any(w is not None for w in self.z_widening):
            return None
        return np.array([(1.0, 1.0) if w is None else w for w in self.z_widening], dtype=float)

    def _models(self) -> NDArray[Any]:
        """The sightings' model tags, or with sensors their :data:`~online_slam.models.observation.SIGHTING`
        records (tag and mounting)."""
        if not self.mounted:
            return np.array(self.z_model, dtype=np.int8)
        models = np.zeros(len(self.z_model), dtype=SIGHTING)
        models["tag"] = self.z_model
        models["mount"] = np.array(self.z_mount, dtype=float).reshape(-1, 3)
        return models

    def _robot_fields(self) -> dict[str, Any]:
        """The step's robot and robot sightings (nothing for a stream that names no robot)."""
        if self.robot is None and not self.robots_seen:
            return {}
        m = len(self.robots_seen)
        return {
            "robot": self.robot,
            "robots_seen": tuple(self.robots_seen),
            "z_robots": np.array(self.z_robots, dtype=float).reshape(m, 2),
            "z_robots_cov": np.array(self.z_robots_cov, dtype=float).reshape(m, 2, 2),
        }
