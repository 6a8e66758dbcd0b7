"""Where each estimator lives in a recording: entity paths, colours and labels (pure, no rerun).

Estimator names may hold spaces and ``=`` (``smoother W=10 K=1``); entity path parts are kept to letters,
digits, ``_``, ``-`` and ``.`` (``smoother_W10_K1``), so no escaping is ever needed. The layout is stored in the
recording's summary, so a reader finds every estimator's entities without guessing.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

from online_slam.reports.palette import COLORS, OKABE_ITO, rgb_colors

TRUTH = "truth"
"""Entity name of the ground truth."""

ROBOT_COLORS: tuple[tuple[int, int, int], ...] = tuple(
    OKABE_ITO[name] for name in ("orange", "sky blue", "bluish green", "reddish purple", "blue", "vermillion", "yellow")
)
"""0-255 RGB of the robots of a recording of several robots, in the order they first appear (then again)."""


def robot_part(robot: int | str) -> str:
    """A robot id as one entity path part: ``1`` -> ``robot_1``, ``"ugv 2"`` -> ``robot_ugv_2``."""
    return f"robot_{entity_part(str(robot))}"


def robot_color(k: int) -> tuple[int, int, int]:
    """The colour of the k-th robot (0-based) to appear."""
    return ROBOT_COLORS[k % len(ROBOT_COLORS)]


def entity_part(name: str) -> str:
    """An estimator name as one entity path part: ``smoother W=10 K=1`` -> ``smoother_W10_K1``."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name.replace("=", "")).strip("_") or "estimator"


@dataclass(frozen=True)
class Layout:
    """The estimators of one recording, in table order."""

    online: tuple[str, ...]
    """Estimators logged at every step (dead reckoning ``odometry`` first, then EKF, smoothers...)."""
    final: tuple[str, ...] = ()
    """Estimators with a final estimate only (batch), logged at the last step."""
    entities: dict[str, str] = field(default_factory=dict)
    """Estimator name -> its entity path part (filled in from the names; distinct)."""

    def __post_init__(self) -> None:
        if self.entities:
            return
        taken: set[str] = {TRUTH, "observations"}
        for name in (*self.online, *self.final):
            part, k = entity_part(name), 2
            base = part
            while part in taken:
                part, k = f"{base}_{k}", k + 1
            taken.add(part)
            self.entities[name] = part

    @property
    def names(self) -> tuple[str, ...]:
        """Every estimator, online ones first."""
        return (*self.online, *self.final)

    def world(self, name: str) -> str:
        """Entity root of an estimator's map data, e.g. ``world/smoother_W10_K1``."""
        return f"world/{self.entities[name] if name in self.entities else entity_part(name)}"

    def metrics(self, name: str) -> str:
        """Entity root of an estimator's per-step figures, e.g. ``metrics/ekf``."""
        return f"metrics/{self.entities[name] if name in self.entities else entity_part(name)}"

    def colors(self) -> dict[str, tuple[int, int, int]]:
        """0-255 RGB per estimator (the plots' colours) and for the truth."""
        return {**rgb_colors(self.names), TRUTH: COLORS[TRUTH]}

    def to_json(self) -> dict[str, Any]:
        """Stored in the recording's summary under ``recording``."""
        colors = self.colors()
        return {
            "online": list(self.online),
            "final": list(self.final),
            "entities": dict(self.entities),
            "colors": {name: "#{:02x}{:02x}{:02x}".format(*colors[name]) for name in self.names},
        }

    @classmethod
    def from_json(cls, value: dict[str, Any] | None, estimators: list[str]) -> Layout:
        """The layout a summary stored; for a recording without one, entities named after the estimators."""
        if value:
            return cls(tuple(value["online"]), tuple(value["final"]), dict(value["entities"]))
        online = tuple(n for n in ("odometry", *estimators) if n != "batch")
        return cls(online, tuple(n for n in estimators if n == "batch"), {n: n for n in (*online, "batch")})
