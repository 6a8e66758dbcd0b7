"""Reading a recording back: summary, per-step figures and poses as arrays, state at a step, the blueprint's views.

Through Rerun's dataframe API (a local server on the loopback) and ``rerun.chunk.RrdReader``; the estimators and
their entities come from the layout the writer stored in the summary.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.sinks.recording.layout import TRUTH, Layout

if TYPE_CHECKING:
    import pandas

Array = NDArray[np.float64]


@dataclass(frozen=True)
class RecordingSummary:
    """What ``online-slam inspect`` reports about a recording."""

    source: str
    """Name of the replayed source."""
    robot: int | str | None
    """The robot the stream's header names (e.g. an MRCLAM robot), or None."""
    steps: int
    """Number of steps logged."""
    time_span: tuple[float, float]
    """First and last stream time, seconds."""
    estimators: tuple[str, ...]
    """Estimators present in the recording, in table order."""
    layout: Layout
    """Where each estimator lives in the recording (entities, colours)."""
    results: dict[str, Any]
    """The results JSON stored in the recording."""
    latency_ms: dict[str, dict[str, float]]
    """Per online estimator: median / p95 / max step time computed from the logged ``step_ms`` series."""
    figures: dict[str, dict[str, float]]
    """Per online estimator, recomputed from the logged series: online RMSE (sqrt of the mean squared
    ``position_error_m``) and mean ``nees``, to compare with the stored table."""
    robots: dict[str, str] = field(default_factory=dict)
    """With several robots: each robot's id (as text) -> its entity part (``robot_1``); empty with one."""


@dataclass(frozen=True)
class RecordingSeries:
    """A recording's per-step series as arrays (S steps), for plots and analysis: what ``inspect`` reads."""

    source: str
    """Name of the replayed source."""
    results: dict[str, Any]
    """The results JSON stored in the recording (the table's figures, see ``docs/formats.md``)."""
    step: NDArray[np.int64]
    """Step numbers 0 .. S-1, shape (S,)."""
    t: Array
    """Stream time of each step, seconds, shape (S,)."""
    poses: Mapping[str, Array]
    """Online estimator (dead reckoning ``odometry`` included) or ``truth`` -> its newest pose ``[x, y, theta]``
    at each step (with several robots: the pose of the step's robot), shape (S, 3), as logged (float32
    precision); NaN where none was logged."""
    robot: tuple[str, ...]
    """With several robots: the robot (its id as text) of each step, shape (S,); empty with one."""
    metrics: Mapping[str, Mapping[str, Array]]
    """Online estimator -> figure -> its value at each step, shape (S,), NaN where none was logged. Figures:
    ``position_error_m``, ``nees`` and ``step_ms`` for each, ``nis`` for the EKF, ``cost_before``,
    ``cost_after`` and ``iterations`` for smoothers (the table's figures are computed from the same values)."""

    def to_pandas(self) -> pandas.DataFrame:
        """One row per (estimator, step): columns ``step``, ``t``, (``robot`` with several robots,) ``estimator``,
        ``x``, ``y``, ``theta`` and one per figure (NaN where the estimator has none).

        Raises:
            ImportError: pandas is not installed (online-slam does not need it otherwise).
        """
        try:
            import pandas
        except ImportError:
            raise ImportError("RecordingSeries.to_pandas needs pandas, which online-slam does not install: "
                              "pip install pandas") from None  # fmt: skip
        figures = sorted({figure for values in self.metrics.values() for figure in values})
        missing = np.full(len(self.step), np.nan)
        frames = []
        for name in dict.fromkeys([*self.poses, *self.metrics]):
            pose = self.poses.get(name, np.full((len(self.step), 3), np.nan))
            columns = {"step": self.step, "t": self.t, **({"robot": list(self.robot)} if self.robot else {})}
            columns |= {"estimator": name, "x": pose[:, 0], "y": pose[:, 1]}
            columns["theta"] = pose[:, 2]
            values = self.metrics.get(name, {})
            columns.update({figure: values.get(figure, missing) for figure in figures})
            frames.append(pandas.DataFrame(columns))
        return pandas.concat(frames, ignore_index=True)


def read_recording(path: str | Path) -> RecordingSeries:
    """Load a recording written by ``online-slam replay --rrd`` or ``compare --rrd`` into arrays.

    It is read as ``online-slam inspect`` reads it (Rerun's query API, a local server on the loopback), nothing is
    re-run. ``read_recording("run.rrd").to_pandas()`` gives a DataFrame.

    Raises:
        OnlineSlamError: No such file, not a (complete) Rerun recording, or not one written by online-slam.
    """
    with Recording(path) as recording:
        return recording.series()


def _steps(table: Any, count: int) -> list[tuple[int, int]]:
    """(row, step) of every row on the step timeline."""
    steps = table.column("step").to_pylist() if "step" in table.column_names else []
    return [(row, step) for row, step in enumerate(steps) if step is not None and 0 <= step < count]


