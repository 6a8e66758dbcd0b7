"""How honest the MRCLAM conversion's odometry covariances are, by the length of the increment.

For every increment whose two ends Vicon covers, the squared Mahalanobis distance of its error against the Vicon
increment, ``e^T C^-1 e`` (3 if consistent), averaged per robot over increments grouped by the time they span.
``python -m benchmarks.mrclam_odometry_chi2 [FOLDER]`` (default ``../shared/data/MRCLAM_Dataset6``).
"""

from __future__ import annotations

import sys

import numpy as np

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between
from online_slam.importers.mrclam import read_mrclam
from online_slam.sources.events import Odometry, Start, Truth

SPANS = ((0.0, 1.0), (1.0, 5.0), (5.0, 15.0), (15.0, np.inf))
"""Groups of increments by the seconds they span."""


def chi2_by_span(folder: str, robot: int) -> list[tuple[int, float]]:
    """(count, mean squared Mahalanobis distance) of one robot's increments in each of :data:`SPANS`."""
    truth: dict[float, np.ndarray] = {}
    increments = []
    last = 0.0
    for event in read_mrclam(folder, robot):
        if isinstance(event, Start | Truth):
            truth[event.t] = np.asarray(event.pose, dtype=float)
        if isinstance(event, Start):
            last = event.t
        elif isinstance(event, Odometry):
            increments.append((last, event.t, np.asarray(event.delta), np.asarray(event.cov)))
            last = event.t
    spans, chi2 = [], []
    for t0, t1, delta, cov in increments:
        if t0 in truth and t1 in truth:
            error = delta - between(truth[t0][None], truth[t1][None])[0]
            error[2] = wrap(error[2])
            spans.append(t1 - t0)
            chi2.append(float(error @ np.linalg.solve(cov, error)))
    s, c = np.array(spans), np.array(chi2)
    groups = [(s >= low) & (s < high) for low, high in SPANS]
    return [(int(np.sum(m)), float(c[m].mean()) if m.any() else float("nan")) for m in groups]


def main(folder: str = "../shared/data/MRCLAM_Dataset6") -> None:
    """Print the table."""
    print("robot  " + "  ".join(f"{a:g}-{b:g} s: n, mean chi2".ljust(24) for a, b in SPANS))
    for robot in (1, 2, 3, 4, 5):
        print(f"{robot:>5}  " + "  ".join(f"{n:>5}, {m:6.1f}".ljust(24) for n, m in chi2_by_span(folder, robot)))


if __name__ == "__main__":
    main(*sys.argv[1:2])
