"""The estimate stream (``replay --emit DEST``): one JSON line per step as it is estimated, for a robot's controller.

Each line holds the newest pose of one estimator and its covariance, and the landmarks it added or moved since its
last line (see docs/formats.md, "Estimate stream"). A landmark counts as moved once it lies more than
:data:`MOVE_M` metres, and more than :data:`MOVE_SIGMAS` of its standard deviation, from where its last line put
it: small corrections are held back (they add up until they count), so that lines stay small.

The destination is a file (written line by line, flushed), ``-`` (standard output) or ``tcp://HOST:PORT``: a
reader listening there, to which a thread connects, and reconnects after it goes away. Estimating never waits for a
reader: while none is connected (or it reads too slowly), lines are dropped and counted, with one warning.
"""

from __future__ import annotations

import json
import queue
import socket
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import IO, TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.estimators.protocol import Snapshot
from online_slam.frontend.steps import GroundTruth, Step
from online_slam.sources.address import is_tcp, tcp_address
from online_slam.sources.events import LandmarkId

if TYPE_CHECKING:
    from online_slam.evaluation.results import Results

Array = NDArray[np.float64]

MOVE_M = 0.001
"""A landmark is sent again once it moved more than this many metres since its last line..."""
MOVE_SIGMAS = 0.1
"""... and more than this share of its standard deviation (the root of its covariance's larger diagonal entry)."""
QUEUE_LINES = 10_000
"""Lines a TCP destination holds for a slow reader; beyond them lines are dropped."""
RETRY_S = 0.5
"""Seconds between two attempts to connect to a TCP reader that is not there."""
CONNECT_S = 1.0
"""Seconds one connection attempt, or one line's send, may take before the reader counts as gone."""
CLOSE_S = 2.0
"""Seconds the end of the run waits for a TCP destination to send the lines it holds."""


class _Landmarks:
    """One estimator's landmarks as its lines have put them: what is new or moved in a snapshot."""

    def __init__(self) -> None:
        self.ids: tuple[LandmarkId, ...] = ()
        self.positions: Array = np.zeros((0, 2))

    def changes(self, snapshot: Snapshot) -> tuple[list[int], list[LandmarkId]]:
        """Rows of the snapshot's landmarks to send (new or moved), and the ids sent before that it no longer
        holds; remembers what is sent."""
        ids, xy = snapshot.landmark_ids, np.reshape(snapshot.landmarks, (-1, 2))
        n = len(self.ids)
        removed: list[LandmarkId] = []
        if ids[:n] == self.ids:  # the usual case: the same landmarks in the same order, maybe new ones after
            rows, before, new = np.arange(n), self.positions, np.arange(n, len(ids))
        else:  # some left the map (a smoother's window) or came in another order
            index = {landmark: row for row, landmark in enumerate(ids)}
            kept = [k for k, landmark in enumerate(self.ids) if landmark in index]
            removed = [landmark for landmark in self.ids if landmark not in index]
            rows = np.array([index[self.ids[k]] for k in kept], dtype=int)
            before, new = self.positions[kept], np.setdiff1d(np.arange(len(ids)), rows)
        far = np.linalg.norm(xy[rows] - before, axis=1) > self._threshold(snapshot.landmark_covs, rows)
        send = np.sort(np.concatenate([rows[far], new]))
        positions = np.empty((len(ids), 2))
        positions[rows] = before
        positions[send] = xy[send]
        self.ids, self.positions = ids, positions
        return send.tolist(), removed

    @staticmethod
    def _threshold(covs: Array | None, rows: NDArray[np.int_]) -> Array | float:
        """How far each landmark at ``rows`` must move to be sent again, metres."""
        if covs is None:
            return MOVE_M
        sigma = np.sqrt(np.maximum(covs[rows, 0, 0], covs[rows, 1, 1]))
        return np.maximum(MOVE_M, MOVE_SIGMAS * sigma)


def _plain_id(landmark: LandmarkId) -> int | str:
    """A landmark id as JSON: the stream's, or ``new-<n>`` for one an estimator made from sightings without id."""
    return landmark if isinstance(landmark, (int, str)) else str(landmark)


def estimate_line(step: Step, snapshot: Snapshot, rows: Sequence[int], removed: Sequence[LandmarkId]) -> dict:
    """One line of the estimate stream: the step's newest pose by one estimator, and the given landmarks."""
    covs = snapshot.landmark_covs
    landmarks = []
    for row in rows:
        item: dict = {"id": _plain_id(snapshot.landmark_ids[row]), "xy": snapshot.landmarks[row].tolist()}
        if covs is not None:
            item["cov"] = covs[row].tolist()
        landmarks.append(item)
    line = {
        "t": step.t, "step": step.index, "robot": step.robot, "estimator": snapshot.estimator,
        "pose": snapshot.pose.tolist(), "cov": None if snapshot.pose_cov is None else snapshot.pose_cov.tolist(),
        "landmarks": landmarks,
    }  # fmt: skip
    if removed:
        line["removed"] = [_plain_id(landmark) for landmark in removed]
    if (bias := snapshot.info.get("odometry_bias")) is not None:
        line["odometry_bias"], line["odometry_bias_sd"] = list(bias[:2]), list(bias[2:])
    if snapshot.wall_s is not None:
        line["step_ms"] = 1e3 * snapshot.wall_s
    return line


