"""The article's table (../shared/seed/) is our first acceptance test.

Golden figures come from the article: its table (3 decimals) and its code's printed values (7 decimals, run
unchanged here, see ../shared/FACTS.md). Odometry figures depend only on the random draws, so they must match
to the last printed digit; the batch optimum is ours (the article's solver stops at ftol 1e-9, slightly above
the minimum: its RMSE prints 0.0822490, the converged one is 0.08224 to 4 decimals).
"""

from __future__ import annotations

import numpy as np

import online_slam
from online_slam.frontend import FrontEnd, FrontEndConfig
from online_slam.pipeline import ReplayConfig


def test_square_world_has_the_article_sizes() -> None:
    fe = FrontEnd()
    steps = list(fe.steps(online_slam.sources.square_world()))
    counts = [len(s.landmarks) for s in steps]
    assert len(steps) == 25 and len(fe.truth.landmarks) == 12 and sum(counts) == 95
    assert [i for i, c in enumerate(counts) if c == 3] == [0, 5, 10, 15, 20]


def test_replay_reproduces_the_article_table() -> None:
    r = online_slam.replay("square")
    assert (r.poses, r.landmarks, r.observations) == (25, 12, 95)
    assert round(r.odometry.rmse_m, 7) == 1.3384918
    assert round(r.odometry.endpoint_gap_m, 7) == 1.8697624
    batch = r.estimators["batch"]
    assert batch.details["converged"]
    assert f"{r.odometry.rmse_m:.3f}" == "1.338" and f"{r.odometry.endpoint_gap_m:.3f}" == "1.870"
    assert f"{batch.final_rmse_m:.3f}" == "0.082" and f"{batch.endpoint_gap_m:.3f}" == "0.060"
    assert abs(batch.final_rmse_m - 0.0822490) < 5e-5 and abs(batch.endpoint_gap_m - 0.0597245) < 5e-5


def test_first_observation_only_gives_odometry() -> None:
    r = online_slam.replay("square", ReplayConfig(frontend=FrontEndConfig(first_observation_only=True)))
    assert r.observations == 12
    assert round(r.estimators["batch"].final_rmse_m, 7) == 1.3384918
    assert f"{r.estimators['batch'].final_rmse_m:.3f}" == "1.338"
    batch, odometry = r.estimates["batch"], r.estimates["odometry"]
    assert np.allclose(batch.poses, odometry.poses, atol=1e-9)
