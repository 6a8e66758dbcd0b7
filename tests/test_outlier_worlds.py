"""Outliers on worlds the robust defaults were not tuned on: every seed of a fixed set, each against the clean
stream of the same world (issue 31). A module of its own, so that pytest-xdist can run it beside the others."""

from __future__ import annotations

import dataclasses

import pytest

import online_slam
from online_slam import ReplayConfig
from online_slam.sources.events import Observation
from online_slam.sources.worlds import (
    Contamination,
    GridConfig,
    WaypointConfig,
    contaminate,
    grid_world,
    waypoint_world,
)

# Issue 31's random-waypoint world at half length: 200 landmarks in a 40 m square, ~13 sightings per pose.
WAYPOINT = WaypointConfig(poses=1000, size=40.0, landmarks=200, sensor_range=6.0, sensor_sigma=(0.1, 0.01745), seed=0)


@pytest.mark.slow
def test_wrong_ids_on_a_waypoint_world_keep_the_smoother_online_within_2x_clean_at_the_seed_that_lost_it() -> None:
    """Before the consensus rule and the stale hand-over check (at f245cd8; 3558ed4 added both) corruption seeds 0,
    1 and 4 read 2.84x, 3.23x and 2.59x: three wrong-id sightings moved a landmark the prior held, or a background
    solve started before such a release was applied, and the online error stayed high until the next global solve.
    The suite keeps the worst of them (seeds 0 and 4 now read 1.14x and 1.13x; every seed, ten world seeds of the
    family: ``python -m benchmarks.robustness``)."""
    config = ReplayConfig(estimators=("smoother",))
    clean = online_slam.replay(waypoint_world(WAYPOINT), config).estimators["smoother"].online_rmse_m
    dirty = contaminate(waypoint_world(WAYPOINT), Contamination(wrong_ids=0.1, seed=1))
    ratio = online_slam.replay(dirty, config).estimators["smoother"].online_rmse_m / clean
    assert ratio <= 2.0, ratio  # measured: 1.23


@pytest.mark.slow
def test_a_landmark_placed_by_a_wrong_id_and_then_seen_where_it_is_does_not_throw_the_ekf() -> None:
    """On the sparse grid three landmarks first placed by wrong ids come into view together; the one a wrong
    id had confirmed was let in as drift at NIS 51,000 and the robot jumped 50 m (17.8 m RMSE over 700 poses).
    No drift explains such a sighting: the landmark is re-anchored instead."""
    world = GridConfig(landmarks=95, poses=700, seed=2)
    config = ReplayConfig(estimators=("ekf",))
    clean = online_slam.replay(grid_world(world), config).estimators["ekf"].online_rmse_m
    dirty = contaminate(grid_world(world), Contamination(wrong_ids=0.1, seed=0))
    ratio = online_slam.replay(dirty, config).estimators["ekf"].online_rmse_m / clean
    assert ratio <= 1.5, ratio  # measured: 1.12


@pytest.mark.slow
def test_a_contaminated_batch_keeps_the_outlier_decisions_of_the_smoother_it_starts_from() -> None:
    """At 20% wrong ids the batch's robust pass (Cauchy from median landmarks, the outliers' tails pulling) ended
    at 0.090 m on this world from the smoother's 0.042 m, at a lower truncated cost; judged from the smoother's
    estimate instead it ends at 0.045 m. The same class: 10% wrong ids on the 2000-pose world 1, corruption seed 4,
    0.056 m against the smoother's 0.025 (benchmarks/RESULTS.md, "The batch judges from its start")."""
    world = WaypointConfig(poses=500, size=40.0, landmarks=200, step=0.5, sensor_range=6.0,
                           sensor_sigma=(0.1, 0.01745), seed=1)  # fmt: skip
    dirty = contaminate(waypoint_world(world), Contamination(wrong_ids=0.2, seed=0))
    figures = online_slam.replay(dirty, ReplayConfig(estimators=("smoother", "batch"))).estimators
    smoother, batch = figures["smoother"].final_rmse_m, figures["batch"].final_rmse_m
    assert batch <= 1.2 * smoother, (batch, smoother)


@pytest.mark.slow
def test_landmarks_placed_by_single_wrong_ids_do_not_drag_the_smoother_online() -> None:
    """Waypoint world 8 of the robustness grid at 10% wrong ids (corruption seed 4): around pose 140 the robot
    enters an area where many landmarks were placed by one wrong-id sighting each; while three true sightings had to
    agree before one moved, each dragged the window and the online error reached 1.7 m. On the first 220 poses the
    smoother's online RMSE read 2.90x the oracle stream's; a cluster that outnumbers a landmark's support now moves
    it: 1.78x (the whole 2000 poses: 2.06x -> 1.40x)."""
    from benchmarks.robustness import CORRUPTIONS, WAYPOINT, _shortened

    events = _shortened(list(waypoint_world(dataclasses.replace(WAYPOINT, seed=8))), 220)
    dirty = list(contaminate(events, dataclasses.replace(CORRUPTIONS["10% wrong ids"], seed=4)))
    oracle = [e for e in dirty if not (isinstance(e, Observation) and e.truth_outlier is not None)]
    config = ReplayConfig(estimators=("smoother",))
    online = [online_slam.replay(s, config).estimators["smoother"].online_rmse_m for s in (dirty, oracle)]
    assert online[0] <= 2.2 * online[1], online
