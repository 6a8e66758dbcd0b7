"""Maps saved and reused (``--map-out``, ``--map``), measured.

- ``simulated``: a world replayed once (run 1), its final map written; then replayed on that map (run 2) on the
  same stream, and on fresh noise draws of the same world (the honest case: run 1's map errors are not those of
  run 2's data), each also on the same map without its joint covariance (independent landmark priors) and with
  no map. The square world (25 poses, fixed path and landmarks: seed 1616, fresh seeds 1..N) and the grid
  world (2000 poses: seed 7; fresh noise: its path and landmarks sensed again with seeds 1000..). For each, run 1's
  final errors, run 2's online errors and mean NEES, and whether the map grew.
- ``mrclam``: Dataset 6, each robot: SLAM (no map), then the surveyed landmarks (``Landmark_Groundtruth.dat``) as a
  fixed map (``--map-fixed``): each estimator's online error beside SLAM's final.

``python -m benchmarks.maps simulated [--seeds 4] [--grid-seeds 2]`` and
``python -m benchmarks.maps mrclam [--folder PATH] [--robots 1,2,3,4,5]``; each replay's line is printed as it
finishes.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from online_slam.evaluation.results import Results
from online_slam.pipeline import MapConfig, ReplayConfig, replay
from online_slam.sources.events import Event, LandmarkTruth, Truth
from online_slam.sources.landmark_map import LandmarkMap, write_map
from online_slam.sources.worlds import GridConfig, _sensed, grid_world, square_world

ONLINE = ("ekf", "smoother")


def resensed_grid(seed: int, config: GridConfig | None = None) -> Iterator[Event]:
    """The grid world of ``config`` (its path and landmarks) sensed again with the noise of ``seed``."""
    config = config or GridConfig()
    events = list(grid_world(config))
    truth = np.array([e.pose for e in events if isinstance(e, Truth)])
    marks = sorted((e.landmark, e.position) for e in events if isinstance(e, LandmarkTruth))
    landmarks = np.array([position for _, position in marks])
    yield from _sensed("grid", config, np.random.default_rng(seed), truth, landmarks)


def _errors(results: Results) -> str:
    parts = []
    for name, e in results.estimators.items():
        online = "-" if e.online_rmse_m is None else f"{e.online_rmse_m:.3f}"
        nees = "" if e.nees_mean is None else f" NEES {e.nees_mean:.1f}"
        parts.append(f"{name} online {online} final {e.final_rmse_m:.3f}{nees}")
    return "; ".join(parts)


def _with_map(path: Path, fixed: bool = False) -> ReplayConfig:
    return dataclasses.replace(ReplayConfig(), map=MapConfig(str(path), fixed=fixed))


def world_case(name: str, first: Iterable[Event], fresh: list[Iterable[Event]], folder: Path) -> dict[str, float]:
    """Run 1, then run 2 on its map (same stream, fresh draws); the figures printed, the summary returned."""
    one = replay(first, name=name)
    assert one.map is not None and one.map.final is not None
    path, independent = folder / f"{name}.json", folder / f"{name}-independent.json"
    write_map(path, one.map.final)
    write_map(independent, dataclasses.replace(one.map.final, joint=None))
    size = len(one.map.final)
    best = min(e.final_rmse_m for e in one.estimators.values() if e.final_rmse_m is not None)
    print(f"{name} run 1: {size} landmarks; {_errors(one)}", flush=True)
    same = replay(first if isinstance(first, list) else list(first), _with_map(path), name=name)
    grew = {n: len(same.estimates[n].landmark_ids) - size for n in ONLINE}
    print(f"{name} run 2, same stream, on the map: {_errors(same)}; map grew by {grew}", flush=True)
    summary = {f"same {n}": float(same.estimators[n].online_rmse_m or np.nan) for n in ONLINE}
    draws: dict[str, list[float]] = {}
    for k, events in enumerate(fresh):
        events = list(events)
        two = replay(events, _with_map(path), name=name)
        apart = replay(events, _with_map(independent), name=name)
        alone = replay(events, name=name)
        grew = {n: len(two.estimates[n].landmark_ids) - size for n in ONLINE}
        print(f"{name} fresh draw {k}: on the map: {_errors(two)}; grew by {grew}", flush=True)
        print(f"{name} fresh draw {k}: independent: {_errors(apart)}", flush=True)
        print(f"{name} fresh draw {k}: no map:     {_errors(alone)}", flush=True)
        for label, results in (("fresh", two), ("fresh independent", apart), ("fresh no map", alone)):
            for n in ONLINE:
                draws.setdefault(f"{label} {n}", []).append(float(results.estimators[n].online_rmse_m or np.nan))
    summary |= {key: float(np.mean(v)) for key, v in draws.items()}
    figures = ", ".join(f"{k} {v:.3f}" for k, v in summary.items())
    print(f"{name}: run 1 best final {best:.3f}; run 2 online: {figures}")
    return summary


def simulated(seeds: int, grid_seeds: int) -> None:
    with tempfile.TemporaryDirectory() as folder:
        square_fresh: list[Iterable[Event]] = [list(square_world(s)) for s in range(1, seeds + 1)]
        world_case("square", list(square_world()), square_fresh, Path(folder))
        grid_fresh: list[Iterable[Event]] = [resensed_grid(1000 + s) for s in range(grid_seeds)]
        world_case("grid", list(grid_world(GridConfig())), grid_fresh, Path(folder))


def mrclam(folder: str, robots: list[int]) -> None:
    from online_slam.importers import registry

    for robot in robots:
        events = list(registry.open_dataset(folder, "mrclam", robot=robot))  # as online-slam replay reads it
        marks = [e for e in events if isinstance(e, LandmarkTruth)]
        survey = LandmarkMap.of([e.landmark for e in marks], [e.position for e in marks], None, folder)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "survey.json"
            write_map(path, survey)
            slam = replay(events, name=f"robot {robot}")
            fixed = replay(events, _with_map(path, fixed=True), name=f"robot {robot}")
        best = min(e.final_rmse_m for e in slam.estimators.values() if e.final_rmse_m is not None)
        print(f"robot {robot} SLAM: {_errors(slam)}", flush=True)
        print(f"robot {robot} fixed survey map ({len(survey)} landmarks): {_errors(fixed)}", flush=True)
        online = ", ".join(f"{n} {fixed.estimators[n].online_rmse_m:.3f}" for n in ONLINE)
        print(f"robot {robot}: SLAM best final {best:.3f}; on the fixed map online {online}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.maps", description=__doc__)
    parser.add_argument("case", choices=("simulated", "mrclam"))
    parser.add_argument("--seeds", type=int, default=4, help="fresh noise draws of the square world")
    parser.add_argument("--grid-seeds", type=int, default=2, help="fresh noise draws of the grid world")
    parser.add_argument("--folder", default="../shared/data/MRCLAM_Dataset6", help="MRCLAM Dataset 6")
    parser.add_argument("--robots", default="1,2,3,4,5", help="MRCLAM robots")
    args = parser.parse_args()
    if args.case == "simulated":
        simulated(args.seeds, args.grid_seeds)
    else:
        mrclam(args.folder, [int(r) for r in args.robots.split(",")])


if __name__ == "__main__":
    main()
