"""The robot rules of stream v1: which robot an event is of, which robot a sighting sees.

A stream names no robot (one robot, as every stream before robots), or names one on every ``start``,
``odometry``, ``observation`` and ``truth``. Each robot starts once (its ``start`` line) before any other line
names it; a sighting of another robot (``robot_seen``) is of a started robot, never of the sighting robot
itself, and carries no landmark. Time is the stream's one clock: it never decreases over all robots together.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from online_slam.sources.events import RobotId

if TYPE_CHECKING:
    from online_slam.errors import InputError
    from online_slam.sources.validate import ValidatorState

ROBOT_FIELDS: dict[str, set[str]] = {
    "start": {"robot"},
    "odometry": {"robot"},
    "observation": {"robot", "robot_seen"},
    "truth": {"robot"},
    "position": {"robot"},
    "heading": {"robot"},
}
"""The robot fields each event type allows besides its own."""


def robot_ids(robots: tuple[RobotId, ...]) -> str:
    """Robot ids for a message: ``1, 2, 3`` (at most five, then ``...``)."""
    shown = ", ".join(json.dumps(r) for r in robots[:5])
    return shown + (", ..." if len(robots) > 5 else "")


class RobotRules:
    """The robot checks of :class:`~online_slam.sources.validate.EventValidator` (which provides ``fail`` and
    the pending state)."""

    _pending: ValidatorState
    fail: Callable[[int, str, str], InputError]

    def robot(self, record: dict[str, Any], line: int, key: str = "robot") -> RobotId | None:
        """The started robot under ``key`` (``robot``: the event's own, required once robots are named;
        ``robot_seen``: the robot a sighting sees), or None when absent."""
        started = self._pending.robots
        if key not in record:
            if started and key == "robot":
                raise self._missing(line)
            return None
        value = self.robot_id(record, line, key)
        if value not in started:
            named = f" (robots: {robot_ids(started)})" if started else ""
            shown = robot_ids((value,))
            raise self.fail(line, key, f"unknown robot {shown}: no start names it before{named}")
        return value

    def robot_id(self, record: dict[str, Any], line: int, key: str) -> RobotId:
        """An integer or non-empty string id under ``key``."""
        value = record[key]
        if isinstance(value, bool) or not isinstance(value, (int, str)) or value == "":
            shown = json.dumps(value, default=repr)[:60]
            raise self.fail(line, key, f"expected an integer or a non-empty string id, got {shown}")
        return value

    def new_robot(self, record: dict[str, Any], line: int) -> RobotId | None:
        """The robot a ``start`` names (not started yet), or None for a stream of one unnamed robot."""
        started = self._pending.robots
        if "robot" not in record:
            if started:
                raise self._missing(line)
            return None
        robot = self.robot_id(record, line, "robot")
        if robot in started:
            raise self.fail(line, "robot", f"robot {robot_ids((robot,))} already has a start (one start per robot)")
        if self._pending.first_pose_t is not None and not started:
            message = "the first pose names no robot, so no other robot may join; name the robot on every start"
            raise self.fail(line, "robot", message)
        self._pending.robots = (*started, robot)
        return robot

    def sighted_robot(self, record: dict[str, Any], line: int, robot: RobotId | None) -> RobotId | None:
        """The robot a sighting sees (``robot_seen``; then no landmark nor its truth, and range and bearing), or
        None."""
        seen = self.robot(record, line, "robot_seen")
        if seen is None:
            return None
        if seen == robot:
            raise self.fail(line, "robot_seen", f"robot {robot_ids((seen,))} cannot sight itself")
        for key in ("landmark", "truth_landmark", "truth_outlier"):
            if record.get(key) is not None:
                raise self.fail(line, key, "a sighting of a robot (robot_seen) has no landmark, nor its truth")
        if "xy" in record:
            raise self.fail(line, "xy", "a sighting of a robot gives range and bearing, not xy")
        return seen

    def _missing(self, line: int) -> InputError:
        named = robot_ids(self._pending.robots)
        return self.fail(line, "robot", f"missing required field: this stream's robots are named ({named})")
