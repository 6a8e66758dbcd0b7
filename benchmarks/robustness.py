"""Robustness benchmark: wrong landmark ids in the grid world, our default estimators beside GTSAM iSAM2 with a
Cauchy kernel on the same streams, in the same run; and the same over a grid of worlds, world seeds, contaminations
and corruption seeds (:func:`run_robustness_grid`; ``python -m benchmarks.robustness --help``)."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace

import numpy as np

from online_slam import gtsam_peer
from online_slam.engine import Engine
from online_slam.evaluation.metrics import align_se2, apply_transform
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sources.events import Event, Observation, Odometry
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
    steps = [r.step for e in events for r in engine.push(e)]
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
        figures = _figures(events, gtsam_peer.available(), cauchy)
        rows.append(
            RobustnessRow(
                level,
                figures["ekf online"],
                figures["smoother online"],
                figures["smoother final"],
                figures["batch final"],
                figures.get("isam2 online"),
                figures.get("isam2 final"),
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
FIGURES = (
    "ekf online",
    "smoother online",
    "smoother final",
    "batch final",
    "isam2 online",
    "isam2 final",
)
"""The figures of a run (position RMSE after anchoring the first pose, as ``replay`` scores), each divided by
the clean batch's final RMSE on the same world seed. ``aligned`` variants (:data:`ALIGNED`) are the same after a
least-squares rigid alignment of the whole path on truth, which leaves out the map's rotation about the start."""
ALIGNED = ("ekf online aligned", "smoother online aligned", "smoother final aligned", "batch final aligned")
"""The aligned figures, each divided by the clean batch's aligned final RMSE."""
ORACLE = tuple(f"{k} vs oracle" for k in FIGURES)
"""The figures over what perfect outlier rejection gives on the same stream: the same replay with every corrupted
sighting removed (the oracle stream). An online figure is divided by the same estimator's online figure there, a
final one by the oracle stream's batch final. Wrong ids also remove the true sightings they replace, and which
ones moves the whole map's rotation about the start: on the waypoint world a batch given the oracle stream ends up
to 3.6x the clean batch, so only these ratios measure what the outliers themselves cost."""


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
    """Largest ratio to the clean batch, by figure (:data:`FIGURES` and :data:`ALIGNED`), and to the oracle stream
    (:data:`ORACLE`); iSAM2 only where GTSAM is installed and asked for."""
    median: dict[str, float]
    """Median ratio, by figure."""


@dataclass(frozen=True)
class GridTask:
    """One replay of the robustness grid."""

    world: str
    """A key of :data:`WORLDS`."""
    world_seed: int
    """The world's seed."""
    corruption: str | None
    """A key of :data:`CORRUPTIONS`, or None for the clean stream."""
    corruption_seed: int
    """The contamination's seed."""
    peer: bool
    """Also run iSAM2 + Cauchy on the stream."""
    poses: int | None
    """Shorten the world to this many poses (a smoke run), or None."""
    oracle: bool = False
    """Replay the contaminated stream with every corrupted sighting removed (perfect outlier rejection)."""


def _aligned_rmse(poses: np.ndarray, truth: np.ndarray) -> float:
    """Position RMSE after the least-squares rigid alignment of ``poses`` on ``truth``."""
    return _rmse(apply_transform(align_se2(poses, truth), poses[:, :2]), truth)


def _figures(events: list[Event], peer: bool, cauchy: float) -> dict[str, float]:
    """RMSE of each estimator on a stream (metres), anchored and aligned; iSAM2 + Cauchy beside them when
    ``peer``."""
    results = replay(iter(events), ReplayConfig(), validate=False)
    figures, truth = results.estimators, results.truth_poses
    out = {
        "ekf online": figures["ekf"].online_rmse_m or float("nan"),
        "smoother online": figures["smoother"].online_rmse_m or float("nan"),
        "smoother final": figures["smoother"].final_rmse_m or float("nan"),
        "batch final": figures["batch"].final_rmse_m or float("nan"),
    }
    if truth is not None:
        for name in ("ekf", "smoother"):
            out[f"{name} online aligned"] = _aligned_rmse(results.series[name].poses, truth)
        for name in ("smoother", "batch"):
            out[f"{name} final aligned"] = _aligned_rmse(results.estimates[name].poses, truth)
    if peer:
        out["isam2 online"], out["isam2 final"] = _isam2(events, cauchy)
    return out


def run_task(task: GridTask, cauchy: float = 3.0) -> dict[str, float]:
    """The figures of one grid replay (metres; a process pool's unit of work)."""
    events = list(WORLDS[task.world](task.world_seed))
    if task.poses is not None:
        events = _shortened(events, task.poses)
    if task.corruption is not None:
        events = list(contaminate(events, replace(CORRUPTIONS[task.corruption], seed=task.corruption_seed)))
    if task.oracle:
        events = [e for e in events if not (isinstance(e, Observation) and e.truth_outlier is not None)]
    return _figures(events, task.peer, cauchy)


