"""g2o 2D files (VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY) <-> stream v1.

Reading: EDGE_SE2 edges must form one chain (i -> i+1 in vertex order; pose-pose loop closures are not part of
stream v1); EDGE_SE2_XY gives the landmark's (x, y) in the pose frame with a 2x2 information matrix, carried to
range and bearing to first order. Information matrices are g2o's (upper triangle, row by row). Vertices only
seed estimates in g2o; here they are read for ids and ignored. Synthetic timestamps: ``t = step * dt``.

Writing: odometry as EDGE_SE2 with information = covariance^-1; observations as EDGE_SE2_XY (the measured point
in the pose frame) with the first-order information; vertices from composed odometry and first sightings. Truth
(``truth``, ``landmark_truth``, a sighting's ``truth_outlier`` and ``truth_landmark``) has no place in g2o: it is
left out. Every sighting needs a landmark id (g2o has no unknown association).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO

import numpy as np

from online_slam.errors import InputError, OnlineSlamError
from online_slam.geometry.se2 import compose
from online_slam.importers._lines import covariance_from, numbered_lines, numbers
from online_slam.importers.gtsam_text.reader import cartesian_to_range_bearing
from online_slam.models.observation import landmark_from_sighting
from online_slam.sources.events import Event, Header, Observation, Odometry, Start

EDGE_SE2 = ("i", "j", "dx", "dy", "dtheta", "I11", "I12", "I13", "I22", "I23", "I33")
EDGE_SE2_XY = ("i", "l", "x", "y", "I11", "I12", "I22")


def _symmetric(upper: list[float], n: int) -> np.ndarray:
    m = np.zeros((n, n))
    m[np.triu_indices(n)] = upper
    return np.triu(m) + np.triu(m, 1).T


def read_g2o(path: str | Path, dt: float = 1.0) -> Iterator[Event]:
    """Stream a 2D g2o landmark file as events (see the module docstring).

    Edges may come in any order in the file: the pose chain is rebuilt from the EDGE_SE2 lines, and each pose's
    sightings follow the odometry that creates it.
    """
    p = Path(path)
    name = str(p)
    chain: dict[int, tuple[int, list[float], int]] = {}  # from pose -> (to pose, values, line)
    sightings: dict[int, list[tuple[list[float], int]]] = {}
    targets: set[int] = set()
    first_line: dict[int, int] = {}
    for number, fields in numbered_lines(p):
        tag, rest = fields[0], fields[1:]
        if tag in ("VERTEX_SE2", "VERTEX_XY"):
            numbers(name, number, rest, ("id", "x", "y", "theta") if tag == "VERTEX_SE2" else ("id", "x", "y"))
        elif tag == "EDGE_SE2":
            v = numbers(name, number, rest, EDGE_SE2)
            i, j = int(v[0]), int(v[1])
            if i in chain or j in targets:
                raise InputError(
                    name,
                    number,
                    "j",
                    f"edge {i}->{j} makes the poses more than one chain (loop closures are not supported)",
                )
            chain[i] = (j, v, number)
            targets.add(j)
        elif tag == "EDGE_SE2_XY":
            v = numbers(name, number, rest, EDGE_SE2_XY)
            sightings.setdefault(int(v[0]), []).append((v, number))
            first_line.setdefault(int(v[0]), number)
        else:
            raise InputError(name, number, "tag", f"unknown g2o tag {tag!r} (2D landmark files only)")
    roots = [i for i in chain if i not in targets] or sorted(sightings)[:1]
    if len(roots) != 1:
        raise InputError(name, 0, "", f"the EDGE_SE2 lines form {len(roots)} chains; expected one")
    yield Header(name=p.stem, meta={"converted_from": p.name, "timestamps": f"synthetic: {dt} s per pose"})
    yield Start(t=0.0, pose=(0.0, 0.0, 0.0))
    pose, step = roots[0], 0
    while True:
        for v, number in sightings.pop(pose, []):
            cov_xy = np.array(covariance_from(name, number, "I11", _symmetric(v[4:], 2), information=True))
            if v[2] == 0.0 and v[3] == 0.0:
                raise InputError(name, number, "x", "a landmark at the sensor has no bearing")
            r, b, cov = cartesian_to_range_bearing(v[2], v[3], cov_xy)
            yield Observation(t=step * dt, landmark=int(v[1]), range=r, bearing=b, cov=tuple(map(tuple, cov)))
        if pose not in chain:
            break
        nxt, v, number = chain[pose]
        odometry_cov = covariance_from(name, number, "I11", _symmetric(v[5:], 3), information=True)
        step += 1
        yield Odometry(t=step * dt, delta=(v[2], v[3], v[4]), cov=odometry_cov)
        pose = nxt
    if sightings:
        orphan = min(sightings)
        raise InputError(name, first_line[orphan], "i", f"sighting from pose {orphan}, which is not on the pose chain")


def _upper(m: np.ndarray) -> str:
    return " ".join(repr(float(x)) for x in m[np.triu_indices(len(m))])


def write_g2o(destination: str | Path | IO[str], events: Iterable[Event]) -> int:
    """Write events as a 2D g2o file: pose ids 0..N-1, landmark ids N.. in order of first sighting.

    Returns:
        Number of lines written.

    Raises:
        OnlineSlamError: A sighting without a landmark id; a second robot.
    """
    poses: list[np.ndarray] = []
    edges: list[str] = []
    landmark_ids: dict[object, int] = {}
    landmark_xy: list[np.ndarray] = []
    sightings: list[tuple[int, object, np.ndarray, np.ndarray]] = []
    sensors: dict[str, list[float]] = {}
    for event in events:
        if isinstance(event, Header):
            sensors = {name: spec["pose"] for name, spec in (event.meta.get("sensors") or {}).items()}
        elif isinstance(event, Start):
            if poses and event.robot is not None:  # a validated stream starts again only for another robot
                raise OnlineSlamError(f"g2o holds one pose chain; robot {event.robot!r} is a second robot")
            poses = poses if poses else [np.array(event.pose)]
        elif isinstance(event, Odometry):
            if not poses:
                poses = [np.zeros(3)]
            info = np.linalg.inv(event.covariance)
            edges.append(f"EDGE_SE2 {len(poses) - 1} {len(poses)} {' '.join(map(repr, event.delta))} {_upper(info)}")
            poses.append(compose(poses[-1], event.delta))
        elif isinstance(event, Observation):
            if event.landmark is None:
                raise OnlineSlamError(f"g2o needs a landmark id on every sighting; the one at t={event.t} has none")
            if not poses:
                poses = [np.zeros(3)]
            if event.xy is None:
                r, b = event.z  # (range, bearing): no xy
                point = np.array([r * np.cos(b), r * np.sin(b)])
                J = np.array([[np.cos(b), -r * np.sin(b)], [np.sin(b), r * np.cos(b)]])  # d(x, y)/d(range, bearing)
                info = np.linalg.inv(J @ event.covariance @ J.T)
            else:  # a position sighting is g2o's own measurement
                point, info = np.array(event.xy), np.linalg.inv(event.covariance)
            if event.sensor is not None:  # from the sensor's frame to the robot's: a rigid move, exact
                x, y, theta = sensors[event.sensor]
                R = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
                point, info = R @ point + [x, y], R @ info @ R.T
            if event.landmark not in landmark_ids:
                landmark_ids[event.landmark] = len(landmark_ids)
                at = poses[-1] if event.sensor is None else compose(poses[-1], sensors[event.sensor])
                landmark_xy.append(landmark_from_sighting(at, event.z, event.model))
            sightings.append((len(poses) - 1, event.landmark, point, info))
    n = len(poses)
    lines = [f"VERTEX_SE2 {i} {' '.join(map(repr, map(float, pose)))}" for i, pose in enumerate(poses)]
    lines += [f"VERTEX_XY {n + k} {' '.join(map(repr, map(float, xy)))}" for k, xy in enumerate(landmark_xy)]
    by_pose: dict[int, list[str]] = {}
    for i, lid, point, info in sightings:
        by_pose.setdefault(i, []).append(
            f"EDGE_SE2_XY {i} {n + landmark_ids[lid]} {float(point[0])!r} {float(point[1])!r} {_upper(info)}"
        )
    lines += by_pose.get(0, [])
    for k, edge in enumerate(edges, 1):  # each pose's sightings right after the edge that creates it
        lines.append(edge)
        lines += by_pose.get(k, [])
    text = "\n".join(lines) + "\n"
    if hasattr(destination, "write"):
        destination.write(text)
    else:
        Path(destination).write_text(text, encoding="utf-8")
    return len(lines)
