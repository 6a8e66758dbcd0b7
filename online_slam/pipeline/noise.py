"""``--noise fit`` for a replay: the source read once to fit its noise scales to its truth, then replayed with them
(see :mod:`online_slam.evaluation.noise_fit`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from pathlib import Path

from online_slam.errors import OnlineSlamError
from online_slam.evaluation.noise_fit import NoiseFit, fit_noise
from online_slam.frontend.steps import FrontEnd
from online_slam.pipeline.config import ReplayConfig
from online_slam.pipeline.source import open_events
from online_slam.sources.events import Event


def fits_noise(config: ReplayConfig) -> bool:
    """Whether the configuration asks for ``--noise fit``."""
    return config.dataset.get("noise") == "fit"


def fit_source_noise(
    source: str | Path | Iterable[Event], config: ReplayConfig
) -> tuple[NoiseFit, str | Path | Iterable[Event]]:
    """Read a source once through the front-end (every noise scale at 1) and fit its noise to its truth.

    Returns:
        The fit, and the source to replay: the same path or world, or the events of an iterable kept in a list
        (a Monte Carlo run's world, read once here).

    Raises:
        OnlineSlamError: Standard input (read only once), or a source without truth to fit to.
        InputError: The source cannot be read.
    """
    if str(source) == "-":
        raise OnlineSlamError("--noise fit reads the source twice (fit, then replay): give a file, not stdin")
    if not isinstance(source, (str, Path)):
        source = list(source)
    plain = dataclasses.replace(config.frontend, odometry_noise_scale=1.0, sensor_noise_scale=1.0)
    opened = open_events(source, dataclasses.replace(config, frontend=plain, association="known"))
    frontend = FrontEnd(plain)
    fit = fit_noise(frontend.steps(opened.events), frontend.truth)
    correlated = frontend.header is not None and bool(frontend.header.meta.get("sightings_correlated"))
    return dataclasses.replace(fit, sightings_correlated=correlated), source


def with_noise_fit(config: ReplayConfig, fit: NoiseFit) -> ReplayConfig:
    """The configuration with the fitted scales in its front-end."""
    frontend = dataclasses.replace(
        config.frontend, odometry_noise_scale=fit.odometry_scale, sensor_noise_scale=fit.applied_sensor_scale
    )
    return dataclasses.replace(config, frontend=frontend)
