"""The two sighting models side by side, chosen per sighting by a tag: range-bearing or position.

Every sighting carries a model tag (:data:`RANGE_BEARING` or :data:`POSITION`); arrays of sightings carry an
``int8`` array of tags beside their z. The functions here evaluate each sighting with its own model, vectorised:
one call per model present, merged by mask, so a batch of one model costs what that model alone costs (and a
range-bearing batch gives exactly the numbers of :mod:`~online_slam.models.range_bearing`). Only range-bearing
rows have an angle (the bearing) to wrap.
"""

from __future__ import annotations

from typing import Any, TypeVar, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import compose_with_jacobians
from online_slam.models.position import landmark_from_position_with_jacobians, position, position_with_jacobians
from online_slam.models.range_bearing import (
    landmark_from_observation,
    landmark_from_observation_with_jacobians,
    range_bearing,
    range_bearing_with_jacobians,
)

Array = NDArray[np.float64]
_Columns = TypeVar("_Columns", bound=tuple[Array, ...])
"""A tuple of per-sighting arrays (values and Jacobians) of one model."""

RANGE_BEARING = 0
"""Tag of a range-bearing sighting ``[range, bearing]``."""
POSITION = 1
"""Tag of a position sighting ``[dx, dy]`` (the landmark in the robot frame)."""
MODEL_NAMES = ("range-bearing", "xy")
"""Names of the models by tag (``--model`` of ``simulate``)."""


def tags(model: ArrayLike, k: int) -> NDArray[Any]:
    """Models of k sightings, a writable copy: one model for all of them, or one each."""
    return as_models(model, k).copy()


def _which(model: ArrayLike) -> tuple[NDArray[np.bool_], bool, bool]:
    """(mask of position sightings, whether some sighting is range-bearing, whether some is a position)."""
    xy = split_models(model)[0] == POSITION
    some = bool(xy.any())
    return xy, not some or not bool(xy.all()), some


def _merge(xy: NDArray[np.bool_], rb: _Columns, pos: _Columns) -> _Columns:
    """Per sighting the position model's values where ``xy``, else the range-bearing ones."""
    merged = tuple(np.where(xy.reshape(xy.shape + (1,) * (b.ndim - xy.ndim)), b, a) for a, b in zip(rb, pos))
    return cast(_Columns, merged)  # as many columns as given


SIGHTING = np.dtype([("tag", np.int8), ("mount", np.float64, (3,))])
"""A sighting's model with its sensor's mounting: the tag and the sensor's pose ``[x, y, theta]`` in the robot
frame. Arrays of this dtype stand wherever tags do (a stream that declares sensors gives every step's sightings
so); plain ``int8`` tags are sightings at the robot's centre."""


def split_models(model: ArrayLike) -> tuple[NDArray[np.int8], Array | None]:
    """(the tags, the mountings (..., 3) or None when there is none or every one is the robot's centre: the
    sightings are then evaluated exactly as without a mounting)."""
    array = np.asarray(model)
    if array.dtype != SIGHTING:
        return array, None
    mount = array["mount"]
    return array["tag"], (mount if mount.size and bool(np.any(mount)) else None)


def as_models(model: ArrayLike, k: int) -> NDArray[Any]:
    """Models of k sightings, read-only: one model for all of them, or one each (tags or :data:`SIGHTING`)."""
    array = np.asarray(model)
    if array.dtype != SIGHTING:
        array = array.astype(np.int8, copy=False)
    return np.broadcast_to(array, (k,))


def _sensor_pose(pose: ArrayLike, mount: Array) -> tuple[Array, Array]:
    """The sensor's pose ``pose * mount`` and its Jacobian with respect to the robot's pose (..., 3, 3)."""
    sensor, J_pose, _ = compose_with_jacobians(pose, mount)
    return sensor, J_pose


def predict(pose: ArrayLike, landmark: ArrayLike, model: ArrayLike) -> Array:
    """Predicted sightings, each with its own model, shape (..., 2) (see :func:`predict_with_jacobians`)."""
    model, at = split_models(model)
    if at is not None:
        pose = _sensor_pose(pose, at)[0]
    xy, has_rb, has_xy = _which(model)
    if not has_xy:
        return range_bearing(pose, landmark)
    if not has_rb:
        return position(pose, landmark)
    return _merge(xy, (range_bearing(pose, landmark),), (position(pose, landmark),))[0]