def run_robustness_grid(
    worlds: tuple[str, ...] = tuple(WORLDS),
    corruptions: tuple[str, ...] = tuple(CORRUPTIONS),
    world_seeds: tuple[int, ...] = tuple(range(1, 11)),
    corruption_seeds: tuple[int, ...] = (0, 1, 2, 3, 4),
    poses: int | None = None,
    peer: bool = True,
    workers: int = 1,
    log: Callable[[GridTask, dict[str, float]], None] | None = None,
) -> list[GridCell]:
    """Every estimator with default flags over worlds x world seeds x contaminations x corruption seeds.

    Each figure is divided by the clean batch's final RMSE on the same world seed (aligned figures by its
    aligned one); each cell gives the worst and the median of those ratios over the seeds. ``poses`` shortens
    every world (a smoke run); ``peer`` adds iSAM2 + Cauchy where GTSAM is installed; ``workers`` replays in
    that many processes; ``log`` is called with each replay's figures (metres) as it ends.
    """
    peer = peer and gtsam_peer.available()
    tasks = [GridTask(w, s, None, 0, False, poses) for w in worlds for s in world_seeds]
    tasks += [
        GridTask(w, s, c, k, peer, poses, oracle)
        for w in worlds
        for c in corruptions
        for s in world_seeds
        for k in corruption_seeds
        for oracle in (False, True)
    ]
    done: dict[GridTask, dict[str, float]] = {}
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for task, figures in zip(tasks, pool.map(run_task, tasks)):
            done[task] = figures
            if log is not None:
                log(task, figures)
    cells = []
    for world in worlds:
        for name in corruptions:
            ratios = []
            for task, figures in done.items():
                if task.world == world and task.corruption == name and not task.oracle:
                    clean = done[GridTask(world, task.world_seed, None, 0, False, poses)]
                    oracle = done[replace(task, oracle=True)]
                    ratios.append(
                        {k: v / clean[_reference(k)] for k, v in figures.items()}
                        | {f"{k} vs oracle": v / oracle[_oracle_reference(k)] for k, v in figures.items()}
                    )
            keys = [k for k in FIGURES + ALIGNED + ORACLE if k in ratios[0]]
            worst = {k: float(np.max([r[k] for r in ratios])) for k in keys}
            median = {k: float(np.median([r[k] for r in ratios])) for k in keys}
            cells.append(GridCell(world, name, len(ratios), worst, median))
    return cells


def _reference(figure: str) -> str:
    """The clean batch figure a figure is divided by."""
    return "batch final aligned" if figure.endswith("aligned") else "batch final"


def _oracle_reference(figure: str) -> str:
    """The oracle stream's figure a figure is divided by: the same online figure, the batch's final one."""
    return figure if "online" in figure else "batch final"


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
    """The grid as three tables: worst / median ratio per figure to the clean batch (anchored, then aligned), then
    to the oracle stream."""
    tables = (
        (FIGURES, "anchored at the first pose, over the clean batch's (same world)"),
        (ALIGNED, "rigidly aligned on truth, over the clean batch's (same world)"),
        (ORACLE, "anchored, over the same figure with every corrupted sighting removed (batch's for finals)"),
    )
    for figures, what in tables:
        keys = [k for k in figures if cells and k in cells[0].worst]
        if not keys:
            continue
        head = "".join(f"{k.removesuffix(' aligned').removesuffix(' vs oracle'):>18}" for k in keys)
        print(f"{'world':<12}{'corruption':<17}{'runs':>5}{head}")
        for c in cells:
            row = "".join(f"{f'{c.worst[k]:.2f} / {c.median[k]:.2f}':>18}" for k in keys)
            print(f"{c.world:<12}{c.corruption:<17}{c.runs:>5}{row}")
        print(f"worst / median over world x corruption seeds; each RMSE {what}\n")


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description="Robustness over worlds x seeds x contaminations.")
    parser.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=list(WORLDS))
    parser.add_argument("--corruptions", nargs="+", default=list(CORRUPTIONS), choices=list(CORRUPTIONS))
    parser.add_argument("--world-seeds", nargs="+", type=int, default=list(range(1, 11)))
    parser.add_argument("--corruption-seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    parser.add_argument("--poses", type=int, default=None, help="shorten every world (smoke run)")
    parser.add_argument("--no-peer", action="store_true", help="leave out iSAM2 + Cauchy (it is the slowest part)")
    parser.add_argument("--workers", type=int, default=1, help="replay in this many processes")
    parser.add_argument("--jsonl", default=None, help="also write each replay's figures (metres) to this file")
    a = parser.parse_args()
    out = open(a.jsonl, "w") if a.jsonl else None  # noqa: SIM115 - closed below

    def log(task: GridTask, figures: dict[str, float]) -> None:
        if out is not None:
            out.write(json.dumps({**asdict(task), **figures}) + "\n")
            out.flush()

    cells = run_robustness_grid(
        tuple(a.worlds),
        tuple(a.corruptions),
        tuple(a.world_seeds),
        tuple(a.corruption_seeds),
        poses=a.poses,
        peer=not a.no_peer,
        workers=a.workers,
        log=log,
    )
    if out is not None:
        out.close()
    print_grid(cells)
