"""Rerun: log every replay step to an ``.rrd`` file (or a live viewer).

Layout of a recording (timelines ``step`` and ``time``; ``<e>`` is an estimator's entity part, see
:mod:`~online_slam.sinks.recording.layout`, e.g. ``ekf``, ``smoother``, ``smoother_W10_K1``):

- ``/world/truth/{pose,path,path_recent,landmarks}`` — truth, when the stream has it;
- ``/world/<e>/{pose,pose_cov,path,path_recent,landmarks,landmark_cov}`` for every online estimator (dead
  reckoning ``odometry`` included), ``/world/<e>/window`` for smoothers; ``/world/<e>/{path,landmarks}`` at the
  last step for estimators with a final estimate only (batch). Each pose arrow carries its estimator's name;
- ``/world/observations`` — rays from the current estimate to each observed landmark's measured position;
- ``/metrics/<e>/{step_ms,position_error_m,nees}``, ``/metrics/<e>/nis`` (EKF),
  ``/metrics/<e>/{cost_before,cost_after,iterations}`` (smoothers) — each series named and coloured after its
  estimator; position error and NEES are the table's figures (same frame and alignment, from
  :mod:`online_slam.evaluation`), logged at the end when the alignment is known;
- ``/events`` — text log (landmark initialised, observation gated, relinearization, marginalization, input
  error); ``/summary`` — the results JSON with the layout under ``recording`` (static).

With several robots (steps naming their robot) each robot's entities lie one level down, ``<r>`` being its id as
``robot_<id>`` (``robot_1``): ``/world/truth/<r>/{pose,path,path_recent}``,
``/world/<e>/<r>/{pose,pose_cov,path,path_recent}`` (batch: ``/world/<e>/<r>/path``), its sightings
``/world/observations/<r>`` and its sightings of other robots ``/world/robot_sightings/<r>`` (a line from the
sighting pose to where it measured the seen robot). Everything of a robot is in its colour (dead reckoning a
lighter shade; truth grey), each pose arrow labelled ``<estimator> <id>``; an estimator's map stays at
``/world/<e>/{landmarks,landmark_cov}``. The summary lists the robots under ``recording.robots`` (id -> entity
part and colour). A stream that names no robot keeps the paths above.

Size stays bounded: a path is re-sent whole only when its tail since the last send has reached max(50, sqrt(n))
points (plus that short ``path_recent`` tail every step), landmark labels only when the set of ids changes,
unchanged maps not at all, and landmark covariance ellipses every ``map_every`` steps.
"""

from __future__ import annotations

import functools
import json
import math
import socket
import time
import urllib.parse
import uuid
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import pyarrow as pa
import rerun as rr
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.estimators.protocol import Snapshot
from online_slam.evaluation.results import Results
from online_slam.frontend.steps import GroundTruth, Step
from online_slam.models.observation import RANGE_BEARING, landmark_from_sighting
from online_slam.reports.palette import COLORS
from online_slam.sinks.geometry import ellipses
from online_slam.sinks.recording.blueprint import blueprint
from online_slam.sinks.recording.layout import TRUTH, Layout, robot_color, robot_part
from online_slam.sources.events import Heading, Position, RobotId
from online_slam.wording import counted

Array = NDArray[np.float64]

VIEWER_FLUSH_S = 15.0
"""When streaming to a viewer, wait at most this long at the end for the recording to be delivered."""
VIEWER_PROBE_S = 2.0
"""Before streaming to a viewer, wait at most this long for its port to accept a connection."""
DEFAULT_VIEWER = "rerun+http://127.0.0.1:9876/proxy"
"""Where rerun's gRPC sink connects when no address is given."""
EPOCH = 1e9
"""Stream times at or above this many seconds are taken as Unix timestamps, below as durations."""


