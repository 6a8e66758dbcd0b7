"""GTSAM / iSAM text files (``victoria_park.txt``, ``cityTrees10000.txt``) -> stream v1.

Lines: ``ODOMETRY i j dx dy dth n1..n6`` or ``EDGE2 i j dx dy dth n1..n6`` (the relative pose of j in i's frame),
``LANDMARK i l lx ly m1 m2 m3`` (landmark l seen from pose i at (lx, ly) in i's frame, x forward) and
``BR i l bearing range bearing_std range_std``. Noise conventions, as documented by the data's provenance:

- ``gtsam`` (files with ODOMETRY lines, what GTSAM's ``load2D`` does by default): the six odometry numbers are the
  upper triangle of the covariance; a LANDMARK's (m1, m2, m3) gives ``bearing_std = sqrt(m1 / 10)``,
  ``range_std = sqrt(m1)`` when ``|m1 - m3| < 1e-4`` (else both 1).
- ``isam`` (files with EDGE2 lines): both are upper-triangular square-root information matrices (1/sigma); the
  landmark's Cartesian noise is carried to range and bearing to first order.

Pose ids are renumbered as consecutive steps in chain order (the GTSAM file skips ids it gives to landmarks);
landmark ids are kept. The files have no timestamps: step k gets ``t = k * dt`` (the header says so).
An optional truth file with the same lines, noise-free, gives truth poses (composed from the origin) and
landmark truth (first noise-free sighting).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from online_slam.errors import InputError
from online_slam.geometry.se2 import compose
from online_slam.importers._lines import covariance_from, numbered_lines, numbers
from online_slam.models.range_bearing import landmark_from_observation
from online_slam.sources.events import Event, Header, LandmarkTruth, Observation, Odometry, Start, Truth

EDGE = ("i", "j", "dx", "dy", "dtheta", "n11", "n12", "n13", "n22", "n23", "n33")
LANDMARK = ("i", "l", "lx", "ly", "m11", "m12", "m22")
BR = ("i", "l", "bearing", "range", "bearing_std", "range_std")


def _upper(values: list[float], n: int) -> np.ndarray:
    m = np.zeros((n, n))
    m[np.triu_indices(n)] = values
    return m


def odometry_covariance(noise: list[float], convention: str) -> np.ndarray:
    """3x3 covariance of an odometry line's six noise numbers."""
    upper = _upper(noise, 3)
    if convention == "gtsam":
        return np.triu(upper) + np.triu(upper, 1).T
    information = upper.T @ upper  # iSAM: upper-triangular square-root information
    return np.linalg.inv(information)


