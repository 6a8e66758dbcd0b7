"""The smoother's consistency on the circle world (esde's Monte Carlo protocol): First-Estimates Jacobians and
the invariant (carried) prior.

Its own module so that the suite's workers, which take whole modules, share the heavy circle runs.
"""

from __future__ import annotations

import pytest
from conftest import circle_anees

from online_slam.estimators.smoother import SmootherConfig, WindowConfig
from online_slam.pipeline import ReplayConfig

WINDOW = WindowConfig(size=20, distance=0.0)
"""20 poses (by default the window spans 18 m, up to 72 poses here): a quarter of the cost, and more marginalized."""


@pytest.mark.slow
@pytest.mark.parametrize(
    "smoother, consistent",
    [
        (SmootherConfig(window=WINDOW, linearization="standard"), False),
        (SmootherConfig(window=WINDOW, linearization="fej"), True),
        (SmootherConfig(window=WINDOW, linearization="invariant"), True),
    ],
    ids=["standard", "fej", "invariant"],
)
def test_six_run_anees_of_the_smoother(smoother: SmootherConfig, consistent: bool) -> None:
    """esde's world cut to its first 120 poses (1.4 laps), 6 seeded runs (100..105), a 20-pose window: the standard
    smoother is overconfident (6.92; band 1.37 .. 5.25); with First-Estimates Jacobians, and solves started undamped,
    it is inside the 95% band (3.44), and so with the prior's covariance carried to each new linearization point
    (3.33). Pose covariances reported curved (the default). Cut to 200 poses, 10 runs: 6.30, 2.97 and 2.88 (band
    1.68 .. 4.70); over esde's 400 poses 6.92, 3.85 and 3.71 (as linearized 7.72, 4.41 and 4.24; at 20 runs, seeds
    100..119, 6.54, 3.79 and 3.70 against a band of 2.02 .. 4.16). With the standard linearization and solves started
    undamped it is still overconfident (6.13 at 20 runs of 400 poses, linear): the window and the prior linearize
    the same variables at different points."""
    seeds = tuple(range(100, 106))
    config = ReplayConfig(estimators=("smoother",), smoother=smoother)
    anees, low, high = circle_anees(config, seeds, poses=120)
    print(f"smoother: ANEES {anees:.2f}, band {low:.2f} .. {high:.2f}")
    assert (low <= anees <= high) == consistent and anees >= low, anees
