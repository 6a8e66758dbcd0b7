"""What the socket costs a live replay: the same stream read from a file and over TCP from a feeder process.

The TCP source listens on a free port of this machine, to which a feeder process, started first, connects and
sends every line as fast as it can, then an ``end`` line: so the reader never waits for the feeder, and the
difference is the socket path (receiving, splitting lines, the reader loop's waits). Everything after the
validated events is the same code for both, so the figure the target is judged on is reading alone: the source's
validated events, file against TCP, over the grid world. The replays (the library call behind ``online-slam
replay``, the EKF alone, the live default latency budget :data:`~online_slam.frontend.steps.STDIN_LATENCY` for
both) of a quarter of it are shown beside: their difference is the same cost plus the machine's noise, which on
seconds of estimating is larger than the cost. Interleaved, best of N each.
"""

from __future__ import annotations

import dataclasses
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from online_slam.frontend.steps import STDIN_LATENCY
from online_slam.options import replay_config
from online_slam.pipeline import replay
from online_slam.pipeline.source import open_events
from online_slam.sources import grid_world, write_stream
from online_slam.sources.worlds import GridConfig

FEEDER = """
import socket, sys, time
port, path = int(sys.argv[1]), sys.argv[2]
data = open(path, "rb").read() + b'{"type": "end"}\\n'
while True:
    try:
        client = socket.create_connection(("127.0.0.1", port))
        break
    except ConnectionRefusedError:
        time.sleep(0.002)
with client:
    client.sendall(data)
"""
TARGET_MS = 0.1
"""The socket may cost a replay at most this much per step over a file."""


@dataclass(frozen=True)
class LiveCost:
    """Best-of-N seconds of one stream read from a file and over TCP."""

    poses: int
    """Poses of the stream read alone."""
    lines: int
    """Its lines."""
    replay_poses: int
    """Poses of the stream replayed."""
    file_s: float
    """Replay of the file."""
    tcp_s: float
    """Replay of the same lines over TCP."""
    read_file_s: float
    """Reading alone (validated events) from the file."""
    read_tcp_s: float
    """Reading alone over TCP."""

    @property
    def per_step_ms(self) -> float:
        """What the socket adds per step (reading alone), milliseconds."""
        return 1e3 * (self.read_tcp_s - self.read_file_s) / self.poses

    @property
    def replay_per_step_ms(self) -> float:
        """The replays' difference per step (the same cost, and the machine's noise), milliseconds."""
        return 1e3 * (self.tcp_s - self.file_s) / self.replay_poses


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _timed_tcp(path: Path, run: Callable[[str], object]) -> float:
    """Seconds of ``run`` over ``tcp://`` with a feeder process sending the file (the feeder's start not counted)."""
    port = _free_port()
    feeder = subprocess.Popen([sys.executable, "-c", FEEDER, str(port), str(path)])
    try:
        time.sleep(0.2)  # the feeder is up and trying to connect
        started = time.perf_counter()
        run(f"tcp://127.0.0.1:{port}")
        return time.perf_counter() - started
    finally:
        feeder.wait(30)


def _timed_file(path: Path, run: Callable[[str], object]) -> float:
    started = time.perf_counter()
    run(str(path))
    return time.perf_counter() - started


def measure_live_cost(world: GridConfig, repeats: int = 3) -> LiveCost:
    """The grid world as a stream file read alone, and a quarter of it replayed, from the file and over TCP."""
    config = replay_config({"estimators": "ekf", "max_latency": STDIN_LATENCY, "on_error": "stop"})

    def replayed(source: str) -> None:
        replay(source, config)

    def read(source: str) -> None:
        for _ in open_events(source, config).events:
            pass

    best = {key: float("inf") for key in ("file", "tcp", "read_file", "read_tcp")}
    quarter = dataclasses.replace(world, poses=max(1, world.poses // 4))
    with tempfile.TemporaryDirectory() as folder:
        whole, part = Path(folder) / "grid.jsonl", Path(folder) / "quarter.jsonl"
        lines = write_stream(whole, grid_world(world))
        write_stream(part, grid_world(quarter))
        for _ in range(repeats):
            best["read_file"] = min(best["read_file"], _timed_file(whole, read))
            best["read_tcp"] = min(best["read_tcp"], _timed_tcp(whole, read))
            best["file"] = min(best["file"], _timed_file(part, replayed))
            best["tcp"] = min(best["tcp"], _timed_tcp(part, replayed))
    return LiveCost(world.poses, lines, quarter.poses, best["file"], best["tcp"], best["read_file"], best["read_tcp"])
