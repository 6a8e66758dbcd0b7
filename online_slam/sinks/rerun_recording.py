"""Rerun: log every replay step to an ``.rrd`` file (or a live viewer), and read a recording back.

This is the only module that imports rerun. Layout of a recording (timelines ``step`` and ``time``):

- ``/world/truth/{pose,path,path_recent,landmarks}`` — truth, when the stream has it (landmarks static);
- ``/world/<estimator>/{pose,pose_cov,path,path_recent,landmarks,landmark_cov}`` for ``odometry``, ``ekf``,
  ``smoother``; ``/world/smoother/window``; ``/world/batch/{path,landmarks}`` at the last step;
- ``/world/observations`` — rays from the current estimate to each observed landmark's measured position;
- ``/metrics/<estimator>/{step_ms,position_error_m,nees}``, ``/metrics/ekf/nis``,
  ``/metrics/smoother/{cost_before,cost_after,iterations}``;
- ``/events`` — text log (landmark initialised, observation gated, relinearization, marginalization, input
  error); ``/summary`` — the results as JSON (static).

Size stays bounded: a path is re-sent whole only when its tail since the last send has reached max(50, sqrt(n))
points (plus that short ``path_recent`` tail every step), landmark labels only when the set of ids changes,
unchanged maps not at all, and landmark covariance ellipses every ``map_every`` steps.
"""

from __future__ import annotations

import functools
import json
import math
import time
import uuid
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.estimators.protocol import Snapshot
from online_slam.evaluation.results import Results
from online_slam.frontend.steps import GroundTruth, Step
from online_slam.models.range_bearing import landmark_from_observation
from online_slam.reports.palette import COLORS
from online_slam.sinks.geometry import ellipses

Array = NDArray[np.float64]

ONLINE = ("odometry", "ekf", "smoother")
"""Estimators whose snapshots are real-time estimates (logged every step)."""
EPOCH = 1e9
"""Stream times at or above this many seconds are taken as Unix timestamps, below as durations."""


