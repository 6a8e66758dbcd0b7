"""Robustness benchmark: wrong landmark ids in the grid world, our default estimators beside GTSAM iSAM2 with a
Cauchy kernel on the same streams, in the same run; and the same over a grid of worlds, world seeds, contaminations
and corruption seeds (:func:`run_robustness_grid`; ``python -m benchmarks.robustness --help``)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

import numpy as np

from benchmarks import gtsam_peer
from online_slam.engine import Engine
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sources.events import Event, Odometry
from online_slam.sources.worlds import (
    Contamination,
    GridConfig,
    WaypointConfig,
    contaminate,
    grid_world,
    waypoint_world,
)


@dataclass(frozen=True)
class RobustnessRow:
    """Figures at one contamination level (metres; None where not run)."""

    wrong_ids: float
    """Fraction of sightings with a wrong landmark id."""
    ekf_online: float
    """EKF online RMSE."""
    smoother_online: float
    """Smoother online RMSE."""
    smoother_final: float
    """Smoother final RMSE."""
    batch_final: float
    """Batch final RMSE."""
    isam2_online: float | None
    """iSAM2 (Cauchy kernel) online RMSE."""
    isam2_final: float | None
    """iSAM2 (Cauchy kernel) final RMSE."""


def _isam2(events: list[Event], cauchy: float) -> tuple[float, float]:
    """GTSAM iSAM2 with a Cauchy kernel on the same steps: its online and final position RMSE."""
    engine = Engine([])
    steps = [r.step for r in (engine.push(e) for e in events) if r is not None]
    last = engine.close()
    steps += [last.step] if last is not None else []
    truth = np.array([engine.frontend.truth.poses[s.index] for s in steps])
    peer = gtsam_peer.isam2_online(steps, cauchy=cauchy)
    return _rmse(peer.poses, truth), _rmse(peer.final_poses, truth)


def _rmse(poses: np.ndarray, truth: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((poses[:, :2] - truth[:, :2]) ** 2, axis=1))))


def run_robustness(
    config: GridConfig, levels: tuple[float, ...] = (0.0, 0.05, 0.1, 0.2), cauchy: float = 3.0, seed: int = 1
) -> list[RobustnessRow]:
    """Replay the grid world at each wrong-id level with default flags; iSAM2 + Cauchy on the same steps."""
    rows = []
    for level in levels:
        events = list(grid_world(config))
        if level:
            events = list(contaminate(events, Contamination(wrong_ids=level, seed=seed)))
        results = replay(iter(events), ReplayConfig(), validate=False)
        figures = results.estimators
        isam_online = isam_final = None
        if gtsam_peer.available():
            isam_online, isam_final = _isam2(events, cauchy)
        rows.append(
            RobustnessRow(
                level,
                figures["ekf"].online_rmse_m or float("nan"),
                figures["smoother"].online_rmse_m or float("nan"),
                figures["smoother"].final_rmse_m or float("nan"),
                figures["batch"].final_rmse_m or float("nan"),
                isam_online,
                isam_final,
            )
        )
    return rows


WAYPOINT = WaypointConfig(poses=2000, size=40.0, landmarks=200, step=0.5, sensor_range=6.0, sensor_sigma=(0.1, 0.01745))
"""The random-waypoint world of issue 31 (issue 11's kind): 200 landmarks over a 40 m square, 6 m range."""
SPARSE_GRID = GridConfig(landmarks=95)
"""The grid world with half its landmarks."""
WORLDS: dict[str, Callable[[int], Iterator[Event]]] = {
    "grid": lambda seed: grid_world(replace(GridConfig(), seed=seed)),
    "sparse grid": lambda seed: grid_world(replace(SPARSE_GRID, seed=seed)),
    "waypoint": lambda seed: waypoint_world(replace(WAYPOINT, seed=seed)),
}
"""The worlds of the robustness grid, each built from a world seed."""
CORRUPTIONS: dict[str, Contamination] = {
    "5% wrong ids": Contamination(wrong_ids=0.05),
    "10% wrong ids": Contamination(wrong_ids=0.1),
    "20% wrong ids": Contamination(wrong_ids=0.2),
    "5% range spikes": Contamination(range_spikes=0.05),
    "10% clutter": Contamination(clutter=0.1),
}
"""The contaminations of the robustness grid (their seeds are set per run)."""
FIGURES = ("ekf online", "smoother online", "smoother final", "batch final", "isam2 online", "isam2 final")
"""The figures of a run, each divided by the clean batch's final RMSE on the same world seed."""


@dataclass(frozen=True)
class GridCell:
    """Worst and median of each figure over the world x corruption seeds of one world and contamination."""

    world: str
    """The world's name (a key of :data:`WORLDS`)."""
    corruption: str
    """The contamination's name (a key of :data:`CORRUPTIONS`)."""
    runs: int
    """World x corruption seeds replayed."""
    worst: dict[str, float]
    """Largest ratio to the clean batch, by figure (:data:`FIGURES`; iSAM2 only where GTSAM is installed)."""
    median: dict[str, float]
    """Median ratio to the clean batch, by figure."""


def _figures(events: list[Event], peer: bool, cauchy: float) -> dict[str, float]:
    """RMSE of each estimator on a stream (metres), iSAM2 + Cauchy beside them when ``peer``."""
    figures = replay(iter(events), ReplayConfig(), validate=False).estimators
    out = {
        "ekf online": figures["ekf"].online_rmse_m or float("nan"),
        "smoother online": figures["smoother"].online_rmse_m or float("nan"),
        "smoother final": figures["smoother"].final_rmse_m or float("nan"),
        "batch final": figures["batch"].final_rmse_m or float("nan"),
    }
    if peer:
        out["isam2 online"], out["isam2 final"] = _isam2(events, cauchy)
    return out


def run_robustness_grid(
    worlds: tuple[str, ...] = tuple(WORLDS),
    corruptions: tuple[str, ...] = tuple(CORRUPTIONS),
    world_seeds: tuple[int, ...] = (1, 2, 3),
    corruption_seeds: tuple[int, ...] = (0, 1, 2, 3, 4),
    cauchy: float = 3.0,
    poses: int | None = None,
) -> list[GridCell]:
    """Every estimator with default flags over worlds x world seeds x contaminations x corruption seeds.

    Each figure is divided by the clean batch's final RMSE on the same world seed; each cell gives the worst and
    the median of those ratios over the seeds. ``poses`` shortens every world (a smoke run).
    """
    peer = gtsam_peer.available()
    cells = []
    for world in worlds:
        ratios: dict[str, list[dict[str, float]]] = {c: [] for c in corruptions}
        for world_seed in world_seeds:
            events = list(WORLDS[world](world_seed))
            if poses is not None:
                events = _shortened(events, poses)
            clean = _figures(events, False, cauchy)["batch final"]
            for name in corruptions:
                for seed in corruption_seeds:
                    dirty = list(contaminate(events, replace(CORRUPTIONS[name], seed=seed)))
                    ratios[name].append({k: v / clean for k, v in _figures(dirty, peer, cauchy).items()})
        for name in corruptions:
            runs = ratios[name]
            keys = [k for k in FIGURES if k in runs[0]]
            worst = {k: float(np.max([r[k] for r in runs])) for k in keys}
            median = {k: float(np.median([r[k] for r in runs])) for k in keys}
            cells.append(GridCell(world, name, len(runs), worst, median))
    return cells


def _shortened(events: list[Event], poses: int) -> list[Event]:
    """The stream up to its ``poses``-th odometry (header, truth and start kept)."""
    out, seen = [], 0
    for event in events:
        if isinstance(event, Odometry):
            seen += 1
            if seen >= poses:
                break
        out.append(event)
    return out


def print_grid(cells: list[GridCell]) -> None:
    """The grid as a table: worst / median ratio to the clean batch per figure."""
    keys = [k for k in FIGURES if k in cells[0].worst] if cells else []
    print(f"{'world':<12}{'corruption':<17}{'runs':>5}" + "".join(f"{k:>20}" for k in keys))
    for c in cells:
        row = "".join(f"{f'{c.worst[k]:.2f} / {c.median[k]:.2f}':>20}" for k in keys)
        print(f"{c.world:<12}{c.corruption:<17}{c.runs:>5}{row}")
    print("worst / median over world x corruption seeds, each figure / the clean batch's final RMSE (same world)")


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description="Robustness over worlds x seeds x contaminations.")
    parser.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=list(WORLDS))
    parser.add_argument("--corruptions", nargs="+", default=list(CORRUPTIONS), choices=list(CORRUPTIONS))
    parser.add_argument("--world-seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--corruption-seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    parser.add_argument("--poses", type=int, default=None, help="shorten every world (smoke run)")
    a = parser.parse_args()
    print_grid(
        run_robustness_grid(
            tuple(a.worlds), tuple(a.corruptions), tuple(a.world_seeds), tuple(a.corruption_seeds), poses=a.poses
        )
    )
