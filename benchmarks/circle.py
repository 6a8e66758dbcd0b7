"""esde's Monte Carlo protocol (the ``circle`` world, and ``circle-rb`` with range-bearing sightings): the EKF with
each linearization, the smoother, the EKF linearized at the truth and GTSAM's iSAM2 over the same seeds."""

from __future__ import annotations

from dataclasses import dataclass, replace

from online_slam import gtsam_peer
from online_slam.compare import CompareConfig, MonteCarlo, compare
from online_slam.estimators.ekf_config import LINEARIZATIONS, EkfConfig
from online_slam.estimators.smoother import SmootherConfig
from online_slam.pipeline import ReplayConfig

ESDE = {"standard EKF": (4.43, 0.245), "OC-EKF (Huang)": (1.88, 0.173), "iSAM": (1.86, 0.179)}
"""esde's figures, 100 runs, position sightings: (pose ANEES, position RMSE m) (``fig2.txt``, ``fig3_position.txt``)."""
CIRCLE_WORLDS = {"circle": "position sightings (esde's)", "circle-rb": "range-bearing sightings"}
"""The protocol's worlds the section measures, with what they sense."""


@dataclass(frozen=True)
class CircleRow:
    """One estimator's Monte Carlo figures on a circle world."""

    world: str
    """``circle`` or ``circle-rb``."""
    label: str
    """Estimator (and the EKF's linearization)."""
    anees: float
    """Pose NEES averaged over runs, then over esde's steps 5..399."""
    in_band: float
    """Share of those steps whose run-averaged NEES is inside the 95% band."""
    landmark_anees: float | None
    """2-dof NEES of the final map's landmarks, averaged over landmarks and runs (None: iSAM2)."""
    position_rmse_m: float
    """Per step RMS over runs of the position error, averaged over the steps."""
    heading_rmse_rad: float
    """The same for the heading."""


def run_circle(
    runs: int,
    workers: int | None,
    smoother: bool = True,
    peer: bool = True,
    worlds: tuple[str, ...] = tuple(CIRCLE_WORLDS),
) -> tuple[tuple[float, float], list[CircleRow]]:
    """The EKF with every linearization, the default smoother, the smoother with First-Estimates Jacobians and
    with the invariant prior, the ideal EKF (Jacobians at the truth) and iSAM2 (when GTSAM is installed) over seeds
    0..runs-1 of each world.

    Returns:
        (the 95% band of the ANEES for ``runs`` runs, one row per world and estimator).
    """
    rows, band = [], (0.0, 0.0)
    for world in worlds:
        for linearization in LINEARIZATIONS:
            first = linearization == LINEARIZATIONS[0]  # the smoother and the peer run once per world
            replay = ReplayConfig(estimators=("ekf",), ekf=EkfConfig(linearization=linearization))
            config = CompareConfig(replay=replay, runs=runs, workers=workers)
            if not (smoother and first):
                config = replace(config, windows=(), relinearize_every=())
            if peer and first:  # the EKF linearized at the truth, and iSAM2 with GTSAM installed
                config = replace(config, peers=("ideal", "isam2") if gtsam_peer.available() else ("ideal",))
            mc = compare(world, config).monte_carlo
            assert mc is not None
            band = mc.anees_bounds
            rows += _rows(world, mc, linearization)
        for name in ("fej", "invariant") if smoother else ():
            chosen = SmootherConfig(linearization=name)
            replay = ReplayConfig(estimators=("smoother",), smoother=chosen)
            windows, every = (chosen.window.size,), (chosen.relinearize_every,)
            config = CompareConfig(replay=replay, runs=runs, workers=workers, windows=windows, relinearize_every=every)
            mc = compare(world, config).monte_carlo
            assert mc is not None
            rows += _rows(world, mc, name)
    return band, rows


def _rows(world: str, mc: MonteCarlo, linearization: str) -> list[CircleRow]:
    """One row per estimator of a Monte Carlo run."""
    return [
        CircleRow(
            world,
            f"EKF {linearization}" if name == "ekf" else name,
            mc.anees[name],
            mc.anees_in_bounds[name],
            mc.landmark_anees[name],
            mc.position_rmse_m[name],
            mc.heading_rmse_rad[name],
        )
        for name in mc.anees
    ]
