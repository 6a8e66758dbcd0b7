"""Result records of a replay: what tables, JSON files and plots all read."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.protocol import Estimate
from online_slam.evaluation.association import AssociationScore
from online_slam.sources.events import LandmarkId
from online_slam.sources.landmark_map import LandmarkMap

Array = NDArray[np.float64]


def _finite_or_none(value: float | None) -> float | None:
    if value is None or value != value:  # NaN
        return None
    return float(value)


INTERRUPTED = "interrupted"
"""``Results.error`` of a replay ended by a stop request (SIGINT, SIGTERM): what came before is scored as usual."""


@dataclass(frozen=True)
class OdometryResult:
    """Dead-reckoning figures (composed odometry from the start pose)."""

    rmse_m: float | None
    """Position RMSE against truth, metres (None without truth)."""
    endpoint_gap_m: float
    """Distance between the last and first composed positions, metres."""
    landmark_rmse_m: float | None = None
    """RMSE of landmarks placed from their first observation, metres (None without truth)."""
    robots: dict[str, OdometryResult] = field(default_factory=dict)
    """With several robots: the same figures per robot (its id as text); empty with one."""

    def row(self) -> Row:
        """Its figures as a table row: the online figures are the final ones, and it takes no time."""
        return Row(
            online_rmse_m=self.rmse_m,
            final_rmse_m=self.rmse_m,
            landmark_rmse_m=self.landmark_rmse_m,
            endpoint_gap_m=self.endpoint_gap_m,
            nees_mean=None,
            nees_in_bounds=None,
            nis_mean=None,
            step_median_ms=None,
            step_p95_ms=None,
            step_max_ms=None,
            total_s=0.0,
        )

    def to_json(self) -> dict[str, Any]:
        """Its figures as the results JSON has them."""
        robots = {"robots": {r: mine.to_json() for r, mine in self.robots.items()}} if self.robots else {}
        return {
            "rmse_m": _finite_or_none(self.rmse_m),
            "endpoint_gap_m": self.endpoint_gap_m,
            "landmark_rmse_m": _finite_or_none(self.landmark_rmse_m),
            **robots,
        }


@dataclass(frozen=True)
class Latency:
    """Wall time per step, milliseconds."""

    median: float
    """Median over steps."""
    p95: float
    """95th percentile."""
    max: float
    """Largest."""

    def to_json(self) -> dict[str, float]:
        """The JSON object of these figures."""
        return {"median": self.median, "p95": self.p95, "max": self.max}


@dataclass(frozen=True)
class OutlierReport:
    """What an estimator judged an outlier, scored against the stream's marks where it has them."""

    rejected: int
    """Sightings the estimator rejected (gated, or dropped as outliers), in its final judgement."""
    sightings: int
    """Sightings it was given."""
    true_outliers: int | None = None
    """Sightings the stream marks as corrupted (None when the stream carries no marks)."""
    caught: int | None = None
    """Marked outliers it rejected."""
    inliers_lost: int | None = None
    """Unmarked sightings it rejected."""

    def to_json(self) -> dict[str, Any]:
        """The ``"outliers"`` object of an estimator's results."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class WithoutIdReport:
    """Sightings a stream gave without a landmark id, under known association (the rest paired by their ids)."""

    sightings: int
    """Sightings without an id."""
    associated: int
    """Those the estimator put on a landmark of its final map; the others it did not use."""

    def to_json(self) -> dict[str, Any]:
        """The ``"without_id"`` object of an estimator's results."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class NeesBand:
    """Where one run's mean NEES lies 95% of the time for a consistent estimator, the correlation of consecutive
    steps that the run shows counted (:func:`~online_slam.evaluation.scoring.nees_band`): a lower bound on the
    width, as errors the whole run shares (its frame's, its map's) widen it further."""

    low: float
    """Lower end."""
    high: float
    """Upper end."""
    steps: int
    """Steps with a NEES."""
    effective_steps: float
    """The independent steps they are worth: ``steps`` over the integrated autocorrelation time."""

    def to_json(self) -> dict[str, Any]:
        """The ``"nees_band"`` object of the results JSON."""
        return {"low": self.low, "high": self.high, "steps": self.steps, "effective_steps": self.effective_steps}


