"""Sensors mounted off the robot's centre: the models with a mounting (Jacobians against numerical ones), a stream
that declares its sensors, every estimator on it, and the checks on the declarations."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import numerical_jacobian

from online_slam import ReplayConfig, Slam, replay
from online_slam.errors import InputError
from online_slam.estimators.smoother.prior import fuse_repeats
from online_slam.geometry import compose
from online_slam.models.observation import (
    POSITION,
    RANGE_BEARING,
    SIGHTING,
    centred,
    landmark_from_sighting,
    landmark_from_sighting_with_jacobians,
    predict,
    predict_with_jacobians,
)
from online_slam.sources.events import Header, Observation
from online_slam.sources.timing import TimingConfig, timing_world
from online_slam.sources.validate import validate_events

MOUNT = (0.3, -0.05, math.radians(10))


def _models(tags: list[int], mount: tuple[float, float, float]) -> np.ndarray:
    models = np.zeros(len(tags), dtype=SIGHTING)
    models["tag"], models["mount"] = tags, mount
    return models


@pytest.mark.parametrize("tag", [RANGE_BEARING, POSITION])
def test_mounted_models_and_their_jacobians(rng: np.random.Generator, tag: int) -> None:
    for _ in range(20):
        pose, landmark = rng.normal(size=3) * [5, 5, 3], rng.normal(size=2) * 6
        mount = rng.normal(size=3) * [0.4, 0.4, 1.0]
        model = _models([tag], tuple(mount))[0]
        z, J_p, J_l = predict_with_jacobians(pose, landmark, model)
        np.testing.assert_allclose(z, predict(compose(pose, mount), landmark, tag), atol=1e-12)
        np.testing.assert_allclose(
            J_p,
            numerical_jacobian(lambda p: predict(p, landmark, model), pose, (1,) if tag == RANGE_BEARING else ()),
            atol=1e-6,
        )
        np.testing.assert_allclose(
            J_l,
            numerical_jacobian(lambda x: predict(pose, x, model), landmark, (1,) if tag == RANGE_BEARING else ()),
            atol=1e-6,
        )
        back, L_p, L_z = landmark_from_sighting_with_jacobians(pose, z, model)
        np.testing.assert_allclose(back, landmark, atol=1e-9)
        np.testing.assert_allclose(
            L_p, numerical_jacobian(lambda p: landmark_from_sighting(p, z, model), pose), atol=1e-6
        )
        np.testing.assert_allclose(
            L_z, numerical_jacobian(lambda x: landmark_from_sighting(pose, x, model), z), atol=1e-6
        )


def test_a_centre_mounting_gives_the_plain_models_numbers(rng: np.random.Generator) -> None:
    pose, landmarks = rng.normal(size=(6, 3)), rng.normal(size=(6, 2)) * 4
    tags = np.array([0, 1, 0, 1, 1, 0], dtype=np.int8)
    plain = predict_with_jacobians(pose, landmarks, tags)
    for a, b in zip(plain, predict_with_jacobians(pose, landmarks, _models(list(tags), (0.0, 0.0, 0.0)))):
        np.testing.assert_array_equal(a, b)


def test_repeats_from_two_sensors_fuse_at_the_centre() -> None:
    pose, landmark = np.array([1.0, 2.0, 0.4]), np.array([4.0, 5.0])
    models = np.concatenate([_models([RANGE_BEARING], MOUNT), _models([POSITION], (-0.2, 0.1, -0.3))])
    z = np.stack([predict(pose, landmark, m) for m in models])
    cov = np.stack([np.diag([0.05**2, 0.01**2]), np.diag([0.04**2, 0.04**2])])
    indices, fused_z, fused_cov, fused_model = fuse_repeats(np.array([7, 7]), z, cov, models)
    assert list(indices) == [7] and fused_model.dtype == SIGHTING
    np.testing.assert_allclose(landmark_from_sighting(pose, fused_z[0], fused_model[0]), landmark, atol=1e-9)
    points, point_covs = centred(z, cov, models)
    assert np.all(np.linalg.eigvalsh(fused_cov[0]) < np.linalg.eigvalsh(point_covs).min(axis=0) + 1e-12)


def test_a_stream_from_a_mounted_sensor_gives_the_truth_in_every_estimator() -> None:
    quiet = TimingConfig(duration=12.0, seed=3, odometry_sigma=(1e-5, 1e-5, 1e-6), sensor_sigma=(1e-5, 1e-6))
    events = list(timing_world(dataclasses.replace(quiet, mount=MOUNT)))
    assert events[0].meta["sensors"] == {"camera": {"pose": list(MOUNT)}}
    results = replay(events, ReplayConfig(estimators=("ekf", "smoother", "batch")))
    for name, row in results.rows().items():
        if name != "odometry":
            assert row.final_rmse_m < 1e-4 and row.landmark_rmse_m < 1e-4, name
    # read as if at the centre, the same sightings put the map off by the mounting
    bare = [
        dataclasses.replace(e, sensor=None)
        if isinstance(e, Observation)
        else (Header(e.name, {k: v for k, v in e.meta.items() if k != "sensors"}) if isinstance(e, Header) else e)
        for e in events
    ]
    assert replay(bare, ReplayConfig(estimators=("batch",))).rows()["batch"].landmark_rmse_m > 0.1


def test_association_confirms_landmarks_from_a_mounted_sensor() -> None:
    """Without ids the smoother keeps a tentative landmark's earlier sightings, and adds them when it is
    confirmed, with their mounting (once stored as a bare tag, which failed on MRCLAM's declared cameras)."""
    quiet = TimingConfig(
        duration=12.0, seed=3, landmarks=40, odometry_sigma=(1e-4, 1e-4, 1e-5), sensor_sigma=(1e-4, 1e-5)
    )
    events = list(timing_world(dataclasses.replace(quiet, mount=MOUNT)))
    results = replay(events, ReplayConfig(estimators=("smoother",), association="jcbb"))
    score = results.estimators["smoother"].association
    # the sightings left are those of landmarks seen too few times to be confirmed
    assert score is not None and score.accuracy is not None and score.accuracy > 0.8
    assert results.rows()["smoother"].final_rmse_m < 1e-3


def test_slam_takes_sightings_from_a_declared_sensor() -> None:
    pose, landmark = np.array([1.0, 0.0, 0.2]), np.array([4.0, 2.0])
    slam = Slam("ekf")
    slam.add({"type": "header", "sensors": {"front": {"pose": list(MOUNT)}}})
    slam.start(0.0, [0.0, 0.0, 0.0])
    slam.add_odometry(1.0, list(pose), sigma=[1e-4, 1e-4, 1e-5])
    r, b = predict(compose(pose, MOUNT), landmark, RANGE_BEARING)
    slam.add_observation(1.0, 9, range=float(r), bearing=float(b), sigma=[1e-3, 1e-4], sensor="front")
    np.testing.assert_allclose(slam.estimate().landmarks[9], landmark, atol=1e-3)
    with pytest.raises(InputError, match='unknown sensor "back"; declared: front'):
        slam.add_observation(1.0, 9, range=1.0, bearing=0.0, sigma=[0.1, 0.01], sensor="back")
    with pytest.raises(InputError) as caught:
        slam.add_observations(1.0, [9], [1.0], [0.0], sigma=[0.1, 0.01], sensor="back")
    assert caught.value.field == "sensor"


@pytest.mark.parametrize(
    ("sensors", "field"),
    [
        ({"cam": {"pose": [0.1, 0.0]}}, "pose"),
        ({"cam": {"pose": [0.1, 0.0, 45.0]}}, "sensors.cam.pose[2]"),
        ({"cam": [0.1, 0.0, 0.0]}, "sensors.cam"),
        ([], "sensors"),
    ],
)
def test_sensor_declarations_are_checked(sensors: object, field: str) -> None:
    with pytest.raises(InputError) as caught:
        list(validate_events([{"type": "header", "sensors": sensors}]))
    assert caught.value.field == field


def test_an_observation_names_a_declared_sensor_and_a_robot_sighting_none() -> None:
    head = {"type": "header", "sensors": {"cam": {"pose": [0.1, 0.0, 0.0]}}}
    sighting = {"type": "observation", "t": 0.0, "landmark": 1, "range": 2.0, "bearing": 0.1, "sigma": [0.1, 0.01]}
    events = list(validate_events([head, {**sighting, "sensor": "cam"}]))
    assert events[1].sensor == "cam" and events[1].to_record()["sensor"] == "cam"
    with pytest.raises(InputError, match='unknown sensor "lidar"'):
        list(validate_events([head, {**sighting, "sensor": "lidar"}]))
    with pytest.raises(InputError, match="declare them in the header"):
        list(validate_events([{**sighting, "sensor": "cam"}]))


def test_g2o_gets_a_mounted_sighting_in_the_robot_frame(tmp_path) -> None:
    from online_slam.importers.g2o.reader import write_g2o

    head = {"type": "header", "sensors": {"cam": {"pose": list(MOUNT)}}}
    sighting = {"type": "observation", "t": 0.0, "landmark": 1, "xy": [2.0, 0.5], "sigma": [0.1, 0.2], "sensor": "cam"}
    path = tmp_path / "one.g2o"
    write_g2o(path, validate_events([head, sighting]))
    edge = next(line for line in path.read_text().splitlines() if line.startswith("EDGE_SE2_XY")).split()
    np.testing.assert_allclose([float(edge[3]), float(edge[4])], compose(MOUNT, [2.0, 0.5, 0.0])[:2])
    vertex = next(line for line in path.read_text().splitlines() if line.startswith("VERTEX_XY")).split()
    np.testing.assert_allclose([float(vertex[2]), float(vertex[3])], compose(MOUNT, [2.0, 0.5, 0.0])[:2])
