"""Settings of the EKF-SLAM estimator (:mod:`~online_slam.estimators.ekf`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from online_slam.estimators.adaptation_config import AdaptationConfig
from online_slam.estimators.association_config import AssociationConfig

LINEARIZATIONS = ("standard", "fej", "oc", "invariant")
"""Where the EKF evaluates its Jacobians (see the module docstring)."""
POSE_COVARIANCES = ("curved", "linear")
"""How the EKF and the smoother report their newest pose's covariance (:attr:`EkfConfig.pose_covariance`)."""


@dataclass(frozen=True)
class EkfConfig:
    """Settings of the EKF-SLAM estimator."""

    gate_probability: float = 0.9999
    """Chi-square gate (2 dof) on each observation's NIS: an observation whose NIS exceeds this quantile
    (18.4 for 0.9999) is rejected and reported. 1.0 disables gating."""
    gate_persistence: int = 8
    """A landmark whose sightings fail the gate this many times in a row is used anyway: a one-off misreading
    fails once, but repeated failures of one landmark mean the filter has drifted, and rejecting them would
    starve it. 0 turns this off (every gated sighting rejected)."""
    reanchor: bool = True
    """When a landmark has failed the gate 3 times in a row (:data:`~online_slam.estimators.ekf.REANCHOR_AFTER`,
    whatever ``gate_persistence``; only ``gate_persistence`` 0 turns re-anchoring off) while the rest of each scan
    agreed with the filter, and those gated sightings agree with each other, the landmark's estimate is the
    stale one (e.g. it was placed by a wrong association): restart it from the newest sighting instead of
    letting that sighting pull the robot. When most of a scan fails the gate, the filter itself has drifted
    and persistent sightings are used (False: always the latter)."""
    update: str = "joint"
    """``joint``: one update with all of a step's observations (fastest); ``sequential``: one at a time,
    relinearized after each."""
    linearization: str = "invariant"
    """Where the Jacobians are evaluated: ``standard`` at the current estimate; ``fej`` at each variable's first
    estimate; ``oc``: the standard ones constrained to see nothing of the unobservable directions; ``invariant``:
    the standard ones, with the error on the group SE_{1+M}(2) (corrections turn the map with the heading; one
    robot: with several its updates are standard). The last three are consistent
    (:mod:`~online_slam.estimators.linearization`)."""
    association: AssociationConfig = field(default_factory=AssociationConfig)
    """How sightings are paired with landmarks: the stream's ids, or nearest neighbour / JCBB against the
    filter's own mean and covariance (with tentative landmarks)."""
    pose_covariance: str = "curved"
    """How the newest pose's covariance is reported (snapshots: NEES, recordings, ``--emit``, ``Slam``):
    ``curved``, the second moment of the belief read as an arc about the pivot its heading correlation implies
    (:mod:`~online_slam.geometry.pose_moments`); ``linear``, the covariance as linearized. The estimate, and
    the covariance the estimator works with, are the same either way."""

    adaptation: AdaptationConfig = field(default_factory=AdaptationConfig)
    """Inflate the declared odometry and sensor covariances when the innovations show a sustained mismatch
    (:mod:`~online_slam.estimators.adaptation`); off by default."""

    def __post_init__(self) -> None:
        if not 0.0 < self.gate_probability <= 1.0:
            raise ValueError("gate_probability must be in (0, 1]")
        if self.gate_persistence < 0:
            raise ValueError("gate_persistence must be >= 0")
        if self.update not in ("joint", "sequential"):
            raise ValueError("update must be 'joint' or 'sequential'")
        if self.linearization not in LINEARIZATIONS:
            raise ValueError(f"linearization must be one of {', '.join(LINEARIZATIONS)}")
        if self.pose_covariance not in POSE_COVARIANCES:
            raise ValueError(f"pose_covariance must be one of {', '.join(POSE_COVARIANCES)}")