def predict_with_jacobians(pose: ArrayLike, landmark: ArrayLike, model: ArrayLike) -> tuple[Array, Array, Array]:
    """Predicted sightings with their Jacobians, each with its own model.

    Args:
        pose: Robot poses, shape (..., 3).
        landmark: Landmark positions, shape (..., 2).
        model: Tags, broadcastable to the sightings' shape (...) (a single tag for all), or :data:`SIGHTING`
            records: a mounted sighting is its model's from the sensor's pose ``pose * mount``, the pose Jacobian
            chained through the composition (exact).

    Returns:
        (z (..., 2), dz/dpose (..., 2, 3), dz/dlandmark (..., 2, 2)); bearings wrapped.
    """
    model, at = split_models(model)
    if at is not None:
        sensor, J_pose = _sensor_pose(pose, at)
        z, H_sensor, H_landmark = predict_with_jacobians(sensor, landmark, model)
        return z, H_sensor @ J_pose, H_landmark
    xy, has_rb, has_xy = _which(model)
    if not has_xy:
        return range_bearing_with_jacobians(pose, landmark)
    if not has_rb:
        return position_with_jacobians(pose, landmark)
    with np.errstate(divide="ignore", invalid="ignore"):  # range-bearing at a position sighting's landmark
        rb = range_bearing_with_jacobians(pose, landmark)
    return _merge(xy, rb, position_with_jacobians(pose, landmark))


def wrap_bearings(e: Array, model: ArrayLike) -> Array:
    """Differences of sightings (..., 2) with the bearing wrapped on range-bearing rows (in place; returned).

    Args:
        e: Differences ``z_a - z_b``, shape (..., 2).
        model: Tags, broadcastable to (...).
    """
    xy, has_rb, has_xy = _which(model)
    if not has_xy:
        e[..., 1] = wrap(e[..., 1])
    elif has_rb:
        e[..., 1] = np.where(xy, e[..., 1], wrap(e[..., 1]))
    return e


def landmark_from_sighting(pose: ArrayLike, z: ArrayLike, model: ArrayLike) -> Array:
    """Inverse observation model: where each sighting puts its landmark, shape (..., 2).

    Args:
        pose: Robot poses, shape (..., 3).
        z: Sightings, shape (..., 2).
        model: Tags, broadcastable to (...), or :data:`SIGHTING` records (see :func:`predict_with_jacobians`).
    """
    model, at = split_models(model)
    if at is not None:
        pose = _sensor_pose(pose, at)[0]
    if not _which(model)[2]:
        return landmark_from_observation(pose, z)
    return landmark_from_sighting_with_jacobians(pose, z, model)[0]


def landmark_from_sighting_with_jacobians(
    pose: ArrayLike, z: ArrayLike, model: ArrayLike
) -> tuple[Array, Array, Array]:
    """``landmark_from_sighting`` with its Jacobians (the pose Jacobian chained through a mounting).

    Returns:
        (landmark (..., 2), d/dpose (..., 2, 3), d/dz (..., 2, 2)).
    """
    model, at = split_models(model)
    if at is not None:
        sensor, J_pose = _sensor_pose(pose, at)
        landmark, L_sensor, L_z = landmark_from_sighting_with_jacobians(sensor, z, model)
        return landmark, L_sensor @ J_pose, L_z
    xy, has_rb, has_xy = _which(model)
    if not has_xy:
        return landmark_from_observation_with_jacobians(pose, z)
    if not has_rb:
        return landmark_from_position_with_jacobians(pose, z)
    rb = landmark_from_observation_with_jacobians(pose, z)
    return _merge(xy, rb, landmark_from_position_with_jacobians(pose, z))


def distance(z: ArrayLike, model: ArrayLike) -> Array:
    """How far each sighting's landmark is from the sensor, metres, shape (...)."""
    z = np.asarray(z, dtype=float)
    xy, _, has_xy = _which(model)
    if not has_xy:
        return z[..., 0]
    return np.where(xy, np.hypot(z[..., 0], z[..., 1]), z[..., 0])


def centred(z: ArrayLike, cov: ArrayLike, model: ArrayLike) -> tuple[Array, Array]:
    """Sightings as positions in the robot frame (at its centre), with their covariance to first order.

    Args:
        z: Sightings, shape (k, 2).
        cov: Their covariances, shape (k, 2, 2).
        model: Their models (tags or :data:`SIGHTING` records), shape (k,).

    Returns:
        (positions ``[dx, dy]`` (k, 2), covariances (k, 2, 2)).
    """
    tag, mount = split_models(model)
    origin = np.zeros((len(tag), 3)) if mount is None else mount
    position, _, L_z = landmark_from_sighting_with_jacobians(origin, z, tag)
    return position, L_z @ np.asarray(cov, dtype=float) @ np.swapaxes(L_z, -1, -2)
