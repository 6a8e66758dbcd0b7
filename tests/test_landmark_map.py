"""Maps saved and reused: the map file, starting the estimators from a map (priors, fixed, map-only), Slam's map."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import numerical_graph_jacobian
from inprocess import run_cli

from online_slam import Slam
from online_slam.errors import ConfigError, InputError
from online_slam.factors.graph import FactorGraph, layout, linearize
from online_slam.pipeline import MapConfig, ReplayConfig, replay
from online_slam.sources.events import GeneratedId
from online_slam.sources.landmark_map import LandmarkMap, map_from_json, read_map, write_map
from online_slam.sources.worlds import square_world

ROOT = Path(__file__).resolve().parents[1]


def first_map(tmp_path: Path) -> tuple[Path, dict[str, tuple[float | None, float | None]], LandmarkMap]:
    """Run 1 on the square world: its final map written, its (online, final) errors by estimator."""
    results = replay(square_world(), name="square")
    assert results.map is not None and results.map.final is not None
    path = tmp_path / "map.json"
    write_map(path, results.map.final)
    errors = {name: (e.online_rmse_m, e.final_rmse_m) for name, e in results.estimators.items()}
    return path, errors, results.map.final


def with_map(path: Path, **kw: bool) -> ReplayConfig:
    return dataclasses.replace(ReplayConfig(), map=MapConfig(str(path), **kw))


def test_a_map_file_round_trips(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    A = rng.normal(size=(3, 2, 2))
    original = LandmarkMap.of([3, "tree-7", GeneratedId(2)], rng.normal(size=(3, 2)), A @ A.transpose(0, 2, 1), "s")
    write_map(tmp_path / "m.json", original)
    again = read_map(tmp_path / "m.json")
    assert again == original
    assert again.ids == (3, "tree-7", "new-2") and again.generated == (False, False, True)
    assert isinstance(again.ids[0], int) and isinstance(again.ids[1], str)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda t: t.update(format="other"), "format"),
        (lambda t: t.update(version=3), "version"),
        (lambda t: t.update(landmarks=3), "landmarks"),
        (lambda t: t["landmarks"][1].update(xy=[1.0]), "landmarks[1].xy"),
        (lambda t: t["landmarks"][1].update(xy=[1.0, float("nan")]), "landmarks[1].xy"),
        (lambda t: t["landmarks"][0].update(cov=[[1.0, 0.5], [0.0, 1.0]]), "landmarks[0].cov"),
        (lambda t: t["landmarks"][0].update(cov=[[-1.0, 0.0], [0.0, 1.0]]), "landmarks[0].cov"),
        (lambda t: t["landmarks"][1].update(id=1), "landmarks[1].id"),
        (lambda t: t["landmarks"][1].update(id=True), "landmarks[1].id"),
        (lambda t: t["landmarks"][1].update(colour="red"), "landmarks[1].colour"),
    ],
)
def test_a_bad_map_is_one_error_naming_the_field(change, field: str) -> None:  # noqa: ANN001
    tree = LandmarkMap.of([1, 2], [[0.0, 0.0], [1.0, 1.0]], np.tile(np.eye(2), (2, 1, 1))).to_json()
    change(tree)
    with pytest.raises(InputError) as caught:
        map_from_json(json.loads(json.dumps(tree)), "m.json")
    assert caught.value.field == field and str(caught.value).startswith(f"m.json: {field}: ")


def test_the_cli_refuses_a_bad_map_in_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "online-slam-map", "version": 1, "landmarks": [{"id": 1, "xy": [0, "a"]}]}')
    run = subprocess.run(
        [sys.executable, "-m", "online_slam", "replay", "square", "--map", str(bad)],
        capture_output=True, text=True, timeout=120, env={"PYTHONPATH": str(ROOT), "PATH": ""},
    )  # fmt: skip
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [f"online-slam: error: {bad}: landmarks[0].xy: expected 2 numbers"]


def test_the_landmark_prior_factor_has_the_numerical_jacobian() -> None:
    rng = np.random.default_rng(1)
    A = rng.normal(size=(2, 2, 2))
    graph = FactorGraph.build(2, 3, fixed_poses=[0], odo_from=[0], odo_to=[1], odo_delta=[[1.0, 0.0, 0.1]],
                              odo_cov=[np.eye(3)], obs_pose=[1], obs_landmark=[2], obs_z=[[2.0, 0.3]],
                              obs_cov=[np.eye(2)])  # fmt: skip
    W = np.linalg.inv(np.linalg.cholesky(A @ A.transpose(0, 2, 1) + np.eye(2)))
    graph = dataclasses.replace(graph, lp_landmark=np.array([0, 2]), lp_mean=rng.normal(size=(2, 2)), lp_sqrt_info=W)
    poses, landmarks = np.array([[0.0, 0.0, 0.0], [1.0, 0.1, 0.2]]), rng.normal(size=(3, 2)) + 2.0
    r, J = linearize(graph, layout(graph), poses, landmarks)
    assert np.allclose(J.toarray(), numerical_graph_jacobian(graph, poses, landmarks), atol=1e-5)
    assert len(r) == graph.n_residuals == 3 + 2 + 4


def test_localisation_on_a_saved_map_does_as_well_as_the_run_that_made_it(tmp_path: Path) -> None:
    path, first, saved = first_map(tmp_path)
    best_final = min(final for _, final in first.values() if final is not None)
    again = replay(square_world(), with_map(path), name="square")  # the same stream
    assert again.map is not None and again.map.loaded == len(saved)
    for name in ("ekf", "smoother"):
        online = again.estimators[name].online_rmse_m
        assert online is not None and online <= best_final
        assert set(again.estimates[name].landmark_ids) == set(saved.ids)  # the map did not grow
    fresh = [replay(square_world(seed), with_map(path), name="square") for seed in (1, 2, 3, 4)]  # new noise
    for name in ("ekf", "smoother"):
        online = np.mean([r.estimators[name].online_rmse_m for r in fresh])
        assert online <= best_final
    assert all(r.map is not None and r.map.final is not None and len(r.map.final) == len(saved) for r in fresh)


def test_a_fixed_map_holds_its_landmarks(tmp_path: Path) -> None:
    path, _, saved = first_map(tmp_path)
    results = replay(square_world(3), with_map(path, fixed=True), name="square")
    where = dict(zip(saved.ids, saved.xy))
    for name, tolerance in (("ekf", 0.0), ("smoother", 1e-6), ("batch", 1e-6)):
        estimate = results.estimates[name]
        held = np.array([where[lid] for lid in estimate.landmark_ids])
        assert len(held) == len(saved)
        assert np.abs(estimate.landmarks - held).max() <= tolerance, name


def test_map_only_skips_and_counts_sightings_of_other_landmarks(tmp_path: Path) -> None:
    _, _, saved = first_map(tmp_path)
    keep = [k for k, lid in enumerate(saved.ids) if lid in (0, 1, 2, 8, 9)]
    part = LandmarkMap.of([saved.ids[k] for k in keep], saved.xy[keep], saved.cov[keep])
    write_map(tmp_path / "part.json", part)
    results = replay(square_world(), with_map(tmp_path / "part.json", only=True), name="square")
    sightings = [e for e in square_world() if type(e).__name__ == "Observation"]
    outside = sum(e.landmark not in part.ids for e in sightings)
    assert results.map is not None and results.map.not_in_map == outside > 0
    assert results.observations == len(sightings) - outside
    for name in ("ekf", "smoother", "batch"):
        assert set(results.estimates[name].landmark_ids) == set(part.ids)
    assert results.to_json()["map"]["not_in_map"] == outside


def test_map_options_without_a_map_are_refused() -> None:
    with pytest.raises(ConfigError, match="--map-fixed needs --map"):
        replay(square_world(), dataclasses.replace(ReplayConfig(), map=MapConfig(None, fixed=True)))
    with pytest.raises(ConfigError, match="--map-only needs --map"):
        replay(square_world(), dataclasses.replace(ReplayConfig(), map=MapConfig(None, only=True)))


def test_map_only_without_ids_localises_and_starts_no_landmark(tmp_path: Path) -> None:
    jcbb = dataclasses.replace(ReplayConfig(), association="jcbb")
    first = replay(square_world(), jcbb, name="square")  # the map of a run without ids: generated ids
    assert first.map is not None and first.map.final is not None
    write_map(tmp_path / "map.json", first.map.final)
    size = len(first.map.final)
    config = dataclasses.replace(jcbb, map=MapConfig(str(tmp_path / "map.json"), only=True))
    for seed in (1, 2):  # fresh noise: some sightings miss every map landmark's gate
        again = replay(square_world(seed), config, name="square")
        free = replay(square_world(seed), jcbb, name="square")
        # On the map without --map-only too: the smoother's association read a map landmark not seen yet as
        # unconstrained (1e6) and lost the robot (1.41 m); it is the map's own prior now.
        grown = replay(square_world(seed), dataclasses.replace(config, map=MapConfig(config.map.path)), name="square")
        for name in ("ekf", "smoother"):
            assert grown.estimators[name].online_rmse_m < 1.5 * free.estimators[name].online_rmse_m
        for name in ("ekf", "smoother"):
            estimate, info = again.estimates[name], again.estimators[name].details["association"]
            assert set(estimate.landmark_ids) <= set(first.map.final.ids) and len(estimate.landmark_ids) == size
            assert info["not_in_map"] >= 0
            assert again.estimators[name].online_rmse_m < 1.5 * free.estimators[name].online_rmse_m
        assert again.map is not None and again.map.not_in_map == 0  # the ids were not read: scoring only


@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
def test_slam_starts_from_a_map_and_gives_its_own(tmp_path: Path, estimator: str) -> None:
    path, _, saved = first_map(tmp_path)
    slam = Slam(estimator, map=path, map_fixed=True)
    truth = [e for e in square_world() if type(e).__name__ == "Start"][0]
    slam.start(0.0, truth.pose)
    slam.add_odometry(1.0, delta=[0.7, 0.0, 0.0], sigma=[0.1, 0.1, 0.04])
    slam.add_observation(1.0, landmark=saved.ids[0], range=2.0, bearing=-2.0, sigma=[0.06, 0.014])
    mapped = slam.map()
    assert mapped.ids == saved.ids
    assert np.allclose(mapped.xy, saved.xy, atol=1e-6, rtol=0)
    slam.save_map(tmp_path / "out.json")
    assert read_map(tmp_path / "out.json").ids == saved.ids
    free = Slam(estimator, map=read_map(path))
    assert free.map().ids == saved.ids and np.allclose(free.map().cov, saved.cov)


@pytest.mark.slow
def test_the_commands_write_and_read_maps(tmp_path: Path) -> None:
    def cli(*args: str) -> subprocess.CompletedProcess:
        return run_cli(*args, cwd=tmp_path)

    survey = cli("convert", "stream", str(ROOT / "replay" / "square.jsonl"), "--map-out", "survey.json")
    assert survey.returncode == 0, survey.stderr
    known = read_map(tmp_path / "survey.json")
    assert len(known) == 12 and not known.cov.any()
    run = cli("replay", "square", "--map", "survey.json", "--map-fixed", "--map-out", "out.json", "--json", "r.json")
    assert run.returncode == 0, run.stderr
    written = read_map(tmp_path / "out.json")
    assert set(written.ids) == set(known.ids)
    where = dict(zip(known.ids, known.xy))
    assert np.abs(written.xy - np.array([where[lid] for lid in written.ids])).max() <= 1e-6
    report = json.loads((tmp_path / "r.json").read_text())["map"]
    assert report["loaded"] == 12 and report["fixed"] and report["final_landmarks"] == 12
    refused = cli("replay", "square", "--map-fixed")
    assert refused.returncode == 2 and refused.stderr.strip() == "online-slam: error: --map-fixed needs --map"


def test_a_generated_id_is_kept_apart_from_a_stream_id_of_its_name() -> None:
    mapped = LandmarkMap.of(["new-0", GeneratedId(0)], [[0.0, 0.0], [1.0, 1.0]])
    assert mapped.ids == ("new-0", "new-0#2") and mapped.generated == (False, True)
