"""Sources: where events come from (stream files, stdin, built-in simulated worlds)."""

from online_slam.sources.events import (
    End,
    Event,
    GeneratedId,
    Header,
    LandmarkId,
    LandmarkTruth,
    Observation,
    Odometry,
    RobotId,
    Start,
    Truth,
)
from online_slam.sources.stream import read_stream, write_stream
from online_slam.sources.worlds import (
    WORLDS,
    GridConfig,
    MeetConfig,
    WaypointConfig,
    grid_world,
    meet_world,
    square_world,
    waypoint_world,
)

__all__ = [
    "WORLDS",
    "End",
    "Event",
    "GeneratedId",
    "GridConfig",
    "WaypointConfig",
    "Header",
    "LandmarkId",
    "LandmarkTruth",
    "MeetConfig",
    "Observation",
    "Odometry",
    "RobotId",
    "Start",
    "Truth",
    "grid_world",
    "meet_world",
    "waypoint_world",
    "read_stream",
    "square_world",
    "write_stream",
]
