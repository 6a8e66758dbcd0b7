"""``--noise fit`` and ``--noise self`` for a replay: the source read once to fit its noise (to its truth:
:mod:`online_slam.evaluation.noise_fit`; to its own data: :mod:`online_slam.evaluation.noise_self`), then replayed
with the fitted scales (and, for ``self``, each sensor's bias taken off its sightings)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from pathlib import Path

from online_slam.errors import OnlineSlamError
from online_slam.evaluation.noise_fit import NoiseFit, fit_noise
from online_slam.evaluation.noise_self import SelfFit, fit_self, own_sensor_scale
from online_slam.frontend.steps import FrontEnd, Step
from online_slam.pipeline.config import ReplayConfig, make_estimator
from online_slam.pipeline.source import open_events
from online_slam.sources.address import is_live
from online_slam.sources.events import Event

FITS = ("fit", "self")
"""The values of the ``noise`` option that fit the noise before the replay."""

Fit = NoiseFit | SelfFit
"""What a fit of the noise gives: against truth, or from the data alone."""


def fits_noise(config: ReplayConfig) -> bool:
    """Whether the configuration asks for ``--noise fit`` or ``--noise self``."""
    return config.dataset.get("noise") in FITS


def fit_source_noise(
    source: str | Path | Iterable[Event], config: ReplayConfig
) -> tuple[Fit, str | Path | Iterable[Event]]:
    """Read a source once through the front-end (every noise scale at 1, no bias) and fit its noise.

    Returns:
        The fit, and the source to replay: the same path or world, or the events of an iterable kept in a list
        (a Monte Carlo run's world, read once here).

    Raises:
        OnlineSlamError: Standard input (read only once); a source without truth to fit to (``fit``), or without
            a landmark sighting with an id (``self``).
        InputError: The source cannot be read.
    """
    mode = config.dataset["noise"]
    if is_live(source):
        what = "stdin" if str(source) == "-" else "a TCP stream"
        raise OnlineSlamError(f"--noise {mode} reads the source twice (fit, then replay): give a file, not {what}")
    if not isinstance(source, (str, Path)):
        source = list(source)
    plain = dataclasses.replace(config.frontend, odometry_noise_scale=1.0, sensor_noise_scale=1.0, sensor_bias=())
    opened = open_events(source, dataclasses.replace(config, frontend=plain, association="known"))
    frontend = FrontEnd(plain)
    steps = frontend.steps(opened.events)
    if mode == "fit":
        fit: Fit = fit_noise(steps, frontend.truth)
        return dataclasses.replace(fit, sightings_correlated=frontend.sightings_correlated), source
    listed = list(steps)  # read to the end: the header is known
    return _fit_self(listed, config, frontend), source


def _fit_self(steps: list[Step], config: ReplayConfig, frontend: FrontEnd) -> SelfFit:
    """``--noise self`` on the steps, started from the estimate of an EKF of the replay's settings over them (the
    batch from composed odometry can stop in a poor minimum; the EKF costs a small part of the fit); for correlated
    sightings, also against their own covariances (:func:`~online_slam.evaluation.noise_self.own_sensor_scale`),
    read against the range the header declares for them."""
    ekf = make_estimator("ekf", config.with_association("known"))
    for step in steps:
        ekf.step(step)
    initial = ekf.finish()
    correlated = frontend.sightings_correlated
    own = own_sensor_scale(steps, initial=initial) if correlated else None
    return dataclasses.replace(
        fit_self(steps, initial=initial),
        sightings_correlated=correlated,
        own_sensor_scale=own,
        own_range=frontend.sightings_own_scale if correlated else None,
    )


def with_noise_fit(config: ReplayConfig, fit: Fit) -> ReplayConfig:
    """The configuration with the fitted scales (and biases) in its front-end."""
    frontend = dataclasses.replace(
        config.frontend, odometry_noise_scale=fit.odometry_scale, sensor_noise_scale=fit.applied_sensor_scale
    )
    if isinstance(fit, SelfFit):
        frontend = dataclasses.replace(frontend, sensor_bias=fit.sensor_bias)
    return dataclasses.replace(config, frontend=frontend)
