"""MRCLAM Dataset 6 without ids: every robot, and all five, replayed with the barcodes and with JCBB.

Each replay runs the defaults (EKF, smoother, batch); ``--association jcbb`` hides the barcodes from the estimators
(they only score the pairing). Reported: the EKF's online error, the smoother's and the batch's final error against
Vicon with ids and without, the share of sightings paired right, and the sightings the rival test left out.
Target (issue 50): every smoother's and batch's final within 1.5x its known-id figure.
``python -m benchmarks --only unknown-ids --mrclam FOLDER``.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from online_slam.options import replay_config
from online_slam.pipeline import replay

ROBOTS: tuple[int | str, ...] = (1, 2, 3, 4, 5, "all")
"""The streams: each robot, then all five in one."""
TARGET = 1.5
"""Smoother and batch final without ids over with them, at most."""


@dataclass(frozen=True)
class Run:
    """One replay's figures (m)."""

    robot: int | str
    """The robot, or ``all``."""
    association: str
    """``known`` or ``jcbb``."""
    ekf_online: float
    """The EKF's online position RMSE."""
    smoother_final: float
    """The smoother's final position RMSE."""
    batch_final: float
    """The batch's final position RMSE."""
    paired_right: float | None
    """The smoother's share of sightings paired right (None with ids)."""
    left_out: int | None
    """Sightings the smoother's rival test left out (None with ids)."""


def _run(job: tuple[str, int | str, str]) -> Run:
    folder, robot, association = job
    values: dict = {"robot": robot} | ({"association": association} if association != "known" else {})
    results = replay(folder, replay_config(values))
    est = results.estimators
    a = est["smoother"].association
    left = est["smoother"].details.get("association", {}).get("rival_scans_sightings") if a is not None else None
    return Run(
        robot,
        association,
        float(est["ekf"].online_rmse_m or 0.0),
        float(est["smoother"].final_rmse_m),
        float(est["batch"].final_rmse_m),
        None if a is None else a.accuracy,
        left,
    )


def run_unknown_ids(folder: str | Path, workers: int | None = None) -> list[tuple[Run, Run]]:
    """(with ids, without) for every stream of :data:`ROBOTS`, the heaviest (all five) first."""
    jobs = [(str(folder), robot, method) for robot in reversed(ROBOTS) for method in ("known", "jcbb")]
    with ProcessPoolExecutor(max_workers=workers or os.cpu_count()) as pool:
        runs = list(pool.map(_run, jobs))
    pairs = {run.robot: (run, other) for run, other in zip(runs[::2], runs[1::2])}
    return [pairs[robot] for robot in ROBOTS]
