"""Generated landmark ids, a namespace apart from the stream's; streams mixing sightings with and without ids."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from online_slam import GeneratedId, Slam
from online_slam.checkpoint import from_tree, read_checkpoint, to_tree, write_checkpoint
from online_slam.errors import InputError
from online_slam.pipeline import Checkpointing, ReplayConfig, replay
from online_slam.reports.table import format_results
from online_slam.sources.events import Event, LandmarkId, LandmarkTruth, Observation
from online_slam.sources.stream import write_stream
from online_slam.sources.worlds import GridConfig, grid_world

WORLD = GridConfig(poses=150, blocks=2, landmarks=20)
USERS = ("u0", str(GeneratedId(0)))
"""User ids that look like generated ones: the old form, and what a generated id is shown as."""


def test_a_generated_id_equals_no_user_id_and_round_trips_through_a_checkpoint(tmp_path: Path) -> None:
    new = GeneratedId(0)
    assert all(new != other for other in (0, "0", "u0", "new-0", ("new", 0)))
    assert len({new, 0, "0", "new-0", GeneratedId(0)}) == 4
    assert sorted([GeneratedId(2), GeneratedId(0)]) == [GeneratedId(0), GeneratedId(2)]
    state = {"index": {new: 3, "new-0": 4, 0: 5}, "ids": [new, "u0", 7, None]}
    hint = dict[str, dict[LandmarkId, int] | list[LandmarkId | None]]
    assert from_tree(hint, to_tree(state)) == state
    write_checkpoint(tmp_path / "c.zip", "test", to_tree(state))
    back = from_tree(hint, read_checkpoint(tmp_path / "c.zip", "test"))
    assert back == state and type(next(iter(back["index"]))) is GeneratedId


def test_a_generated_id_is_not_accepted_as_a_sighting_id() -> None:
    with pytest.raises(InputError, match="landmark"):
        Slam("ekf").add_observation(0.0, landmark=GeneratedId(0), range=2.0, bearing=0.0, sigma=[0.1, 0.01])


def _mixed(user: str) -> tuple[list[Event], LandmarkId]:
    """The world with its first-seen landmark always without an id (so a generated id is given first) and its
    last-seen landmark renamed ``user``; a few other sightings without ids. Returns the events and the first-seen
    landmark's true id."""
    events = list(grid_world(WORLD))
    order = list(dict.fromkeys(e.landmark for e in events if isinstance(e, Observation)))
    first, last = order[0], order[-1]
    rng = np.random.default_rng(1)
    out: list[Event] = []
    for event in events:
        if isinstance(event, (LandmarkTruth, Observation)) and event.landmark == last:
            event = replace(event, landmark=user)
        elif isinstance(event, Observation) and (event.landmark == first or rng.random() < 0.05):
            event = replace(event, landmark=None, truth_landmark=event.landmark)
        out.append(event)
    return out, first


@pytest.mark.parametrize("user", USERS)
def test_a_user_id_like_a_generated_one_stays_its_own_landmark_under_known_ids(user: str) -> None:
    events, first = _mixed(user)
    results = replay(events, ReplayConfig(association="known"), name="mixed")
    truth = results.truth_landmarks
    for name in ("ekf", "smoother", "batch"):
        estimate = results.estimates[name]
        where = dict(zip(estimate.landmark_ids, estimate.landmarks))
        generated = [lid for lid in where if isinstance(lid, GeneratedId)]
        assert user in where and len(generated) == 1, (name, estimate.landmark_ids)
        assert np.linalg.norm(where[user] - truth[user]) < 0.3, name  # not merged with the generated landmark
        assert np.linalg.norm(where[generated[0]] - truth[first]) < 0.3, name
        assert len(where) == WORLD.landmarks, name
        report = results.estimators[name].without_id
        assert report is not None and report.sightings == sum(
            isinstance(e, Observation) and e.landmark is None for e in events
        )
        assert report.associated >= 0.95 * report.sightings, name


@pytest.mark.parametrize("method", ["nn", "jcbb"])
def test_a_user_id_like_a_generated_one_is_scored_as_its_own_landmark_when_associating(method: str) -> None:
    events, _ = _mixed(USERS[1])
    results = replay(events, ReplayConfig(association=method), name="mixed")
    for name in ("ekf", "smoother", "batch"):
        estimate = results.estimates[name]
        assert all(isinstance(lid, GeneratedId) for lid in estimate.landmark_ids), name  # the stream's ids unused
        score = results.estimators[name].association
        assert score is not None and score.accuracy >= 0.95, (name, score)
        assert score.landmarks_true == WORLD.landmarks and score.landmarks_mapped >= WORLD.landmarks - 1, (name, score)
        assert results.estimators[name].landmark_rmse_m < 0.2, name  # each mapped landmark near its own truth


def test_sightings_without_ids_under_known_ids_are_counted_even_where_unused(tmp_path: Path) -> None:
    events, _ = _mixed("u0")
    count = sum(isinstance(e, Observation) and e.landmark is None for e in events)
    alone = replay(events, ReplayConfig(association="known", estimators=("batch",)), name="mixed")
    assert alone.estimators["batch"].without_id is not None
    assert alone.estimators["batch"].without_id.to_json() == {"sightings": count, "associated": 0}
    assert f"batch: {count} sightings without an id not used" in format_results(alone)
    assert json.loads(json.dumps(alone.to_json()))["estimators"]["batch"]["without_id"]["sightings"] == count
    clean = replay(grid_world(WORLD), ReplayConfig(estimators=("ekf",)), name="clean")
    assert clean.estimators["ekf"].without_id is None and "without_id" not in clean.to_json()["estimators"]["ekf"]


@pytest.mark.slow
def test_a_resumed_replay_keeps_generated_ids_and_the_count(tmp_path: Path) -> None:
    events, _ = _mixed("u0")
    path = tmp_path / "mixed.jsonl"
    write_stream(path, events)
    config = ReplayConfig(association="known")
    whole = replay(path, config)
    replay(path, config, checkpoint=Checkpointing(tmp_path / "ck", every=100))
    resumed = replay(path, config, resume=tmp_path / "ck")
    for name in ("ekf", "smoother", "batch"):
        a, b = whole.estimates[name], resumed.estimates[name]
        assert a.landmark_ids == b.landmark_ids and any(isinstance(i, GeneratedId) for i in a.landmark_ids), name
        np.testing.assert_array_equal(a.landmarks, b.landmarks)
        assert whole.estimators[name].without_id == resumed.estimators[name].without_id, name
