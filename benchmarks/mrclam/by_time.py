"""Where an MRCLAM robot's online error and NEES come from: per stretch of its run.

The online estimators' position RMSE and mean pose NEES (3 if consistent) per ``BIN`` seconds from the robot's
first pose, over the steps with a NEES (those Vicon covers): the replay's own per-step figures
(``Results.series``), whose run averages are the online RMSE and mean NEES of ``online-slam replay``'s table.

``python -m benchmarks.mrclam.by_time ROBOT [FOLDER] [BIN]`` (default ``../shared/data/MRCLAM_Dataset6``, 50 s).
"""

from __future__ import annotations

import sys

import numpy as np

from online_slam.pipeline import replay
from online_slam.pipeline.config import ReplayConfig

FOLDER = "../shared/data/MRCLAM_Dataset6"
ESTIMATORS = ("ekf", "smoother")


def by_time(robot: int, folder: str = FOLDER, width: float = 50.0) -> list[tuple[float, int, list[float]]]:
    """Per bin: (start s, steps with NEES, [RMSE m, mean NEES] of each of :data:`ESTIMATORS` in turn)."""
    results = replay(folder, ReplayConfig(estimators=ESTIMATORS, dataset={"robot": robot}))
    series = [results.series[name] for name in ESTIMATORS]
    t = series[0].t - series[0].t[0]
    rows = []
    for start in np.arange(0.0, t[-1] + width, width):
        inside = (t >= start) & (t < start + width) & np.isfinite(series[0].nees)
        if inside.any():
            figures = []
            for s in series:
                figures += [float(np.sqrt(np.mean(s.position_error_m[inside] ** 2))), float(np.mean(s.nees[inside]))]
            rows.append((float(start), int(inside.sum()), figures))
    return rows


def main(robot: str = "2", folder: str = FOLDER, width: str = "50") -> None:
    """Print the table."""
    size = float(width)
    print(f"MRCLAM robot {robot}, per {size:g} s from its first pose: steps, then RMSE m / mean NEES")
    print("from s    steps   " + "   ".join(f"{name:<16}" for name in ESTIMATORS))
    for start, steps, f in by_time(int(robot), folder, size):
        cells = "   ".join(f"{f[2 * k]:6.3f} / {f[2 * k + 1]:6.2f}" for k in range(len(ESTIMATORS)))
        print(f"{start:6.0f}  {steps:6d}   {cells}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
