"""What a replay runs: its configuration and the estimators built from it."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from online_slam.errors import OnlineSlamError
from online_slam.estimators.association_config import ASSOCIATION_CHOICES
from online_slam.estimators.batch_config import BatchConfig
from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.smoother.config import SmootherConfig
from online_slam.frontend.steps import FrontEndConfig

if TYPE_CHECKING:
    from online_slam.estimators.protocol import Estimator


@dataclass(frozen=True)
class Checkpointing:
    """Where and how often a replay saves its whole state (see :func:`~online_slam.pipeline.replay`)."""

    directory: Path
    """Folder of the checkpoint (``replay.ckpt`` inside it, replaced atomically each time)."""
    every: int = 100
    """Steps between checkpoints (>= 1)."""

    def __post_init__(self) -> None:
        if self.every < 1:
            raise OnlineSlamError("--checkpoint-every must be >= 1")


@dataclass(frozen=True)
class MapConfig:
    """A map to start from (``--map``; docs/commands.md, "Maps: save and reuse")."""

    path: str | None = None
    """The map file (``online-slam-map`` JSON), or None: no map."""
    fixed: bool = False
    """Its landmarks are known (held), not priors with their covariances."""
    only: bool = False
    """Sightings of landmarks not in the map are skipped (counted), never added; needs sightings with ids."""


ESTIMATORS = ("ekf", "smoother", "batch")
"""Names of the estimators ``replay`` can run (all run by default)."""


@dataclass(frozen=True)
class ReplayConfig:
    """What a replay runs and how it is evaluated."""

    estimators: tuple[str, ...] = ESTIMATORS
    """Estimators to run beside dead reckoning, by name."""
    frontend: FrontEndConfig = field(default_factory=FrontEndConfig)
    """How events become steps (keyframing, first-observation-only ablation)."""
    ekf: EkfConfig = field(default_factory=EkfConfig)
    """Settings of the EKF."""
    smoother: SmootherConfig = field(default_factory=SmootherConfig)
    """Settings of the sliding-window smoother."""
    extra_smoothers: tuple[SmootherConfig, ...] = ()
    """Further smoother configurations run side by side, each named by what its window is
    (:func:`~online_slam.estimators.presets.smoother_label`)."""
    batch: BatchConfig = field(default_factory=BatchConfig)
    """Settings of the batch solver."""
    alignment: str = "anchor"
    """Frame for errors: ``anchor`` (first pose with truth) or ``se2`` (least-squares rigid alignment)."""
    dataset: dict[str, Any] = field(default_factory=dict)
    """Options for dataset sources: ``format``, ``robot`` (MRCLAM), ``truth``, ``dt``, ``convention``."""
    association: str = "auto"
    """Data association: ``known`` (the stream's ids; a sighting without one is associated by JCBB), ``nn`` or
    ``jcbb`` (every sighting associated by each online estimator against its own belief; ids only score it;
    batch solves with the associations of the estimate it starts from), or ``auto`` (default): ``known`` when the
    stream's first sighting has an id, else ``jcbb``."""
    on_error: str = "stop"
    """A bad line of a stream file or stdin: ``stop`` the replay there (figures cover what came before), or
    ``skip`` it and go on (counted in ``Results.input``; the results equal those of the stream without it)."""
    map: MapConfig = field(default_factory=MapConfig)
    """A map to start from: its landmarks as priors, or known (see :class:`MapConfig`)."""
    strict: bool = False
    """When most of the first sightings are rejected, or lines skipped (wrong units?), stop there with an error
    (figures cover what came before), not only warn (:mod:`~online_slam.pipeline.units`)."""

    def __post_init__(self) -> None:
        if self.on_error not in ("stop", "skip"):
            raise OnlineSlamError(f"on_error must be 'stop' or 'skip', not {self.on_error!r}")
        if self.association not in ("auto", *ASSOCIATION_CHOICES):
            raise OnlineSlamError(
                f"association must be one of auto, {', '.join(ASSOCIATION_CHOICES)}, not {self.association!r}"
            )

    def with_association(self, method: str) -> ReplayConfig:
        """This configuration with every estimator set to associate by ``method`` (``known``, ``nn``, ``jcbb``)."""
        config = dataclasses.replace(
            self,
            association=method,
            ekf=_associating(self.ekf, method, self.map.only),
            smoother=_associating(self.smoother, method, self.map.only),
            extra_smoothers=tuple(_associating(s, method, self.map.only) for s in self.extra_smoothers),
            batch=dataclasses.replace(self.batch, use_ids=method == "known"),
        )
        if method != "known" and "batch" in config.estimators:
            online = {"ekf", "smoother"} & set(config.estimators) or config.extra_smoothers
            if config.batch.initial == "odometry" or not online:
                raise OnlineSlamError(
                    "batch without ids solves with the associations of an EKF or a smoother of the same run: "
                    "run one, and do not start batch from odometry"
                )
        return config


def _associating(config: Any, method: str, map_only: bool = False) -> Any:
    """An EKF or smoother configuration with its association method replaced; ``map_only`` (``--map-only``): the
    sightings it associates start no landmark (with ids, the replay leaves out those of other landmarks itself)."""
    association = dataclasses.replace(config.association, method=method, new_landmarks=not map_only)
    return dataclasses.replace(config, association=association)


def make_estimator(name: str, config: ReplayConfig) -> Estimator:
    """Build an estimator by name."""
    from online_slam.estimators.batch import BatchEstimator
    from online_slam.estimators.ekf import EkfSlam
    from online_slam.estimators.smoother import SlidingWindowSmoother

    if name == "ekf":
        return EkfSlam(config.ekf)
    if name == "smoother":
        return SlidingWindowSmoother(config.smoother)
    if name == "batch":
        return BatchEstimator(config.batch)
    raise OnlineSlamError(f"unknown estimator {name!r}; expected one of {', '.join(ESTIMATORS)}")


def build_estimators(config: ReplayConfig) -> list[Estimator]:
    """The estimators a replay with this configuration runs, in table order (extra smoothers after the rest)."""
    from online_slam.estimators.presets import smoother_label
    from online_slam.estimators.smoother import SlidingWindowSmoother

    estimators = [make_estimator(n, config) for n in config.estimators]
    for extra in config.extra_smoothers:
        estimators.append(SlidingWindowSmoother(extra, name=smoother_label(extra)))
    names = [e.name for e in estimators]
    if len(set(names)) != len(names):
        raise OnlineSlamError(f"estimator names repeat: {', '.join(names)}")
    return estimators


def estimator_names(config: ReplayConfig) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Names of the estimators a replay runs: (online ones, dead reckoning first; those with a final estimate only)."""
    estimators = build_estimators(config)
    online = ("odometry", *(e.name for e in estimators if e.online))
    return online, tuple(e.name for e in estimators if not e.online)
