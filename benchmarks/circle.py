"""esde's Monte Carlo protocol (the ``circle`` world): the EKF with each linearization and the smoother."""

from __future__ import annotations

from dataclasses import dataclass, replace

from online_slam.compare import CompareConfig, compare
from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.linearization import LINEARIZATIONS
from online_slam.pipeline import ReplayConfig

ESDE = {"standard EKF": (4.43, 0.245), "OC-EKF (Huang)": (1.88, 0.173), "iSAM": (1.86, 0.179)}
"""esde's figures, 100 runs, position sightings: (pose ANEES, position RMSE m) (``fig2.txt``, ``fig3_position.txt``)."""


@dataclass(frozen=True)
class CircleRow:
    """One estimator's Monte Carlo figures on the circle world."""

    label: str
    """Estimator and its linearization."""
    anees: float
    """Pose NEES averaged over runs, then over esde's steps 5..399."""
    in_band: float
    """Share of those steps whose run-averaged NEES is inside the 95% band."""
    landmark_anees: float | None
    """2-dof NEES of the final map's landmarks, averaged over landmarks and runs."""
    position_rmse_m: float
    """Per step RMS over runs of the position error, averaged over the steps."""
    heading_rmse_rad: float
    """The same for the heading."""


def run_circle(runs: int, workers: int | None, smoother: bool = True) -> tuple[tuple[float, float], list[CircleRow]]:
    """The EKF with every linearization (and the default smoother) over ``runs`` seeds of the circle world.

    Returns:
        (the 95% band of the ANEES for ``runs`` runs, one row per estimator).
    """
    rows, band = [], (0.0, 0.0)
    for linearization in LINEARIZATIONS:
        names = ("ekf", "smoother") if smoother and linearization == "standard" else ("ekf",)
        replay = ReplayConfig(estimators=("ekf",), ekf=EkfConfig(linearization=linearization))
        config = CompareConfig(replay=replay, runs=runs, workers=workers)
        if "smoother" not in names:
            config = replace(config, windows=(), relinearize_every=())
        mc = compare("circle", config).monte_carlo
        assert mc is not None
        band = mc.anees_bounds
        for name in mc.anees:
            label = f"EKF {linearization}" if name == "ekf" else name
            rows.append(
                CircleRow(
                    label,
                    mc.anees[name],
                    mc.anees_in_bounds[name],
                    mc.landmark_anees[name],
                    mc.position_rmse_m[name],
                    mc.heading_rmse_rad[name],
                )
            )
    return band, rows