@dataclass(frozen=True)
class LandmarkCoverage:
    """Which landmarks a landmark RMSE covers, and which it leaves out."""

    scored: int
    """Landmarks of the estimate with truth: those the RMSE is over."""
    without_truth: tuple[LandmarkId, ...]
    """Landmarks of the estimate that have no truth (left out)."""
    not_estimated: tuple[LandmarkId, ...]
    """Landmarks with truth that the estimate does not hold (never sighted, or not mapped; left out)."""

    def to_json(self) -> dict[str, Any]:
        """The ``"landmark_coverage"`` object of the results JSON."""
        return {"scored": self.scored, "without_truth": list(self.without_truth),
                "not_estimated": list(self.not_estimated)}  # fmt: skip


@dataclass(frozen=True)
class Row:
    """One estimator's figures as a flat record: a line of ``compare``'s table and JSON, of a sweep's output."""

    online_rmse_m: float | None
    """RMSE of each pose as estimated when newest (None for batch)."""
    final_rmse_m: float | None
    """RMSE of the final estimate."""
    landmark_rmse_m: float | None
    """Landmark RMSE."""
    endpoint_gap_m: float
    """Last-to-first distance of the final estimate."""
    nees_mean: float | None
    """Mean pose NEES over steps with truth (3 = consistent)."""
    nees_in_bounds: float | None
    """Share of steps whose NEES lies inside the two-sided 95% chi-square interval (3 dof)."""
    nis_mean: float | None
    """Mean NIS over steps (each step's mean over its sightings; 2 = consistent), where the estimator computes
    one."""
    step_median_ms: float | None
    """Median step time, ms (None for estimators whose work is all at the end)."""
    step_p95_ms: float | None
    """95th percentile of the step time, ms."""
    step_max_ms: float | None
    """Longest step, ms."""
    total_s: float
    """Total wall time of the estimator, seconds (0 for dead reckoning)."""
    nis_median: float | None = None
    """Median of the same per-step NIS (an outlier does not move it; chi-square median 1.39 on 2 dof)."""
    nees_band: NeesBand | None = None
    """Where ``nees_mean`` lies in 95% of runs like this one for a consistent estimator."""


@dataclass(frozen=True)
class MapReport:
    """The map a replay started from (``--map``) and the final map (``--map-out`` writes it)."""

    loaded: int
    """Landmarks of the map started from (0: none)."""
    fixed: bool
    """They were held (``--map-fixed``)."""
    not_in_map: int
    """Sightings skipped by ``--map-only`` (of landmarks not in the map)."""
    final: LandmarkMap | None = field(default=None, repr=False)
    """The final map (None when no estimator with covariances ran)."""
    positions_from: str = ""
    """The estimator whose final landmark positions it holds."""
    covariances_from: str = ""
    """The estimator whose final covariances it holds."""
    joint: bool = False
    """The map started from was one prior with its joint covariance (False: independent priors, or fixed)."""
    path: str = ""
    """The file of the map started from (empty: none, or a map given as an object)."""

    def to_json(self) -> dict[str, Any]:
        """The ``"map"`` object of the results JSON."""
        return {
            "loaded": self.loaded,
            "fixed": self.fixed,
            "joint": self.joint,
            "not_in_map": self.not_in_map,
            "final_landmarks": None if self.final is None else len(self.final),
            "positions_from": self.positions_from,
            "covariances_from": self.covariances_from,
        }