class EstimateStream:
    """Writes the estimate stream: a :class:`~online_slam.sinks.protocol.ReplaySink`.

    Args:
        destination: A path, ``-`` (standard output) or ``tcp://HOST:PORT`` (a reader listening there).
        estimators: Whose estimates to write, one line each per step, in this order.
        tell: Told, once, that lines are being dropped (no reader; a closed pipe, a full disk), and at the end
            how many were.

    Raises:
        OnlineSlamError: A file that cannot be opened for writing; a TCP address that is not one.
    """

    def __init__(self, destination: str, estimators: Sequence[str], tell: Callable[[str], None] = print) -> None:
        self.estimators = tuple(estimators)
        self.writer: LineWriter = TcpLines(destination, tell) if is_tcp(destination) else FileLines(destination, tell)
        """Where the lines go."""
        self.written = 0
        """Lines given to the writer."""
        self._maps = {name: _Landmarks() for name in self.estimators}
        self._tell = tell

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        """Write a line per chosen estimator (one that left, taking one robot at a time, writes no more)."""
        for name in self.estimators:
            snapshot = snapshots.get(name)
            if snapshot is None:
                continue
            rows, removed = self._maps[name].changes(snapshot)
            line = json.dumps(estimate_line(step, snapshot, rows, removed), separators=(",", ":"))
            self.writer.write(line + "\n")
            self.written += 1

    def on_finish(self, results: Results, truth: GroundTruth) -> None:
        """Close the destination; say how many lines were dropped, if any."""
        self.writer.close()
        dropped = self.writer.dropped
        if dropped:
            self._tell(f"--emit {self.writer.name}: {dropped} of {self.written} lines dropped ({self.writer.why})")


class LineWriter:
    """Where estimate lines go; never raises once open: a line that cannot be written is dropped and counted."""

    name: str
    """The destination as given."""
    why: str = ""
    """Why lines were dropped (the first reason)."""

    def __init__(self, name: str, tell: Callable[[str], None]) -> None:
        self.name, self._tell = name, tell
        self._dropped = 0

    @property
    def dropped(self) -> int:
        """Lines dropped so far."""
        return self._dropped

    def write(self, line: str) -> None:
        """Write one line (it ends with a newline)."""
        raise NotImplementedError

    def close(self) -> None:
        """Write what is held, and close."""
        raise NotImplementedError

    def _dropping(self, why: str) -> None:
        """Lines are being dropped: warn on the first time."""
        if not self.why:
            self.why = why
            self._tell(f"warning: --emit {self.name}: {why}; dropping lines (counted at the end), the run goes on")


class FileLines(LineWriter):
    """A file or standard output, flushed after every line so that a reader sees each at once."""

    def __init__(self, name: str, tell: Callable[[str], None]) -> None:
        super().__init__(name, tell)
        self._handle: IO[str] | None
        try:
            self._handle = sys.stdout if name == "-" else open(name, "w", encoding="utf-8")  # noqa: SIM115
        except OSError as exc:
            raise OnlineSlamError(f"--emit: cannot write {name} ({exc.strerror or exc})") from None

    def write(self, line: str) -> None:
        if self._handle is None:
            self._dropped += 1
            return
        try:
            self._handle.write(line)
            self._handle.flush()
        except (OSError, ValueError) as exc:  # a reader that closed the pipe, a full disk
            self._handle = None
            self._dropped += 1
            self._dropping(f"cannot write ({getattr(exc, 'strerror', None) or exc})")

    def close(self) -> None:
        if self._handle is not None and self._handle is not sys.stdout:
            self._handle.close()


class TcpLines(LineWriter):
    """A reader listening at ``tcp://HOST:PORT``: a thread connects (again after it goes away) and sends."""

    def __init__(self, name: str, tell: Callable[[str], None]) -> None:
        super().__init__(name, tell)
        try:
            self._address = tcp_address(name)
        except ValueError as exc:
            raise OnlineSlamError(f"--emit: {exc}") from None
        self._queue: queue.Queue[bytes | None] = queue.Queue(QUEUE_LINES)
        self._full = 0
        self._thread = threading.Thread(target=self._send_all, name="online-slam emit", daemon=True)
        self._thread.start()

    @property
    def dropped(self) -> int:
        return self._dropped + self._full + self._queue.qsize()

    def write(self, line: str) -> None:
        try:
            self._queue.put_nowait(line.encode("utf-8"))
        except queue.Full:
            self._full += 1

    def close(self) -> None:
        try:
            self._queue.put(None, timeout=CLOSE_S)
        except queue.Full:
            return
        self._thread.join(CLOSE_S)

    def _send_all(self) -> None:
        """The thread: take each line, connect when not connected (at most every :data:`RETRY_S`), send it."""
        client: socket.socket | None = None
        retry = 0.0
        while (line := self._queue.get()) is not None:
            if client is None and time.monotonic() >= retry:
                try:
                    client = socket.create_connection(self._address, timeout=CONNECT_S)
                except OSError as exc:
                    retry = time.monotonic() + RETRY_S
                    self._dropping(f"no reader ({exc.strerror or exc})")
            if client is None:
                self._dropped += 1
                continue
            try:
                client.sendall(line)
            except OSError as exc:
                client.close()
                client, retry = None, 0.0
                self._dropped += 1
                self._dropping(f"the reader went away ({exc.strerror or exc})")
        if client is not None:
            client.close()