def cartesian_to_range_bearing(lx: float, ly: float, cov_xy: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(range, bearing, 2x2 covariance) of a point (lx, ly) in the pose frame with Cartesian covariance."""
    r2 = lx * lx + ly * ly
    r = np.sqrt(r2)
    J = np.array([[lx / r, ly / r], [-ly / r2, lx / r2]])
    cov = J @ cov_xy @ J.T
    return float(r), float(np.arctan2(ly, lx)), 0.5 * (cov + cov.T)


def _landmark_noise(lx: float, ly: float, m: list[float], convention: str) -> tuple[float, float, np.ndarray]:
    if convention == "gtsam":
        r, b = float(np.hypot(lx, ly)), float(np.arctan2(ly, lx))
        if abs(m[0] - m[2]) < 1e-4:
            bearing_std, range_std = np.sqrt(m[0] / 10.0), np.sqrt(m[0])
        else:
            bearing_std = range_std = 1.0
        return r, b, np.diag([range_std**2, bearing_std**2])
    S = _upper(m, 2)
    return cartesian_to_range_bearing(lx, ly, np.linalg.inv(S.T @ S))


def _detect(path: Path) -> str:
    for _, fields in numbered_lines(path):
        if fields[0] == "EDGE2":
            return "isam"
        if fields[0] == "ODOMETRY":
            return "gtsam"
    return "gtsam"


def read_gtsam_text(
    path: str | Path, *, truth: str | Path | None = None, dt: float = 1.0, convention: str | None = None
) -> Iterator[Event]:
    """Stream a GTSAM/iSAM text file as events.

    Args:
        path: The dataset file.
        truth: Optional noise-free twin of the file (same lines) for truth poses and landmarks.
        dt: Synthetic time between poses, seconds.
        convention: ``gtsam`` or ``isam``; default: ``isam`` if the file uses EDGE2, else ``gtsam``.

    Yields:
        Stream-v1 events.
    """
    p = Path(path)
    conv = convention or _detect(p)
    if conv not in ("gtsam", "isam"):
        raise InputError(str(p), 0, "", f"unknown noise convention {conv!r}; expected gtsam or isam")
    name = str(p)
    meta = {
        "converted_from": p.name,
        "noise_convention": conv,
        "timestamps": f"synthetic: {dt} s per pose (the file has none)",
    }
    yield Header(name=p.stem, meta=meta)
    yield Start(t=0.0, pose=(0.0, 0.0, 0.0))
    truth_lines = numbered_lines(truth) if truth is not None else None
    steps = {}  # file pose id -> step index
    current = None
    true_pose = np.zeros(3)
    seen_truth: set = set()
    if truth_lines is not None:
        yield Truth(t=0.0, pose=(0.0, 0.0, 0.0))
    for number, fields in numbered_lines(p):
        twin = next(truth_lines, None) if truth_lines is not None else None
        tag, rest = fields[0], fields[1:]
        if twin is not None and twin[1][0] != tag:
            raise InputError(str(truth), twin[0], "", f"truth file does not match {p.name}:{number} (tag {tag})")
        if tag in ("ODOMETRY", "EDGE2"):
            v = numbers(name, number, rest, EDGE)
            i, j = int(v[0]), int(v[1])
            if current is None:
                current, steps[i] = i, 0
            if i != current:
                raise InputError(name, number, "i", f"odometry must continue the chain from pose {current}, got {i}")
            if j in steps:
                raise InputError(name, number, "j", f"pose {j} already exists (loop-closure edges are not supported)")
            steps[j] = len(steps)
            current = j
            odometry_cov = covariance_from(name, number, "n11", odometry_covariance(v[5:], conv))
            t = steps[j] * dt
            yield Odometry(t=t, delta=(v[2], v[3], v[4]), cov=odometry_cov)
            if twin is not None:
                tv = numbers(str(truth), twin[0], twin[1][1:], EDGE)
                true_pose = compose(true_pose, tv[2:5])
                yield Truth(t=t, pose=tuple(map(float, true_pose)))
        elif tag in ("LANDMARK", "BR"):
            cols = LANDMARK if tag == "LANDMARK" else BR
            v = numbers(name, number, rest, cols)
            i, landmark = int(v[0]), int(v[1])
            if current is None:
                current, steps[i] = i, 0
            if i != current:
                raise InputError(name, number, "i", f"sighting from pose {i}, but the newest pose is {current}")
            if tag == "LANDMARK":
                if v[2] == 0.0 and v[3] == 0.0:
                    raise InputError(name, number, "lx", "a landmark at the sensor has no bearing")
                r, b, cov = _landmark_noise(v[2], v[3], v[4:], conv)
            else:
                b, r, cov = v[2], v[3], np.diag([v[5] ** 2, v[4] ** 2])
                if r <= 0 or v[4] <= 0 or v[5] <= 0:
                    raise InputError(name, number, "range", "range and standard deviations must be > 0")
            yield Observation(t=steps[i] * dt, landmark=landmark, range=r, bearing=b, cov=tuple(map(tuple, cov)))
            if twin is not None and landmark not in seen_truth:
                tv = numbers(str(truth), twin[0], twin[1][1:], cols)
                z = (np.hypot(tv[2], tv[3]), np.arctan2(tv[3], tv[2])) if tag == "LANDMARK" else (tv[3], tv[2])
                seen_truth.add(landmark)
                yield LandmarkTruth(landmark, tuple(map(float, landmark_from_observation(true_pose, z))))
        else:
            raise InputError(
                name, number, "tag", f"unknown line type {tag!r}; expected ODOMETRY, EDGE2, LANDMARK or BR"
            )