def blueprint(estimators: tuple[str, ...]) -> rrb.Blueprint:
    """The default layout: the map, the time series, the event log."""
    series = [
        rrb.TimeSeriesView(origin="/metrics", contents="$origin/*/position_error_m", name="position error (m)"),
        rrb.TimeSeriesView(origin="/metrics", contents="$origin/*/step_ms", name="step time (ms)"),
        rrb.TimeSeriesView(origin="/metrics", contents=["$origin/*/nees", "$origin/ekf/nis"], name="NEES / NIS"),
    ]
    if "smoother" in estimators:
        series.append(
            rrb.TimeSeriesView(origin="/metrics/smoother", contents="$origin/**", name="smoother cost, iterations")
        )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(origin="/world", name="map"),
            rrb.Vertical(rrb.Tabs(*series, name="time series"), rrb.TextLogView(origin="/events", name="events")),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


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
        estimators: Names of the estimators that run, to lay out the blueprint.
    """

    def __init__(self, config: RerunConfig, source: str, estimators: tuple[str, ...]) -> None:
        if config.path is None and config.connect is None:
            raise ValueError("RerunSink needs a path or a viewer to connect to")
        self.config = config
        self.rec = rr.RecordingStream("online-slam", recording_id=str(uuid.uuid4()))
        self.rec.set_log_tick_enabled(False)
        self.rec.set_log_time_enabled(False)
        sinks: list[Any] = []
        if config.path is not None:
            sinks.append(rr.FileSink(str(config.path)))
        if config.connect is not None:
            sinks.append(rr.GrpcSink(config.connect) if config.connect != "default" else rr.GrpcSink())
        try:
            self.rec.set_sinks(*sinks, default_blueprint=blueprint(estimators))
        except Exception as exc:  # noqa: BLE001 - rerun raises several kinds; one message for the user
            raise OnlineSlamError(f"rerun: cannot open the recording sink: {exc}") from None
        self.rec.send_recording_name(source)
        self.columns = _Columns(self.rec)
        self.paths: dict[str, _Path] = {}
        self.labels: dict[str, tuple[Any, ...]] = {}
        self._landmark_values: dict[str, Array] = {}
        self.truth_landmarks = 0
        self._last_flush = time.perf_counter()
        self._buffered = 0
        self._last_step: Step | None = None
        self.error: str | None = None
        """Set when the recording could not be delivered (the replay itself is not affected)."""
        self._appearance()

    def _appearance(self) -> None:
        """Colours and sizes, once and for all time."""
        log = self.rec.log
        for name in (*ONLINE, "truth"):
            color = [COLORS[name]]
            log(f"world/{name}/pose", rr.Arrows2D.from_fields(colors=color, radii=[0.02]), static=True)
            for part in ("path", "path_recent"):
                log(f"world/{name}/{part}", rr.LineStrips2D.from_fields(colors=color, radii=[0.015]), static=True)
            for part in ("pose_cov", "landmark_cov"):
                log(f"world/{name}/{part}", rr.LineStrips2D.from_fields(colors=color, radii=[0.008]), static=True)
            log(f"world/{name}/landmarks", rr.Points2D.from_fields(colors=color, radii=[0.08]), static=True)
        log("world/smoother/window", rr.Points2D.from_fields(colors=[COLORS["smoother"]], radii=[0.05]), static=True)
        log(
            "world/observations",
            rr.LineStrips2D.from_fields(colors=[COLORS["observations"]], radii=[0.005]),
            static=True,
        )

    # -- per step ----------------------------------------------------------------------------------
    def _time(self, step: Step) -> None:
        self.rec.set_time("step", sequence=step.index)
        if step.t >= EPOCH:
            self.rec.set_time("time", timestamp=step.t)
        else:
            self.rec.set_time("time", duration=step.t)

    def _pose(self, name: str, pose: Array, step: Step) -> None:
        heading = 0.5 * np.array([math.cos(pose[2]), math.sin(pose[2])])
        self.columns.add(f"world/{name}/pose", "arrow", step, (pose[:2], heading))
        whole, recent = self.paths.setdefault(name, _Path()).add(pose)
        if whole is not None:
            self.columns.add(f"world/{name}/path", "strips", step, [whole])
        self.columns.add(f"world/{name}/path_recent", "strips", step, [recent])

    def _landmarks(self, name: str, snapshot: Snapshot, step: Step) -> None:
        if snapshot.landmark_ids != self.labels.get(name):
            self.labels[name] = snapshot.landmark_ids
            self._time(step)
            labels = [str(i) for i in snapshot.landmark_ids]
            self.rec.log(f"world/{name}/landmarks", rr.Points2D.from_fields(labels=labels, show_labels=False))
        previous = self._landmark_values.get(name)
        if previous is None or not np.array_equal(previous, snapshot.landmarks):  # unchanged maps are not re-sent
            self._landmark_values[name] = snapshot.landmarks
            self.columns.add(f"world/{name}/landmarks", "points", step, snapshot.landmarks)
        due = step.index % max(1, self.config.map_every) == 0
        if due and snapshot.landmark_covs is not None and len(snapshot.landmarks):
            self.columns.add(
                f"world/{name}/landmark_cov", "strips", step, list(ellipses(snapshot.landmarks, snapshot.landmark_covs))
            )

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        """Buffer one step: poses, paths, maps, observation rays, scalars; log its events."""
        add = self.columns.add
        if len(truth.landmarks) != self.truth_landmarks:
            self.truth_landmarks = len(truth.landmarks)
            self._truth_landmarks(truth)
        true_pose = truth.poses.get(step.index)
        if true_pose is not None:
            self._pose("truth", true_pose, step)
        events: list[str] = []
        for name in ONLINE:
            snap = snapshots.get(name)
            if snap is None:
                continue
            self._pose(name, snap.pose, step)
            self._landmarks(name, snap, step)
            if snap.pose_cov is not None and np.all(np.isfinite(snap.pose_cov)):
                add(
                    f"world/{name}/pose_cov",
                    "strips",
                    step,
                    list(ellipses(snap.pose[None, :2], snap.pose_cov[None, :2, :2])),
                )
            if snap.wall_s is not None:
                add(f"metrics/{name}/step_ms", "scalar", step, 1e3 * snap.wall_s)
            events += self._events(name, snap, step)
        current = next((snapshots[n] for n in ("smoother", "ekf", "odometry") if n in snapshots), None)
        rays: list[Array] = []
        if current is not None and len(step.landmarks):
            ends = landmark_from_observation(current.pose[None, :], step.z)
            rays = list(np.stack([np.broadcast_to(current.pose[:2], ends.shape), ends], axis=1))
        add("world/observations", "strips", step, rays)
        if events:
            self._time(step)
            for text in events:
                self.rec.log("events", rr.TextLog(f"step {step.index}: {text}", level="INFO"))
        self._last_step = step
        self._buffered += 1
        now = time.perf_counter()
        live = self.config.connect is not None and now - self._last_flush > 0.25
        if live or self._buffered >= self.config.flush_every:
            self.columns.flush()
            self._last_flush, self._buffered = now, 0

    def _events(self, name: str, snap: Snapshot, step: Step) -> list[str]:
        info, out = snap.info, []
        if name == "ekf":
            nis = np.asarray(info.get("nis", []), dtype=float)
            if np.isfinite(nis).any():
                self.columns.add("metrics/ekf/nis", "scalar", step, float(np.nanmean(nis)))
            if info.get("new_landmarks"):
                out.append(f"ekf: landmarks initialised {', '.join(map(str, info['new_landmarks']))}")
            if info.get("gated"):
                out.append(f"ekf: observations gated (chi-square) of {', '.join(map(str, info['gated']))}")
        if name == "smoother":
            if info.get("window") is not None:
                self.columns.add("world/smoother/window", "points", step, info["window_poses"][:, :2])
            if info.get("relinearized"):
                for key in ("cost_before", "cost_after", "iterations"):
                    self.columns.add(f"metrics/smoother/{key}", "scalar", step, float(info[key]))
                out.append(f"smoother: relinearized, {info['iterations']} iterations")
            if info.get("marginalized"):
                out.append(f"smoother: marginalized poses {', '.join(map(str, info['marginalized']))}")
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
    def on_finish(self, results: Results, truth: GroundTruth) -> None:
        """Send what is buffered, the batch solution at the last step, the summary; close the file."""
        rec = self.rec
        # Errors and NEES as the table computes them (same frame and alignment: known only at the end).
        for name, series in results.series.items():
            for entity, values in (("position_error_m", series.position_error_m), ("nees", series.nees)):
                for index in np.flatnonzero(np.isfinite(values)):
                    self.columns.add_at(
                        f"metrics/{name}/{entity}", "scalar", int(index), float(series.t[index]), float(values[index])
                    )
        self.columns.flush()
        if self._last_step is not None:
            self._time(self._last_step)
        if truth.landmarks:
            self._truth_landmarks(truth)
        batch = results.estimates.get("batch")
        if batch is not None and len(batch.poses):
            rec.log("world/batch/path", rr.LineStrips2D([batch.poses[:, :2]], colors=[COLORS["batch"]]))
            rec.log(
                "world/batch/landmarks",
                rr.Points2D(
                    batch.landmarks,
                    labels=[str(i) for i in batch.landmark_ids],
                    colors=[COLORS["batch"]],
                    radii=[0.08],
                    show_labels=False,
                ),
            )
        if results.error:
            rec.log("events", rr.TextLog(f"input stopped early: {results.error}", level="ERROR"))
        rec.log(
            "summary", rr.TextDocument(json.dumps(results.to_json(), indent=2), media_type="text/plain"), static=True
        )
        try:
            rec.flush()
        except RuntimeError as exc:  # e.g. no viewer at the address: the results must not be lost over it
            where = self.config.connect if self.config.connect != "default" else "the default address"
            self.error = f"rerun: could not deliver the recording to the viewer at {where} ({exc})"
        rec.disconnect()


# -- reading back -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RecordingSummary:
    """What ``online-slam inspect`` reports about a recording."""

    source: str
    """Name of the replayed source."""
    steps: int
    """Number of steps logged."""
    time_span: tuple[float, float]
    """First and last stream time, seconds."""
    estimators: tuple[str, ...]
    """Estimators present in the recording."""
    results: dict[str, Any]
    """The results JSON stored in the recording."""
    latency_ms: dict[str, dict[str, float]]
    """Per online estimator: median / p95 / max step time computed from the logged ``step_ms`` series."""


def check_rrd(path: str | Path, complete: bool = True) -> Path:
    """Raise an :class:`OnlineSlamError` with one clear line unless path is a complete ``.rrd`` file.

    Args:
        path: The file.
        complete: Require the footer a finished recording ends with (``rerun rrd verify`` requires it too);
            False accepts a stream saved by a viewer, which has none.
    """
    p = Path(path)
    if not p.is_file():
        raise OnlineSlamError(f"{p}: no such file")
    data = p.read_bytes()
    if not data.startswith(b"RRF2"):
        raise OnlineSlamError(f"{p}: not a Rerun recording (no RRF2 header)")
    if complete and b"RRF2FOOT" not in data[-64:]:
        raise OnlineSlamError(f"{p}: incomplete Rerun recording: no footer (truncated, or the replay was cut off)")
    return p


def _column(table: Any, suffix: str) -> list[Any]:
    names = [n for n in table.column_names if n.endswith(suffix)]
    return table.column(names[0]).to_pylist() if names else []


def _seconds(value: Any) -> float:
    if hasattr(value, "total_seconds"):
        return float(value.total_seconds())
    if hasattr(value, "timestamp"):
        return float(value.timestamp())
    return float(value) / 1e9


class Recording:
    """A recording opened for queries through Rerun's dataframe API (a local server on the loopback).

    Use as a context manager: ``with Recording(path) as rec: rec.summary(); rec.state_at(10)``.
    """

    def __init__(self, path: str | Path, complete: bool = True) -> None:
        self.path = check_rrd(path, complete)
        self._server: Any = None
        self._dataset: Any = None

    def __enter__(self) -> Recording:
        try:
            self._server = rr.server.Server(host="127.0.0.1", datasets={"run": [str(self.path)]})
            self._dataset = self._server.client().get_dataset("run")
        except Exception as exc:  # noqa: BLE001 - one line for the user whatever rerun raised
            self.__exit__(None, None, None)
            raise OnlineSlamError(f"{self.path}: cannot read the recording ({exc})") from None
        return self

    def __exit__(self, *exc: object) -> None:
        if self._server is not None:
            self._server.__exit__(None, None, None)
            self._server = None

    def _table(self, contents: list[str], index: str | None, **kwargs: Any) -> Any:
        try:
            return self._dataset.filter_contents(contents).reader(index=index, **kwargs).to_arrow_table()
        except Exception as exc:  # noqa: BLE001
            raise OnlineSlamError(f"{self.path}: not an online-slam recording ({exc})") from None

    def summary(self) -> RecordingSummary:
        """Source, steps, time span, estimators, stored results, and latency from the logged series."""
        texts = _column(self._table(["/summary"], None), ":TextDocument:text")
        if not texts:
            raise OnlineSlamError(f"{self.path}: not an online-slam recording (no /summary)")
        results = json.loads(texts[0] if isinstance(texts[0], str) else texts[0][0])
        world = self._table(["/world/**"], "step")
        steps = [v for v in world.column("step").to_pylist() if v is not None]
        seconds = [_seconds(t) for t in world.column("time").to_pylist() if t is not None]
        metrics = self._table(["/metrics/**"], "step")
        latency = {}
        for name in ONLINE:
            values = [v[0] for v in _column(metrics, f"/metrics/{name}/step_ms:Scalars:scalars") if v]
            if values:
                ms = np.array(values, dtype=float)
                latency[name] = {
                    "median": float(np.median(ms)),
                    "p95": float(np.percentile(ms, 95)),
                    "max": float(ms.max()),
                }
        return RecordingSummary(
            source=results.get("source", "?"),
            steps=(max(steps) + 1) if steps else 0,
            time_span=(min(seconds), max(seconds)) if seconds else (math.nan, math.nan),
            estimators=tuple(results.get("estimators", {})),
            results=results,
            latency_ms=latency,
        )

    def metric(self, estimator: str, name: str) -> tuple[list[int], list[float]]:
        """One logged per-step figure (e.g. ``position_error_m``, ``nees``): (steps, values) in step order."""
        entity = f"/metrics/{estimator}/{name}"
        table = self._table([entity], "step")
        values = _column(table, f"{entity}:Scalars:scalars")
        steps = table.column("step").to_pylist() if "step" in table.column_names else []
        pairs = sorted((int(st), float(v[0])) for st, v in zip(steps, values) if st is not None and v)
        return [p[0] for p in pairs], [p[1] for p in pairs]

    def entity_paths(self) -> list[str]:
        """Entity paths that hold data on the ``step`` timeline."""
        names = self._table(["/**"], "step").column_names
        return sorted({n.split(":")[0] for n in names if n.startswith("/")})

    def state_at(self, step: int) -> dict[str, Any]:
        """Per estimator: pose and landmark count at a step (latest values), and that step's events."""
        table = self._table(["/world/**"], "step", fill_latest_at=True, using_index_values=[step])
        state: dict[str, Any] = {"step": step, "estimators": {}}
        for name in (*ONLINE, "truth"):
            origins = _column(table, f"/world/{name}/pose:Arrows2D:origins")
            vectors = _column(table, f"/world/{name}/pose:Arrows2D:vectors")
            if origins and origins[0]:
                (x, y), (vx, vy) = origins[0][0], vectors[0][0]
                landmarks = _column(table, f"/world/{name}/landmarks:Points2D:positions")
                state["estimators"][name] = {
                    "pose": [x, y, math.atan2(vy, vx)],
                    "landmarks": len(landmarks[0]) if landmarks and landmarks[0] else 0,
                }
        events = self._table(["/events"], "step")
        texts = _column(events, ":TextLog:text")
        steps = events.column("step").to_pylist() if "step" in events.column_names else []
        state["events"] = [t[0] if isinstance(t, list) else t for s, t in zip(steps, texts) if s == step and t]
        state["gated"] = [e for e in state["events"] if "gated" in e]
        return state