def _merged(found: list[Array | None]) -> Array | None:
    """One pose per step from the poses logged under each robot's entity (a step logs its robot's), or None."""
    logged = [poses for poses in found if poses is not None]
    if not logged:
        return None
    merged = logged[0]
    for poses in logged[1:]:
        merged = np.where(np.isnan(merged), poses, merged)
    return merged


def _step_robots(found: list[Array | None], robots: list[str], count: int) -> tuple[str, ...]:
    """The robot of each step, from which robot's entity logged a pose at it (``found``: per robot, in the order
    of ``robots``); () with one robot."""
    if len(robots) < 2:
        return ()
    out = np.full(count, "", dtype=object)
    for robot, poses in zip(robots, found):
        if poses is not None:
            out[np.isfinite(poses[:, 0])] = robot
    return tuple(out.tolist())


def _poses(table: Any, root: str, rows: list[tuple[int, int]], count: int) -> Array | None:
    """An entity's logged pose arrows as ``[x, y, theta]`` per step (None when it logged none)."""
    origins = _column(table, f"{root}/pose:Arrows2D:origins")
    vectors = _column(table, f"{root}/pose:Arrows2D:vectors")
    poses = np.full((count, 3), np.nan)
    found = False
    for row, step in rows:
        if origins[row] and vectors[row]:
            (x, y), (vx, vy) = origins[row][0], vectors[row][0]
            poses[step] = (x, y, math.atan2(vy, vx))
            found = True
    return poses if found else None


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


def _scalars(table: Any, entity: str) -> list[float]:
    """The logged values of one scalar entity (rows without one left out)."""
    return [v[0] for v in _column(table, f"{entity}:Scalars:scalars") if v]


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
        estimators = tuple(results.get("estimators", {}))
        layout = Layout.from_json(results.get("recording"), list(estimators))
        metrics = self._table(["/metrics/**"], "step")
        latency, figures = {}, {}
        for name in layout.online:
            root = f"/{layout.metrics(name)}"
            values = _scalars(metrics, f"{root}/step_ms")
            if values:
                ms = np.array(values, dtype=float)
                latency[name] = {
                    "median": float(np.median(ms)),
                    "p95": float(np.percentile(ms, 95)),
                    "max": float(ms.max()),
                }
            errors = np.array(_scalars(metrics, f"{root}/position_error_m"))
            nees = np.array(_scalars(metrics, f"{root}/nees"))
            if errors.size:
                figures[name] = {
                    "online_rmse_m": float(np.sqrt(np.mean(np.square(errors)))),
                    "nees_mean": float(np.mean(nees)) if nees.size else math.nan,
                }
        robots = (results.get("recording") or {}).get("robots", {})
        return RecordingSummary(
            source=results.get("source", "?"),
            robot=results.get("robot"),
            steps=(max(steps) + 1) if steps else 0,
            time_span=(min(seconds), max(seconds)) if seconds else (math.nan, math.nan),
            estimators=estimators,
            layout=layout,
            results=results,
            latency_ms=latency,
            figures=figures,
            robots={robot: value["entity"] for robot, value in robots.items()},
        )

    def series(self) -> RecordingSeries:
        """Every estimator's (and the truth's) pose and logged figures at every step (see :func:`read_recording`)."""
        summary = self.summary()
        layout, count = summary.layout, summary.steps
        parts = [f"/{part}" for part in summary.robots.values()] or [""]
        bases = {name: f"/{layout.world(name)}" for name in layout.online} | {TRUTH: "/world/truth"}
        roots = {name: [base + part for part in parts] for name, base in bases.items()}
        table = self._table([f"{root}/pose" for each in roots.values() for root in each], "step")
        rows = _steps(table, count)
        times = table.column("time").to_pylist()
        t = np.full(count, np.nan)
        for row, step in rows:
            t[step] = _seconds(times[row])
        found = {name: [_poses(table, root, rows, count) for root in each] for name, each in roots.items()}
        poses = {name: _merged(each) for name, each in found.items()}
        robot = _step_robots(found[next(iter(bases))], list(summary.robots), count)
        metrics_table = self._table(["/metrics/**"], "step")
        metric_rows = _steps(metrics_table, count)
        metrics: dict[str, dict[str, Array]] = {}
        for name in layout.online:
            root = f"/{layout.metrics(name)}/"
            for column in metrics_table.column_names:
                if column.startswith(root) and column.endswith(":Scalars:scalars"):
                    values, at_steps = metrics_table.column(column).to_pylist(), np.full(count, np.nan)
                    for row, step in metric_rows:
                        if values[row]:
                            at_steps[step] = values[row][0]
                    metrics.setdefault(name, {})[column[len(root) :].split(":")[0]] = at_steps
        return RecordingSeries(
            source=summary.source,
            results=summary.results,
            step=np.arange(count),
            t=t,
            poses={name: value for name, value in poses.items() if value is not None},
            robot=robot,
            metrics=metrics,
        )

    def metric(self, estimator: str, name: str, layout: Layout | None = None) -> tuple[list[int], list[float]]:
        """One logged per-step figure (e.g. ``position_error_m``, ``nees``): (steps, values) in step order.

        Args:
            estimator: Its name (as in the table).
            name: The figure.
            layout: The recording's layout (default: read from its summary).
        """
        layout = layout or self.summary().layout
        entity = f"/{layout.metrics(estimator)}/{name}"
        table = self._table([entity], "step")
        values = _column(table, f"{entity}:Scalars:scalars")
        steps = table.column("step").to_pylist() if "step" in table.column_names else []
        pairs = sorted((int(st), float(v[0])) for st, v in zip(steps, values) if st is not None and v)
        return [p[0] for p in pairs], [p[1] for p in pairs]

    def entity_paths(self) -> list[str]:
        """Entity paths that hold data on the ``step`` timeline."""
        names = self._table(["/**"], "step").column_names
        return sorted({n.split(":")[0] for n in names if n.startswith("/")})

    def state_at(
        self, step: int, layout: Layout | None = None, robots: Mapping[str, str] | None = None
    ) -> dict[str, Any]:
        """Per estimator: pose and landmark count at a step (latest values); the step's time and events.

        With several robots (``robots``: id -> entity part, default the summary's) an estimator has one entry
        per robot, ``<estimator> robot <id>``, each with that robot's latest pose and the estimator's map.
        """
        if layout is None or robots is None:
            summary = self.summary()
            layout, robots = layout or summary.layout, summary.robots if robots is None else robots
        table = self._table(["/world/**"], "step", fill_latest_at=True, using_index_values=[step])
        times = [t for t in table.column("time").to_pylist() if t is not None] if "time" in table.column_names else []
        state: dict[str, Any] = {"step": step, "t": _seconds(times[0]) if times else None, "estimators": {}}
        parts = {f" robot {robot}": f"/{part}" for robot, part in robots.items()} or {"": ""}
        for name in (*layout.online, TRUTH):
            root = "/world/truth" if name == TRUTH else f"/{layout.world(name)}"
            landmarks = _column(table, f"{root}/landmarks:Points2D:positions")
            for suffix, part in parts.items():
                origins = _column(table, f"{root}{part}/pose:Arrows2D:origins")
                vectors = _column(table, f"{root}{part}/pose:Arrows2D:vectors")
                if origins and origins[0]:
                    (x, y), (vx, vy) = origins[0][0], vectors[0][0]
                    state["estimators"][name + suffix] = {
                        "pose": [x, y, math.atan2(vy, vx)],
                        "landmarks": len(landmarks[0]) if landmarks and landmarks[0] else 0,
                    }
        events = self._table(["/events"], "step")
        texts = _column(events, ":TextLog:text")
        steps = events.column("step").to_pylist() if "step" in events.column_names else []
        rows = [t for s, t in zip(steps, texts) if s == step and t]  # a row holds that step's lines
        state["events"] = [text for row in rows for text in (row if isinstance(row, list) else [row])]
        state["gated"] = [e for e in state["events"] if "gated" in e]
        return state