@dataclass
class _Path:
    """A trajectory sent whole only when its unsent tail has grown to T = max(50, sqrt(n)) points.

    Every step sends the short tail since the last whole send (``path_recent``), so the full path is always
    visible while the data sent grows as n^1.5 instead of n^2.
    """

    points: list[Array] = field(default_factory=list)
    sent: int = 0

    def add(self, xy: Array) -> tuple[Array | None, Array]:
        """Append a point; return (whole path if it is due, else None; the tail since the last whole send)."""
        self.points.append(np.asarray(xy[:2], dtype=float))
        n = len(self.points)
        whole = None
        if n - self.sent >= max(50, int(math.sqrt(n))):  # whole resends ~n^2/2T points, tails ~nT/2: T ~ sqrt(n)
            whole, self.sent = np.array(self.points), n
        return whole, np.array(self.points[max(self.sent - 1, 0) :])


def _rays(pose: Array, z: Array, model: NDArray[np.int8]) -> list[Array]:
    """Segments from a pose to the measured positions of its sightings, each shape (2, 2)."""
    if not len(z):
        return []
    ends = landmark_from_sighting(pose[None, :], z, model)
    return list(np.stack([np.broadcast_to(pose[:2], ends.shape), ends], axis=1))


def _hex(color: tuple[int, int, int]) -> str:
    return "#{:02x}{:02x}{:02x}".format(*color)


def _ids(noun: str, ids: Any) -> str:
    """``landmark id 15``, ``landmark ids 3, 7``: ids that no one reads as a count."""
    ids = list(ids)
    return f"{noun} id{'s' if len(ids) > 1 else ''} {', '.join(map(str, ids))}"


def viewer_unreachable(address: str, timeout_s: float = VIEWER_PROBE_S) -> str | None:
    """Why the viewer at a ``rerun+http://host:port/...`` address cannot be reached, or None if its port answers.

    rerun's gRPC sink retries an absent viewer silently and gives up only at the end of the run (15 s to flush,
    then 5-15 s more to disconnect); one TCP connection up front tells the user at once and costs nothing.
    """
    parts = urllib.parse.urlsplit(address.removeprefix("rerun+"))
    try:
        host, port = parts.hostname or "127.0.0.1", parts.port or 9876
    except ValueError as exc:  # a port that is not a number
        return str(exc)
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            return None
    except OSError as exc:
        return exc.strerror or type(exc).__name__


@dataclass(frozen=True)
class RerunConfig:
    """Where and how a replay is logged to Rerun."""

    path: str | None = None
    """``.rrd`` file to write, or None."""
    connect: str | None = None
    """gRPC URL of a running viewer (``default`` for the default address), or None."""
    map_every: int = 50
    """Landmark covariance ellipses are logged every this many steps (and at the end)."""
    flush_every: int = 256
    """Per-step data is buffered and sent as columns every this many steps (and at least every 0.25 s when
    streaming to a viewer)."""

    def __post_init__(self) -> None:
        if self.map_every < 1 or self.flush_every < 1:
            raise ValueError("map_every and flush_every must be >= 1")


@functools.cache
def _strip_datatype() -> pa.DataType:
    """The Arrow type of ``LineStrip2D``, read off a one-strip batch built through the public API."""
    return rr.components.LineStrip2DBatch([np.zeros((2, 2), dtype=np.float32)]).as_arrow_array().type


def _strips_array(strips: list[Array]) -> pa.Array:
    """Polylines as one Arrow ``LineStrip2D`` array, built in one go (rerun converts a list strip by strip)."""
    sizes = np.fromiter((len(strip) for strip in strips), dtype=np.int32, count=len(strips))
    offsets = np.zeros(len(strips) + 1, dtype=np.int32)
    np.cumsum(sizes, out=offsets[1:])
    flat = np.concatenate(strips).astype(np.float32).reshape(-1) if strips else np.zeros(0, dtype=np.float32)
    datatype = _strip_datatype()
    points = pa.FixedSizeListArray.from_arrays(pa.array(flat, type=pa.float32()), type=datatype.value_type)
    return pa.ListArray.from_arrays(pa.array(offsets), points, type=datatype)


