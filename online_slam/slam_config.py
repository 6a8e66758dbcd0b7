"""What a :class:`~online_slam.slam.Slam` runs: its estimators and options, and the configurations built from
them."""

from __future__ import annotations

from typing import Any

from online_slam.errors import ConfigError
from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.smoother import SmootherConfig
from online_slam.frontend.steps import FrontEndConfig
from online_slam.options import Option, check_value, estimator_options, replay_config
from online_slam.wording import did_you_mean

ESTIMATORS = ("ekf", "smoother")
"""Estimators a :class:`Slam` can run (names are case-insensitive)."""
NOT_ONLINE = {
    "batch": "the batch solver is not an online estimator: it solves the whole stream at its end. Run it with "
    'online_slam.replay(events, online_slam.ReplayConfig(estimators=("batch",))) (events: a list of event objects '
    "or stream-v1 records, a stream path or a world name) and read .estimates['batch']",
}
"""Estimators of a replay that a :class:`Slam` cannot run, and what to do instead."""

OPTIONS: dict[str, Option] = estimator_options()
"""Options of :class:`Slam`: the estimator options of :mod:`online_slam.options`, named as the CLI's flags
(``--relinearize-every`` -> ``relinearize_every``); each estimator takes its own, the front-end's and the
association's."""


def configs(estimator: str, options: dict[str, Any]) -> tuple[EkfConfig | SmootherConfig, FrontEndConfig]:
    """Check the options and build the estimator's and the front-end's configurations (the CLI's translation)."""
    if estimator in NOT_ONLINE:
        raise ConfigError(f"Slam({estimator!r}): {NOT_ONLINE[estimator]}")
    if estimator not in ESTIMATORS:
        raise ConfigError(f"estimator must be one of {', '.join(ESTIMATORS)}, not {estimator!r}")
    for key, value in options.items():
        if key not in OPTIONS:
            takes = sorted(name for name, o in OPTIONS.items() if o.fits(estimator))
            raise ConfigError(
                f"unknown option {key!r}{did_you_mean(key, takes)}; {estimator} options: {', '.join(takes)}"
            )
        option = OPTIONS[key]
        check_value(option, value)
        if not option.fits(estimator):
            owners = " and the ".join(option.owners)
            raise ConfigError(f"option {key} is for the {owners}, not the {estimator} (a Slam runs ekf or smoother)")
    method = options.get("association", "auto")
    config = replay_config({**options, "estimators": estimator}).with_association(
        "known" if method == "auto" else method  # no stream to look ahead in: ids where given, else JCBB
    )
    return (config.ekf if estimator == "ekf" else config.smoother), config.frontend


def typed_configs(
    estimator: str | None, config: EkfConfig | SmootherConfig | None, frontend: FrontEndConfig | None
) -> tuple[str, EkfConfig | SmootherConfig, FrontEndConfig]:
    """``Slam(config=..., frontend=...)``: the estimator named by ``estimator`` or by the config's type, checked."""
    by_type: dict[type, str] = {EkfConfig: "ekf", SmootherConfig: "smoother"}
    if config is not None and type(config) not in by_type:
        raise ConfigError(f"Slam: config must be an EkfConfig or a SmootherConfig, not {type(config).__name__}")
    if frontend is not None and not isinstance(frontend, FrontEndConfig):
        raise ConfigError(f"Slam: frontend must be a FrontEndConfig, not {type(frontend).__name__}")
    name = (estimator or (by_type[type(config)] if config is not None else "smoother")).strip().lower()
    default, default_frontend = configs(name, {})
    if config is not None and by_type[type(config)] != name:
        raise ConfigError(f"Slam({name!r}): config is a {type(config).__name__}, for the {by_type[type(config)]}")
    return name, config if config is not None else default, frontend if frontend is not None else default_frontend
