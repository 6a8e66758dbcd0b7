"""How an estimator pairs sightings with landmarks: its settings (an import-light module: the option table reads
them; the pairing itself is :mod:`online_slam.estimators.landmark_book`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

ASSOCIATION_CHOICES = ("known", "nn", "jcbb")
"""Values of ``--association`` / ``association=``."""


@dataclass(frozen=True)
class AssociationConfig:
    """How an estimator pairs sightings with landmarks."""

    method: str = "known"
    """``known``: the stream's ids (a sighting without one is associated by JCBB); ``nn`` / ``jcbb``: every
    sighting is associated by that method, ids in the stream are ignored (used only to score)."""
    gate_probability: float = 0.99
    """Individual and joint chi-square gates: probability that a true pairing passes."""
    new_probability: float = 0.9999
    """A sighting no landmark takes starts a new (tentative) landmark only if no confirmed landmark passes
    this wider gate either."""
    confirm: int = 3
    """Sightings (in distinct steps, mutually consistent) that confirm a tentative landmark."""
    tentative_steps: int = 15
    """A tentative landmark not confirmed within this many steps of its first sighting is dropped (keep it below
    the smoother's window, so that its sightings can still be added when it is confirmed)."""
    new_density: float = 0.0
    """Density of landmarks not yet mapped (per m^2): a pairing is kept only if the sighting is likelier a
    sighting of its landmark (the innovation's Gaussian density, per unit of range x bearing) than of an unmapped
    landmark (this density times the range; a position sighting's density is per unit area: this one); otherwise
    the sighting starts a new tentative landmark, however near a mapped one it lies. 0 (default): no such test
    (JCBB's pairing stands)."""
    reach: float = 2.0
    """Candidates: landmarks within the scan's longest range plus this margin (m) plus three sigmas of the
    pose's position and heading from the predicted pose."""
    rival: float = 0.01
    """A scan is left out whole when a rival pairing (as many sightings, with landmarks the sensor alone tells
    apart from the pairing's: another place for the robot) is at least this likely relative to the pairing
    (:func:`~online_slam.frontend.association.rival_ratio`): after a blind stretch one sighting may fit two
    look-alike places, and the wrong one locks the pose there; the next scans decide. 0: never. Why 0.01:
    benchmarks/RESULTS.md "A rival place for the robot"."""
    new_landmarks: bool = True
    """False: a sighting no landmark takes is left out and counted (``not_in_map``), never a new landmark:
    localisation on a map without ids (``--map-only``)."""

    def __post_init__(self) -> None:
        if self.method not in ASSOCIATION_CHOICES:
            raise ValueError(f"association must be one of {', '.join(ASSOCIATION_CHOICES)}, not {self.method!r}")
        if not 0.0 < self.gate_probability < 1.0 or not self.gate_probability <= self.new_probability < 1.0:
            raise ValueError("need 0 < gate_probability <= new_probability < 1")
        if not 0.0 <= self.rival < math.inf:
            raise ValueError("rival must be finite and >= 0")
        if not 0.0 <= self.new_density < math.inf:
            raise ValueError("new_density must be finite and >= 0")
        if self.confirm < 1 or self.tentative_steps < 1:
            raise ValueError("confirm and tentative_steps must be >= 1")

    @property
    def ignores_ids(self) -> bool:
        """True when every sighting is associated (the stream's ids are for scoring only)."""
        return self.method != "known"

    @property
    def scan_method(self) -> str:
        """The method applied to a scan's sightings without ids."""
        return "jcbb" if self.method == "known" else self.method
