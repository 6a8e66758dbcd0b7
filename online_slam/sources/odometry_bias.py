"""A stream's odometry biased: what a robot with a wheel radius off and a drifting turn rate would log.

The inverse of :func:`~online_slam.models.motion.unbiased_increment`: each increment's distance overstated by
``1 / (1 - s)`` and ``w`` rad/s added to its turn, per robot (its time span since that robot's previous pose).
Simulated worlds draw odometry without bias; this makes the stress streams of benchmarks/RESULTS.md ("Odometry
biased beyond the model") and the tests of the EKF's bias state.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator, Mapping

from online_slam.sources.events import Event, Odometry, RobotId, Start


def biased_odometry(
    events: Iterable[Event], bias: tuple[float, float] | Mapping[RobotId | None, tuple[float, float]]
) -> Iterator[Event]:
    """The events with every odometry increment biased; the declared covariances unchanged.

    Args:
        events: A stream's events.
        bias: ``(s, w)`` for every robot, or by robot (a robot not named is left as it is). The logged increment
            is ``[dx / (1 - s), dy / (1 - s), dtheta + w dt]``, so that the EKF's ``[s, w]`` undoes it exactly.
    """
    last: dict[RobotId | None, float] = {}
    for event in events:
        if isinstance(event, Odometry) and event.robot in last:
            s, w = bias if isinstance(bias, tuple) else bias.get(event.robot, (0.0, 0.0))
            dx, dy, dtheta = event.delta
            dt = event.t - last[event.robot]
            event = dataclasses.replace(event, delta=(dx / (1.0 - s), dy / (1.0 - s), dtheta + w * dt))
        if isinstance(event, (Odometry, Start)):
            last[event.robot] = event.t
        yield event