def blueprint_views(path: str | Path) -> list[tuple[str, str, str]]:
    """The (view class, name, origin) of each view in the recording's blueprint, read through the SDK.

    ``rerun.chunk.RrdReader`` (rerun-sdk 0.41) lists the blueprint stores of an .rrd and streams their chunks; each
    view's ``ViewBlueprint`` components name its class, display name and space origin.
    """
    from rerun.chunk import RrdReader

    p = check_rrd(path)
    views = set()
    try:
        reader = RrdReader(str(p))
        for store in reader.blueprints():
            for chunk in reader.stream(store=store):
                batch = chunk.to_record_batch()
                names = batch.schema.names
                if "ViewBlueprint:class_identifier" not in names:
                    continue
                value = {
                    n.split(":")[1]: batch.column(n).to_pylist()[0] for n in names if n.startswith("ViewBlueprint:")
                }
                first = {k: (v[0] if isinstance(v, list) and v else v) for k, v in value.items()}
                views.add(
                    (str(first.get("class_identifier")), str(first.get("display_name")), str(first.get("space_origin")))
                )
    except Exception as exc:  # noqa: BLE001 - one line for the user whatever rerun raised
        raise OnlineSlamError(f"{p}: cannot read the blueprint ({exc})") from None
    return sorted(views)