@dataclass(frozen=True)
class EstimatorResult:
    """One estimator's figures over the whole stream."""

    final_rmse_m: float | None
    """Position RMSE of the final estimate against truth, metres (None without truth)."""
    endpoint_gap_m: float
    """Distance between the last and first estimated positions, metres."""
    landmark_rmse_m: float | None
    """Landmark RMSE against truth, metres (None without landmark truth)."""
    total_s: float
    """Wall time spent in this estimator (every step plus the final solve), seconds."""
    online_rmse_m: float | None = None
    """Position RMSE of each pose as estimated when it was the newest (what the robot knew then); None for
    estimators that only answer at the end (batch) or without truth."""
    nees_mean: float | None = None
    """Mean pose NEES (3 dof) over steps with truth and a covariance; None when unavailable."""
    nees_in_bounds: float | None = None
    """Share of steps whose NEES lies inside the two-sided 95% chi-square interval (3 dof); None when unavailable
    (in :meth:`Results.rows`, not in the replay's JSON)."""
    nis_mean: float | None = None
    """Mean NIS over steps (each step's mean over its sightings; 2 = consistent), where the estimator computes
    one."""
    nis_median: float | None = None
    """Median of the same per-step NIS: what one outlier does not move."""
    nees_band: NeesBand | None = None
    """The 95% band of ``nees_mean`` for a consistent estimator, consecutive steps' correlation counted."""
    landmarks: LandmarkCoverage | None = None
    """Which landmarks ``landmark_rmse_m`` covers (None without landmark truth)."""
    step_ms: Latency | None = None
    """Per-step wall time; None for estimators whose work is all at the end."""
    details: dict[str, Any] = field(default_factory=dict)
    """Estimator-specific report (iterations, convergence, gated observations, ...)."""
    outliers: OutlierReport | None = None
    """Sightings judged outliers (and, on marked streams, how many were true outliers), where it judges."""
    association: AssociationScore | None = None
    """How it paired sightings with landmarks, scored against the stream's ids (``--association nn|jcbb``)."""
    without_id: WithoutIdReport | None = None
    """Under known association, the sightings without an id and how many it used (None: every sighting had one)."""
    robots: dict[str, EstimatorResult] = field(default_factory=dict)
    """With several robots: the same figures per robot, by robot id as text (empty with one robot)."""

    def to_json(self) -> dict[str, Any]:
        """The JSON object of this result."""
        out: dict[str, Any] = {
            "final_rmse_m": _finite_or_none(self.final_rmse_m),
            "endpoint_gap_m": self.endpoint_gap_m,
            "landmark_rmse_m": _finite_or_none(self.landmark_rmse_m),
            "total_s": self.total_s,
        }
        if self.step_ms is not None:
            out["online_rmse_m"] = _finite_or_none(self.online_rmse_m)
            out["nees_mean"] = _finite_or_none(self.nees_mean)
            out["nees_band"] = None if self.nees_band is None else self.nees_band.to_json()
            out["nis_mean"] = _finite_or_none(self.nis_mean)
            out["nis_median"] = _finite_or_none(self.nis_median)
            out["step_ms"] = self.step_ms.to_json()
        if self.landmarks is not None:
            out["landmark_coverage"] = self.landmarks.to_json()
        out.update(self.details)
        if self.outliers is not None:
            out["outliers"] = self.outliers.to_json()
        if self.association is not None:
            out["association"] = {**out.get("association", {}), **self.association.to_dict()}
        if self.without_id is not None:
            out["without_id"] = self.without_id.to_json()
        if self.robots:
            out["robots"] = {robot: result.to_json() for robot, result in self.robots.items()}
        return out

    def row(self) -> Row:
        """These figures as one flat record."""
        latency = self.step_ms
        return Row(
            online_rmse_m=self.online_rmse_m,
            final_rmse_m=self.final_rmse_m,
            landmark_rmse_m=self.landmark_rmse_m,
            endpoint_gap_m=self.endpoint_gap_m,
            nees_mean=self.nees_mean,
            nees_in_bounds=self.nees_in_bounds,
            nis_mean=self.nis_mean,
            step_median_ms=None if latency is None else latency.median,
            step_p95_ms=None if latency is None else latency.p95,
            step_max_ms=None if latency is None else latency.max,
            total_s=self.total_s,
            nis_median=self.nis_median,
            nees_band=self.nees_band,
        )


@dataclass(frozen=True)
class Series:
    """Per-step record of an online estimator over a replay (N steps); NaN where a value does not exist."""

    t: Array
    """Step times, seconds, shape (N,)."""
    poses: Array
    """Each pose as estimated when it was the newest, in the estimator's frame, shape (N, 3)."""
    position_error_m: Array
    """Distance to the true position after the replay's alignment, shape (N,)."""
    position_sigma_m: Array
    """Square root of the trace of the 2x2 position covariance (the RMS of the radial error), shape (N,)."""
    position_cov: Array
    """The 2x2 position covariance of each pose as estimated when it was the newest, in the estimator's frame,
    shape (N, 2, 2); NaN where the estimator gave none."""
    nees: Array
    """Pose NEES, 3 dof, shape (N,)."""
    nis: Array
    """Mean NIS of the step's observations, 2 dof, shape (N,)."""
    step_ms: Array
    """Wall time of the step, milliseconds, shape (N,)."""