@dataclass(frozen=True)
class BlueprintView:
    """One view of a recording's blueprint."""

    kind: str
    """View class (``2D``, ``TimeSeries``, ``TextLog`` ...)."""
    name: str
    """Display name."""
    origin: str
    """Space origin."""
    contents: tuple[str, ...]
    """Its entity query expressions."""


def blueprint_views(path: str | Path) -> list[BlueprintView]:
    """The views of the recording's blueprint, read through the SDK.

    ``rerun.chunk.RrdReader`` (rerun-sdk 0.41) lists the blueprint stores of an .rrd and streams their chunks; a
    view's ``ViewBlueprint`` components (at ``/view/<id>``) name its class, display name and space origin, and its
    ``ViewContents`` (at ``/view/<id>/ViewContents``) hold its entity query.
    """
    from rerun.chunk import RrdReader

    p = check_rrd(path)
    heads: dict[str, dict[str, Any]] = {}
    queries: dict[str, tuple[str, ...]] = {}
    try:
        reader = RrdReader(str(p))
        for store in reader.blueprints():
            for chunk in reader.stream(store=store):
                batch = chunk.to_record_batch()
                names = batch.schema.names
                entity = str(chunk.entity_path)
                if "ViewContents:query" in names:
                    query = batch.column("ViewContents:query").to_pylist()[0] or []
                    queries[entity.removesuffix("/ViewContents")] = tuple(map(str, query))
                if "ViewBlueprint:class_identifier" in names:
                    value = {
                        n.split(":")[1]: batch.column(n).to_pylist()[0] for n in names if n.startswith("ViewBlueprint:")
                    }
                    heads[entity] = {k: (v[0] if isinstance(v, list) and v else v) for k, v in value.items()}
    except Exception as exc:  # noqa: BLE001 - one line for the user whatever rerun raised
        raise OnlineSlamError(f"{p}: cannot read the blueprint ({exc})") from None
    views = [
        BlueprintView(
            str(head.get("class_identifier")),
            str(head.get("display_name")),
            str(head.get("space_origin")),
            queries.get(entity, ()),
        )
        for entity, head in heads.items()
    ]
    return sorted(views, key=lambda v: (v.kind, v.name))