class _Columns:
    """Per-step values buffered by entity and sent as Rerun columns, one chunk per entity per flush."""

    def __init__(self, rec: rr.RecordingStream) -> None:
        self.rec = rec
        self.rows: dict[tuple[str, str], list[tuple[int, float, Any]]] = {}

    def add(self, entity: str, kind: str, step: Step, value: Any) -> None:
        self.rows.setdefault((entity, kind), []).append((step.index, step.t, value))

    def add_at(self, entity: str, kind: str, index: int, t: float, value: Any) -> None:
        self.rows.setdefault((entity, kind), []).append((index, t, value))

    def flush(self) -> None:
        for (entity, kind), rows in self.rows.items():
            steps = np.array([r[0] for r in rows])
            times = np.array([r[1] for r in rows], dtype=float)
            time_column = (
                rr.TimeColumn("time", timestamp=times) if times[0] >= EPOCH else rr.TimeColumn("time", duration=times)
            )
            indexes = [rr.TimeColumn("step", sequence=steps), time_column]
            values = [r[2] for r in rows]
            if kind == "scalar":
                columns = rr.Scalars.columns(scalars=np.array(values, dtype=float))
            elif kind == "arrow":
                pairs = np.array(values, dtype=float)  # (n, 2, 2): origin, vector
                columns = rr.Arrows2D.columns(origins=pairs[:, 0], vectors=pairs[:, 1])
            elif kind == "ellipse":  # one (mean, 2x2 covariance) per row, drawn here for all rows at once
                rings = ellipses(np.array([v[0] for v in values]), np.array([v[1] for v in values]))
                columns = rr.LineStrips2D.columns(strips=_strips_array(list(rings)))
            elif kind == "text":  # each row: that step's lines
                lengths = [len(v) for v in values]
                lines = [line for v in values for line in v]
                columns = rr.TextLog.columns(text=lines, level=["INFO"] * len(lines)).partition(lengths)
            elif kind == "points":
                lengths = [len(v) for v in values]
                flat = np.concatenate([np.asarray(v, dtype=float).reshape(-1, 2) for v in values])
                columns = rr.Points2D.columns(positions=flat).partition(lengths)
            else:  # strips: each row holds a list of (P, 2) polylines
                lengths = [len(v) for v in values]
                columns = rr.LineStrips2D.columns(strips=_strips_array([s for v in values for s in v])).partition(
                    lengths
                )
            self.rec.send_columns(entity, indexes=indexes, columns=columns)
        self.rows.clear()