@dataclass(frozen=True)
class InputReport:
    """What the reader skipped (``--on-error skip``)."""

    skipped_lines: int = 0
    """Bad lines skipped."""
    skipped_by_reason: dict[str, int] = field(default_factory=dict)
    """Their count by reason (``invalid_json``, ``time_order``, ``not_finite``, ``unknown_type``, ``late``, ...)."""
    after_last_odometry: int = 0
    """Sightings stamped after the last odometry line (nothing spans their time): put on the last pose."""

    def to_json(self) -> dict[str, Any]:
        """The ``"input"`` object of the results JSON."""
        return {
            "skipped_lines": self.skipped_lines,
            "skipped_by_reason": dict(sorted(self.skipped_by_reason.items())),
            "after_last_odometry": self.after_last_odometry,
        }


@dataclass(frozen=True)
class Results:
    """Everything a replay produced."""

    source: str
    """Name of the source (path, ``<stdin>`` or built-in world)."""
    poses: int
    """Number of poses (steps) replayed."""
    landmarks: int
    """Number of distinct landmarks observed."""
    observations: int
    """Number of observations given to the estimators."""
    odometry: OdometryResult
    """Dead-reckoning figures."""
    estimators: dict[str, EstimatorResult]
    """Figures per estimator, by name."""
    estimates: dict[str, Estimate] = field(default_factory=dict, repr=False)
    """Final estimates per estimator (``odometry`` included), for plots and further analysis."""
    alignment: str = "anchor"
    """How estimates were put in the truth's frame: ``anchor`` (first pose) or ``se2`` (least squares)."""
    series: dict[str, Series] = field(default_factory=dict, repr=False)
    """Per-step records of the online estimators, for plots and consistency tests."""
    truth_poses: Array | None = field(default=None, repr=False)
    """True poses by step (NaN rows where the stream had none), shape (N, 3), or None without truth."""
    truth_offsets: dict[int, Array] = field(default_factory=dict, repr=False)
    """Steps whose position-only truth is of a robot-frame point (a GPS antenna): that point ``[dx, dy]``."""
    truth_starts: dict[int, Array] = field(default_factory=dict, repr=False)
    """Start priors' poses by step: where ``anchor`` puts the truth (``GroundTruth.starts``)."""
    truth_landmarks: dict[Any, Array] = field(default_factory=dict, repr=False)
    """True landmark positions by id."""
    error: str | None = None
    """The input error (or failed checkpoint write) that ended the replay early, or None; the figures cover what
    came before it."""
    input: InputReport = field(default_factory=InputReport)
    """Lines skipped by the reader (``--on-error skip``)."""
    step_times: Array | None = field(default=None, repr=False)
    """Time of every step, seconds, shape (N,)."""
    robot: int | str | None = None
    """The robot the stream's header names (``"robot"`` in its metadata, e.g. an MRCLAM robot), or None."""
    left: tuple[str, ...] = ()
    """Estimators that did not run to the end: they take one robot at a time and a second robot began."""
    step_robots: tuple[int | str | None, ...] = field(default=(), repr=False)
    """With several robots: the robot of every step, length N (empty with one robot)."""
    warning: str | None = None
    """Why the input looks wrong (most of the first sightings rejected or lines skipped) and its likely cause, or
    None."""
    map: MapReport | None = None
    """The map started from and the final map (see :class:`MapReport`)."""

    def rows(self) -> dict[str, Row]:
        """One flat record per estimator by name, dead reckoning (``odometry``) first: its online figures are its
        final ones, and it takes no time."""
        rows = {"odometry": self.odometry.row()}
        rows.update((name, result.row()) for name, result in self.estimators.items())
        return rows

    def to_json(self) -> dict[str, Any]:
        """The documented JSON schema of ``online-slam replay --json``."""
        return {
            "source": self.source,
            "robot": self.robot,
            "poses": self.poses,
            "landmarks": self.landmarks,
            "observations": self.observations,
            "alignment": self.alignment,
            "odometry": self.odometry.to_json(),
            "estimators": {name: result.to_json() for name, result in self.estimators.items()},
            "input": self.input.to_json(),
            "error": self.error,
            "trajectory_times": [] if self.step_times is None else [float(t) for t in self.step_times],
            "warning": self.warning,
            **({"left": list(self.left)} if self.left else {}),
            "map": None if self.map is None else self.map.to_json(),
        }
