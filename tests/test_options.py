"""The option table: one definition per option, from which the CLI, Slam, sweep and the docs all come."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import pytest

from online_slam import ConfigError, Slam
from online_slam.cli.main import build_parser
from online_slam.estimators.batch import BatchConfig
from online_slam.estimators.smoother import WindowConfig
from online_slam.options import (
    CONFIGS,
    GROUPS,
    OPTIONS,
    Option,
    estimator_options,
    field_default,
    flag,
    markdown,
    replay_config,
)
from online_slam.pipeline import ReplayConfig
from online_slam.sinks.recording.writer import RerunConfig
from online_slam.slam import OPTIONS as SLAM_OPTIONS
from online_slam.slam_config import configs
from online_slam.solvers.least_squares import SolverConfig
from online_slam.sources.meet import MeetConfig
from online_slam.sources.worlds import GridConfig
from online_slam.sweep import SETTINGS, make_cells

DOCS = Path(__file__).resolve().parents[1] / "docs" / "options.md"


def test_the_docs_option_list_is_the_tables_rendering() -> None:
    """docs/options.md cannot drift (regenerate it as the module docstring of online_slam.options says)."""
    assert DOCS.read_text(encoding="utf-8") == markdown()


def test_defaults_are_read_from_the_configurations_in_light_modules() -> None:
    """No generated copy: each option's default and type are its dataclass field's, and every configuration
    module imports without the numerical libraries (so that --help does not load them)."""
    for option in estimator_options().values():
        if option.field is not None:
            default = field_default(option.field)
            assert option.kind is type(default) or default is None and option.unset, option.name
    code = (
        "import sys, importlib\n"
        f"for m in {sorted(set(CONFIGS.values()))!r}: importlib.import_module(m)\n"
        "print(sorted({n.split('.')[0] for n in sys.modules} & {'scipy', 'filterpy', 'qdldl'}))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.strip() == "[]", done.stdout + done.stderr


def test_every_option_has_a_group_a_unique_flag_and_lands_on_a_real_field() -> None:
    assert len({o.flag for o in OPTIONS.values()}) == len(OPTIONS)
    for option in OPTIONS.values():
        assert option.group in GROUPS and option.help and "\n" not in option.help
        for path in option.lands:
            target = ReplayConfig(frontend=dataclasses.replace(ReplayConfig().frontend, keyframing=_keyframes()))
            *parents, last = path.split(".")
            for part in parents:
                target = getattr(target, part)
            assert isinstance(target, dict) or last in {f.name for f in dataclasses.fields(target)}, path


def _keyframes():  # noqa: ANN202 - the front-end's keyframe settings
    from online_slam.frontend.steps import KeyframeConfig

    return KeyframeConfig()


def test_defaults_are_the_configs() -> None:
    assert OPTIONS["window"].value == WindowConfig.size
    assert OPTIONS["window_distance"].shown_default() == f"{WindowConfig.distance:g} m"
    assert "deg)" in OPTIONS["keyframe_angle"].shown_default()
    assert replay_config({}) == ReplayConfig()  # no options: the configurations' own defaults


def _sample(option: Option) -> object:
    """A value other than the default, valid for the option."""
    if option.kind is bool:
        return True
    if option.choices:
        return option.choices[-1]
    if option.name == "odometry_bias":  # text: prior sigmas
        return "0.02,0.003"
    base = option.value if option.value is not None else field_default(option.field)
    if base is None:  # resolved later (e.g. --max-latency by the source)
        return 2 if option.kind is int else 0.25
    if option.kind is int:
        return base + 1
    return 0.01 if base == 0 else base if math.isinf(base) else base * 0.5


def _cli_args(option: Option, value: object) -> list[str]:
    return [option.flag] if option.kind is bool else [option.flag, str(value)]


@pytest.mark.parametrize("name", sorted(estimator_options()))
def test_cli_slam_and_sweep_take_every_estimator_option_the_same_way(name: str) -> None:
    """replay, compare and sweep parse it, Slam takes it for an estimator it configures, and all four translate
    it into the same configuration."""
    option = OPTIONS[name]
    value = _sample(option)
    parser = build_parser()
    replay = replay_config(vars(parser.parse_args(["replay", *_cli_args(option, value)])), flag)
    compared = vars(parser.parse_args(["compare", *_cli_args(option, value)]))
    assert compared[name] in (value, (value,))
    swept = vars(parser.parse_args(["sweep", "square", *_cli_args(option, value)]))
    (cell,) = make_cells(["square"], {name: swept[name]})
    assert cell.config() == replay
    method = replay.association if replay.association != "auto" else "known"
    expected = replay.with_association(method)
    for estimator in ("ekf", "smoother"):
        if not option.fits(estimator):
            with pytest.raises(ConfigError, match=f"is for the {option.owners[0]}"):
                Slam(estimator, **{name: value})
            continue
        config, frontend = configs(estimator, {name: value})
        assert config == (expected.ekf if estimator == "ekf" else expected.smoother)
        assert frontend == expected.frontend


def test_cli_slam_and_sweep_accept_the_same_set_of_estimator_options() -> None:
    parser = build_parser()
    for command in ("replay", "compare"):
        assert set(estimator_options()) <= set(vars(parser.parse_args([command])))
    swept = {name for name in vars(parser.parse_args(["sweep", "square"])) if name in OPTIONS}
    sweep_settings = {name for name in swept if OPTIONS[name].estimator}
    assert set(SLAM_OPTIONS) == set(estimator_options()) == set(SETTINGS) == sweep_settings


def test_slam_takes_new_density_and_refuses_bad_values() -> None:
    config, _ = configs("smoother", {"new_density": 0.002, "association": "jcbb"})
    assert config.association.new_density == 0.002 and config.association.method == "jcbb"
    with pytest.raises(ConfigError, match="for the batch"):
        Slam("smoother", max_iterations=5)
    with pytest.raises(ConfigError, match="expected one of auto, none, huber, cauchy"):
        Slam("smoother", robust="tukey")
    with pytest.raises(ConfigError, match="expected int"):
        Slam("smoother", window=2.5)
    with pytest.raises(ConfigError, match="robust_scale: must be > 0"):
        Slam("smoother", robust_scale=0.0)


def test_help_shows_each_command_its_own_notes() -> None:
    from online_slam.options import for_command

    text = OPTIONS["workers"].help
    assert "compare:" in text and "sweep:" in text  # one definition, notes for two commands
    assert "sweep" not in for_command(text, "compare") and "Monte Carlo" in for_command(text, "compare")
    assert "(a list)" in for_command(OPTIONS["window"].help, "compare")
    assert "list" not in for_command(OPTIONS["window"].help, "replay")
    assert "(Slam: known)" not in for_command(OPTIONS["association"].help, "replay")


def test_estimator_names_are_case_insensitive_as_in_slam() -> None:
    assert replay_config({"estimators": "EKF, Batch"}).estimators == ("ekf", "batch")


@pytest.mark.parametrize(
    ("config", "fields"),
    [
        (BatchConfig, {"outliers": "Auto"}),
        (BatchConfig, {"initial": "odom"}),
        (SolverConfig, {"step_tolerance": -1.0}),
        (GridConfig, {"model": "bearing"}),
        (MeetConfig, {"robots": 0}),
        (RerunConfig, {"flush_every": 0}),
    ],
)
def test_every_config_refuses_a_value_it_would_misread(config: type, fields: dict) -> None:
    """``outliers="Auto"`` once silently meant off."""
    with pytest.raises(ValueError):
        config(**fields)
