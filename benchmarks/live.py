"""What the socket costs a live replay: the same stream read from a file and over TCP from a feeder process.

The TCP source listens on a free port of this machine, to which a feeder process, started first, connects and
sends every line as fast as it can, then an ``end`` line. Everything after the validated events is the same code
for both, so the figure the target is judged on is reading alone: the source's validated events, file against
TCP, over the grid world, in CPU seconds of the reading process. On a loaded machine the feeder may wait for a
core, and the reader with it: that is the stream's pace, not a cost of the socket (wall seconds of the same, three
runs at load 9 on 2 cores: 0.02 to 0.06 ms per step). The replays of a quarter of it (the library call behind
``online-slam replay``, the EKF alone, the live default latency budget
:data:`~online_slam.frontend.steps.STDIN_LATENCY` for both) are shown beside, in wall seconds: their difference is
the same cost plus the machine's noise, which on seconds of estimating is larger than the cost. Interleaved, best
of N each.
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
from online_slam.pipeline import ReplayConfig, replay
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
    """Reading alone (validated events) from the file: CPU seconds of this process."""
    read_tcp_s: float
    """Reading alone over TCP: CPU seconds of this process (not its waits for the feeder, the stream's pace)."""

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


Clock = Callable[[], float]


def _timed_tcp(path: Path, run: Callable[[str], object], clock: Clock = time.perf_counter) -> float:
    """Seconds of ``run`` over ``tcp://`` with a feeder process sending the file (the feeder's start not counted)."""
    port = _free_port()
    feeder = subprocess.Popen([sys.executable, "-c", FEEDER, str(port), str(path)])
    try:
        time.sleep(0.2)  # the feeder is up and trying to connect
        started = clock()
        run(f"tcp://127.0.0.1:{port}")
        return clock() - started
    finally:
        feeder.wait(30)


def _timed_file(path: Path, run: Callable[[str], object], clock: Clock = time.perf_counter) -> float:
    started = clock()
    run(str(path))
    return clock() - started


def _reading(config: ReplayConfig) -> Callable[[str], None]:
    def read(source: str) -> None:
        for _ in open_events(source, config).events:
            pass

    return read


def _config() -> ReplayConfig:
    return replay_config({"estimators": "ekf", "max_latency": STDIN_LATENCY, "on_error": "stop"})


def socket_ms_per_step(world: GridConfig, repeats: int = 3) -> float:
    """What the socket adds per step reading the world's stream alone (CPU time, best of N each, interleaved), ms:
    the figure ``python -m benchmarks --record`` writes and ``--gate`` holds to :data:`TARGET_MS`."""
    read = _reading(_config())
    best = [float("inf"), float("inf")]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "grid.jsonl"
        write_stream(path, grid_world(world))
        for _ in range(repeats):
            best[0] = min(best[0], _timed_file(path, read, time.process_time))
            best[1] = min(best[1], _timed_tcp(path, read, time.process_time))
    return 1e3 * (best[1] - best[0]) / world.poses


def measure_live_cost(world: GridConfig, repeats: int = 3) -> LiveCost:
    """The grid world as a stream file read alone, and a quarter of it replayed, from the file and over TCP."""
    config = _config()
    read = _reading(config)

    def replayed(source: str) -> None:
        replay(source, config)

    best = {key: float("inf") for key in ("file", "tcp", "read_file", "read_tcp")}
    quarter = dataclasses.replace(world, poses=max(1, world.poses // 4))
    with tempfile.TemporaryDirectory() as folder:
        whole, part = Path(folder) / "grid.jsonl", Path(folder) / "quarter.jsonl"
        lines = write_stream(whole, grid_world(world))
        write_stream(part, grid_world(quarter))
        for _ in range(repeats):
            best["read_file"] = min(best["read_file"], _timed_file(whole, read, time.process_time))
            best["read_tcp"] = min(best["read_tcp"], _timed_tcp(whole, read, time.process_time))
            best["file"] = min(best["file"], _timed_file(part, replayed))
            best["tcp"] = min(best["tcp"], _timed_tcp(part, replayed))
    return LiveCost(world.poses, lines, quarter.poses, best["file"], best["tcp"], best["read_file"], best["read_tcp"])
