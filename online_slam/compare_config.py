"""What ``online-slam compare`` runs: its settings (an import-light module: the option table reads them; the
comparison itself is :mod:`online_slam.compare`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from online_slam.estimators.smoother.config import SmootherConfig, WindowConfig
from online_slam.pipeline.config import ReplayConfig

PEERS = ("isam2", "ideal")
"""Peers Monte Carlo can run beside the estimators: ``isam2``, GTSAM's iSAM2 (full smoothing, relinearized
incrementally; :func:`~online_slam.gtsam_peer.isam2_online`, factorized by QR), each step reading the newest pose
and its ``marginalCovariance``; ``ideal``, the EKF with every Jacobian at the true state
(:class:`~online_slam.estimators.ideal_ekf.IdealEkf`: the yardstick of consistency, simulated worlds only)."""


@dataclass(frozen=True)
class CompareConfig:
    """What ``online-slam compare`` runs."""

    windows: tuple[int, ...] = (WindowConfig.size,)
    """Smoother window sizes W; every (W, K) pair is run."""
    relinearize_every: tuple[int, ...] = (SmootherConfig.relinearize_every,)
    """Smoother relinearization periods K."""
    replay: ReplayConfig = field(default_factory=lambda: ReplayConfig(estimators=("ekf", "batch")))
    """Everything else (EKF and batch settings, front-end, alignment); its smoother settings seed each (W, K)."""
    runs: int = 1
    """Monte Carlo runs over noise seeds (simulated worlds only); 1 = just the given stream."""
    workers: int | None = None
    """Processes for Monte Carlo runs (default: all cores)."""
    peers: tuple[str, ...] = ()
    """Peers (:data:`PEERS`) run on every Monte Carlo run's stream, beside the estimators: their figures over
    steps join the online estimators' (Monte Carlo only, so ``runs`` >= 2)."""

    def __post_init__(self) -> None:
        if any(w < 1 for w in self.windows) or any(k < 1 for k in self.relinearize_every):
            raise ValueError("windows and relinearize_every must be >= 1")
        if self.runs < 1 or (self.workers is not None and self.workers < 1):
            raise ValueError("runs and workers must be >= 1")
        if any(p not in PEERS for p in self.peers) or len(set(self.peers)) != len(self.peers):
            raise ValueError(f"peers must be distinct names of {', '.join(PEERS)}, not {', '.join(self.peers)}")
        if self.peers and self.runs < 2:
            raise ValueError("a peer runs in Monte Carlo runs: give runs >= 2")