class RerunSink:
    """Logs each replay step to Rerun (a :class:`~online_slam.sinks.protocol.ReplaySink`).

    Per-step data is buffered and sent as columns (one chunk per entity every ``flush_every`` steps), which
    costs far less than one log call per value; appearance (colours, radii) is logged once, statically.

    Args:
        config: File and/or live viewer, and logging cadence.
        source: Name of the replayed source (stored as the recording name).
        layout: The estimators that run (names, entities, colours); it also lays out the blueprint.
    """

    def __init__(self, config: RerunConfig, source: str, layout: Layout) -> None:
        if config.path is None and config.connect is None:
            raise ValueError("RerunSink needs a path or a viewer to connect to")
        self.config = config
        self.layout = layout
        self.live = config.connect is not None
        """Whether the recording streams to a viewer (whose port answered: checked first, before any step)."""
        viewer = self._viewer() if self.live else None
        if config.path is not None:  # told here in one line: rerun's own failure also logs a warning of its own
            try:
                with open(config.path, "ab"):
                    pass
            except OSError as exc:
                raise OnlineSlamError(f"{config.path}: cannot write the recording ({exc.strerror or exc})") from None
        self.rec = rr.RecordingStream("online-slam", recording_id=str(uuid.uuid4()))
        self.rec.set_log_tick_enabled(False)
        self.rec.set_log_time_enabled(False)
        self.error: str | None = None
        """Set when the recording could not be delivered (the replay itself is not affected)."""
        sinks: list[Any] = []
        if config.path is not None:
            sinks.append(rr.FileSink(str(config.path)))
        if viewer is not None:
            sinks.append(rr.GrpcSink(viewer))
        try:
            self.rec.set_sinks(*sinks, default_blueprint=blueprint(layout))
        except Exception as exc:  # noqa: BLE001 - rerun raises several kinds; one message for the user
            raise OnlineSlamError(f"rerun: cannot open the recording sink: {exc}") from None
        self.rec.send_recording_name(source)
        self.columns = _Columns(self.rec)
        self.paths: dict[tuple[str, str | None], _Path] = {}
        self.robots: dict[RobotId, tuple[str, tuple[int, int, int]]] = {}
        """With several robots: each robot's entity part and colour, in the order they appeared."""
        self.labels: dict[str, tuple[Any, ...]] = {}
        self._landmark_values: dict[str, Array] = {}
        self.truth_landmarks = 0
        self._last_flush = time.perf_counter()
        self._buffered = 0
        self._last_step: Step | None = None
        estimated = [n for n in layout.online if n != "odometry"]
        self._rays_from = next((n for n in estimated if n.startswith("smoother")), None) or (
            estimated[0] if estimated else "odometry"
        )
        self._appearance()

    def _viewer(self) -> str:
        """The viewer's address; raises when nothing answers there, before the replay does any work."""
        connect = cast(str, self.config.connect)  # a live sink: connect is given
        address = connect if connect != "default" else DEFAULT_VIEWER
        problem = viewer_unreachable(address)
        if problem is not None:
            raise OnlineSlamError(
                f"--connect: no Rerun viewer answers at {self._where()} ({problem}); start one first: 'rerun' on "
                "a desktop, 'rerun --serve-web' on a machine without a display (then open http://localhost:9090)"
            )
        return address

    def _where(self) -> str | None:
        return self.config.connect if self.config.connect != "default" else f"the default address {DEFAULT_VIEWER}"

    def _appearance(self) -> None:
        """Colours, sizes and names, once and for all time."""
        log = self.rec.log
        colors = self.layout.colors()
        for name in (*self.layout.online, TRUTH):
            root, color = self._root(name), [colors[name]]
            self._track_style(root, colors[name], name if name != TRUTH else None)
            log(f"{root}/landmark_cov", rr.LineStrips2D.from_fields(colors=color, radii=[0.008]), static=True)
            log(f"{root}/landmarks", rr.Points2D.from_fields(colors=color, radii=[0.08]), static=True)
            if name == TRUTH:
                continue
            log(f"{root}/window", rr.Points2D.from_fields(colors=color, radii=[0.05]), static=True)
            metrics = self.layout.metrics(name)
            figures = {
                "position_error_m": name,
                "nees": name,
                "step_ms": name,
                "nis": f"{name} NIS",
                "cost_before": f"{name} before",
                "cost_after": name,
                "iterations": name,
            }
            lighter = [tuple((c + 255) // 2 for c in colors[name])]  # the NIS beside its NEES, told apart
            for figure, title in figures.items():
                shade = lighter if figure in ("nis", "cost_before") else color
                log(f"{metrics}/{figure}", rr.SeriesLines(colors=shade, names=[title]), static=True)
        log(
            "world/observations",
            rr.LineStrips2D.from_fields(colors=[COLORS["observations"]], radii=[0.005]),
            static=True,
        )
        fix = [COLORS["truth"]]
        log("world/fixes/position", rr.Points2D.from_fields(colors=fix, radii=[0.15]), static=True)
        log("world/fixes/position_cov", rr.LineStrips2D.from_fields(colors=fix, radii=[0.01]), static=True)
        log("world/fixes/heading", rr.Arrows2D.from_fields(colors=fix, radii=[0.03]), static=True)

    def _track_style(self, root: str, color: tuple[int, int, int], label: str | None) -> None:
        """Colour and sizes of a pose arrow (labelled unless ``label`` is None), its path and its covariance."""
        log, colors = self.rec.log, [color]
        labels: dict[str, Any] = {"labels": [label], "show_labels": True} if label is not None else {}
        log(f"{root}/pose", rr.Arrows2D.from_fields(colors=colors, radii=[0.02], **labels), static=True)
        for part in ("path", "path_recent"):
            log(f"{root}/{part}", rr.LineStrips2D.from_fields(colors=colors, radii=[0.015]), static=True)
        log(f"{root}/pose_cov", rr.LineStrips2D.from_fields(colors=colors, radii=[0.008]), static=True)

    def _root(self, name: str, robot: str | None = None) -> str:
        """Entity root of an estimator's (or the truth's) data, or of one robot's part of it."""
        root = "world/truth" if name == TRUTH else self.layout.world(name)
        return root if robot is None else f"{root}/{robot}"

    def _robot(self, robot: RobotId | None) -> str | None:
        """The entity part of a step's robot (None: the stream names none); styled when it first appears."""
        if robot is None:
            return None
        if robot not in self.robots:
            taken = {part for part, _ in self.robots.values()}
            part, k = robot_part(robot), 2
            while part in taken:
                part, k = f"{robot_part(robot)}_{k}", k + 1
            self.robots[robot] = (part, robot_color(len(self.robots)))
            self._robot_appearance(robot)
        return self.robots[robot][0]

    def _robot_appearance(self, robot: RobotId) -> None:
        """A new robot's colours: its tracks in every estimator (dead reckoning lighter, truth grey), its sightings."""
        part, color = self.robots[robot]
        r, g, b = color
        lighter = ((r + 255) // 2, (g + 255) // 2, (b + 255) // 2)
        for name in (*self.layout.online, TRUTH):
            shade = COLORS[TRUTH] if name == TRUTH else lighter if name == "odometry" else color
            self._track_style(self._root(name, part), shade, None if name == TRUTH else f"{name} {robot}")
        for entity, radius in (("observations", 0.005), ("robot_sightings", 0.02)):
            style = rr.LineStrips2D.from_fields(colors=[color], radii=[radius])
            self.rec.log(f"world/{entity}/{part}", style, static=True)

    # -- per step ----------------------------------------------------------------------------------
    def _time(self, step: Step) -> None:
        self.rec.set_time("step", sequence=step.index)
        if step.t >= EPOCH:
            self.rec.set_time("time", timestamp=step.t)
        else:
            self.rec.set_time("time", duration=step.t)

    def _pose(self, name: str, pose: Array, step: Step, robot: str | None) -> None:
        root = self._root(name, robot)
        # position-only truth (GPS) has no heading: a short stub along x marks the point
        heading = 0.5 * np.array([math.cos(pose[2]), math.sin(pose[2])]) if math.isfinite(pose[2]) else np.zeros(2)
        self.columns.add(f"{root}/pose", "arrow", step, (pose[:2], heading))
        whole, recent = self.paths.setdefault((name, robot), _Path()).add(pose)
        if whole is not None:
            self.columns.add(f"{root}/path", "strips", step, [whole])
        self.columns.add(f"{root}/path_recent", "strips", step, [recent])

    def _landmarks(self, name: str, snapshot: Snapshot, step: Step) -> None:
        root = self._root(name)
        if snapshot.landmark_ids != self.labels.get(name):
            self.labels[name] = snapshot.landmark_ids
            self._time(step)
            labels = [str(i) for i in snapshot.landmark_ids]
            self.rec.log(f"{root}/landmarks", rr.Points2D.from_fields(labels=labels, show_labels=False))
        previous = self._landmark_values.get(name)
        if previous is None or not np.array_equal(previous, snapshot.landmarks):  # unchanged maps are not re-sent
            self._landmark_values[name] = snapshot.landmarks
            self.columns.add(f"{root}/landmarks", "points", step, snapshot.landmarks)
        due = step.index % max(1, self.config.map_every) == 0
        if due and snapshot.landmark_covs is not None and len(snapshot.landmarks):
            self.columns.add(
                f"{root}/landmark_cov", "strips", step, list(ellipses(snapshot.landmarks, snapshot.landmark_covs))
            )

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        """Buffer one step: poses, paths, maps, observation rays, scalars; log its events."""
        add = self.columns.add
        if len(truth.landmarks) != self.truth_landmarks:
            self.truth_landmarks = len(truth.landmarks)
            self._truth_landmarks(truth)
        robot = self._robot(step.robot)
        true_pose = truth.poses.get(step.index)
        if true_pose is not None:
            self._pose(TRUTH, true_pose, step, robot)
        events: list[str] = []
        for name in self.layout.online:
            snap = snapshots.get(name)
            if snap is None:
                continue
            self._pose(name, snap.pose, step, robot)
            self._landmarks(name, snap, step)
            if snap.pose_cov is not None and np.all(np.isfinite(snap.pose_cov)):
                add(f"{self._root(name, robot)}/pose_cov", "ellipse", step, (snap.pose[:2], snap.pose_cov[:2, :2]))
            if snap.wall_s is not None and name != "odometry":
                add(f"{self.layout.metrics(name)}/step_ms", "scalar", step, 1e3 * snap.wall_s)
            events += self._events(name, snap, step)
        current = snapshots.get(self._rays_from) or snapshots.get("odometry")
        pose = None if current is None else current.pose
        rays = [] if pose is None else _rays(pose, step.z, step.z_model)
        add("world/observations" if robot is None else f"world/observations/{robot}", "strips", step, rays)
        if robot is not None:
            model = np.full(len(step.z_robots), RANGE_BEARING, dtype=np.int8)
            add(
                f"world/robot_sightings/{robot}",
                "strips",
                step,
                [] if pose is None else _rays(pose, step.z_robots, model),
            )
        if step.fixes:
            self._fixes(step, pose)
        if events:
            add("events", "text", step, [f"step {step.index}: {text}" for text in events])
        self._last_step = step
        self._buffered += 1
        now = time.perf_counter()
        live = self.live and now - self._last_flush > 0.25
        if live or self._buffered >= self.config.flush_every:
            self.columns.flush()
            self._last_flush, self._buffered = now, 0

    def _fixes(self, step: Step, pose: Array | None) -> None:
        """A step's absolute fixes: each position with its 2-sigma ellipse, each heading as a 2 m arrow from the
        pose drawn (none without a pose)."""
        add = self.columns.add
        positions = [f for f in step.fixes if isinstance(f, Position)]
        if positions:
            add("world/fixes/position", "points", step, [f.xy for f in positions])
            for p in positions:
                add("world/fixes/position_cov", "ellipse", step, (np.array(p.xy), p.covariance))
        for h in step.fixes:
            if isinstance(h, Heading) and pose is not None:
                arrow = 2.0 * np.array([np.cos(h.theta), np.sin(h.theta)])
                add("world/fixes/heading", "arrow", step, (pose[:2], arrow))

    def _events(self, name: str, snap: Snapshot, step: Step) -> list[str]:
        """Per-step figures and events from the snapshot's info (NIS and gating for a filter, solves and
        marginalization for a smoother), whatever the estimator is called."""
        info, out, metrics = snap.info, [], self.layout.metrics(name)
        if "nis" in info:
            nis = np.asarray(info.get("nis", []), dtype=float)
            if np.isfinite(nis).any():
                self.columns.add(f"{metrics}/nis", "scalar", step, float(np.nanmean(nis)))
        if (bias := info.get("odometry_bias")) is not None:  # the EKF's, of the step's robot
            self.columns.add(f"{metrics}/odometry_bias_scale", "scalar", step, float(bias[0]))
            self.columns.add(f"{metrics}/odometry_bias_rate", "scalar", step, float(bias[1]))
        if info.get("new_landmarks"):
            out.append(f"{name}: initialised {_ids('landmark', info['new_landmarks'])}")
        if info.get("gated"):
            out.append(f"{name}: sightings gated (chi-square) of {_ids('landmark', info['gated'])}")
        if info.get("window") is not None and info.get("window_poses") is not None:
            self.columns.add(f"{self._root(name)}/window", "points", step, info["window_poses"][:, :2])
        if info.get("relinearized") and "iterations" in info:
            for key in ("cost_before", "cost_after", "iterations"):
                self.columns.add(f"{metrics}/{key}", "scalar", step, float(info[key]))
            out.append(f"{name}: relinearized, {counted(info['iterations'], 'iteration')}")
        if "global_s" in info:
            if info.get("global_rejected"):
                out.append(f"{name}: global relinearization not kept (the history did not reconcile)")
            else:
                out.append(f"{name}: relinearized globally, {counted(info['global_iterations'], 'iteration')}")
        if info.get("marginalized"):
            out.append(f"{name}: marginalized {_ids('pose', info['marginalized'])}")
        return out

    def _truth_landmarks(self, truth: GroundTruth) -> None:
        ids = list(truth.landmarks)
        points = np.array([truth.landmarks[i] for i in ids])
        self.rec.log(
            "world/truth/landmarks",
            rr.Points2D(points, labels=[str(i) for i in ids], colors=[COLORS["truth"]], radii=[0.1], show_labels=False),
            static=True,
        )

    # -- end ---------------------------------------------------------------------------------------
    def _final_paths(self, name: str, poses: Array, step_robots: tuple[RobotId | None, ...]) -> None:
        """A final estimate's path, or with several robots each robot's, in its colour."""
        root = self.layout.world(name)
        if not step_robots:
            self.rec.log(
                f"{root}/path", rr.LineStrips2D([poses[:, :2]], colors=[self.layout.colors()[name]], labels=[name])
            )
            return
        column = np.array(step_robots[: len(poses)], dtype=object)
        for robot in dict.fromkeys(step_robots):
            part, color = self._robot(robot), self.robots[cast(RobotId, robot)][1]  # several robots: all named
            strip = poses[column == robot, :2]
            self.rec.log(f"{root}/{part}/path", rr.LineStrips2D([strip], colors=[color], labels=[f"{name} {robot}"]))

    def on_finish(self, results: Results, truth: GroundTruth) -> None:
        """Send what is buffered, the batch solution at the last step, the summary; close the file."""
        rec = self.rec
        # Errors and NEES as the table computes them (same frame and alignment: known only at the end).
        for name, series in results.series.items():
            metrics = self.layout.metrics(name)
            for entity, values in (("position_error_m", series.position_error_m), ("nees", series.nees)):
                for index in np.flatnonzero(np.isfinite(values)):
                    self.columns.add_at(
                        f"{metrics}/{entity}", "scalar", int(index), float(series.t[index]), float(values[index])
                    )
        self.columns.flush()
        if self._last_step is not None:
            self._time(self._last_step)
        if truth.landmarks:
            self._truth_landmarks(truth)
        colors = self.layout.colors()
        for name in self.layout.final:
            estimate = results.estimates.get(name)
            if estimate is None or not len(estimate.poses):
                continue
            root, color = self.layout.world(name), [colors[name]]
            self._final_paths(name, estimate.poses, results.step_robots)
            rec.log(
                f"{root}/landmarks",
                rr.Points2D(
                    estimate.landmarks,
                    labels=[str(i) for i in estimate.landmark_ids],
                    colors=color,
                    radii=[0.08],
                    show_labels=False,
                ),
            )
        if results.error:
            rec.log("events", rr.TextLog(f"input stopped early: {results.error}", level="ERROR"))
        if results.robot is not None:  # known from the stream's header, read after the recording was opened
            rec.send_recording_name(f"{results.source}, robot {results.robot}")
        recording = self.layout.to_json()
        if self.robots:
            recording["robots"] = {str(r): {"entity": part, "color": _hex(c)} for r, (part, c) in self.robots.items()}
        summary = dict(results.to_json(), recording=recording)
        rec.log("summary", rr.TextDocument(json.dumps(summary, indent=2), media_type="text/plain"), static=True)
        try:  # a viewer that never answers must not hang the run (rerun-sdk 0.41 can wait for it forever)
            rec.flush(timeout_sec=VIEWER_FLUSH_S) if self.live else rec.flush()
        except RuntimeError as exc:  # e.g. no viewer at the address: the results must not be lost over it
            where = f"the viewer at {self._where()}" if self.live else f"the file {self.config.path}"
            self.error = f"rerun: could not deliver the recording to {where} ({exc})"
        rec.disconnect()
