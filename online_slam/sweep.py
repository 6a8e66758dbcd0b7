"""Sweeps: the cartesian product of sources, settings and noise seeds, one replay per cell, on Dask.

A cell is one replay (a source, a combination of estimator options and, for built-in worlds, a seed), its options
translated exactly as ``replay`` translates its flags; it gives one tidy row per estimator, holding every estimator
option's value; on a stream of several robots each estimator also has a row per robot, its ``estimator`` named
``<estimator> robot <id>`` (the replay table's figures of that robot). Cells run as tasks of a
``dask.distributed`` cluster: a ``LocalCluster`` on this machine's cores by default, or an existing scheduler
(``tcp://host:port``) whose workers run this package. Rows are written to the output file as each cell finishes,
so a sweep that is stopped and started again with the same output skips the cells already there. A cell that
fails is a row with its error, not a dead sweep. Replays are deterministic: the same cell gives the same figures
(timings aside) wherever it runs.
"""

from __future__ import annotations

import csv
import hashlib
import itertools
import json
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from online_slam.errors import ConfigError, OnlineSlamError
from online_slam.faults import crash_point
from online_slam.importers import registry
from online_slam.options import OPTIONS, check_value, estimator_options, flag, replay_config
from online_slam.pipeline import ESTIMATORS, ReplayConfig
from online_slam.sources.worlds import WORLDS

FIGURES = (
    "online_rmse_m",
    "final_rmse_m",
    "landmark_rmse_m",
    "endpoint_gap_m",
    "nees_mean",
    "step_median_ms",
    "step_p95_ms",
    "total_s",
)
"""Figures of a row: fields of :class:`~online_slam.evaluation.results.Row` (floats; empty where an estimator has
none)."""
SETTINGS = tuple(estimator_options())
"""Settings a sweep varies: the estimator options (each row holds every one's value, given or default)."""
COLUMNS = ("cell", "source", "robot", "seed", *SETTINGS, "estimator", *FIGURES, "error")
"""Columns of the tidy output, in order."""


@dataclass(frozen=True)
class Cell:
    """One replay of a sweep."""

    source: str
    """A built-in world, a stream file, or a dataset path."""
    estimators: tuple[str, ...]
    """Estimators to run."""
    settings: tuple[tuple[str, Any], ...] = ()
    """Estimator options given for this cell as (name, value), in table order; the others keep their defaults."""
    seed: int | None = None
    """Noise seed of a simulated world (None for files and datasets)."""
    robot: int | str | None = None
    """MRCLAM robot, or ``all`` (None otherwise)."""

    @property
    def values(self) -> dict[str, Any]:
        """Every estimator option's value in this cell (given or default), as the row records it."""
        given = dict(self.settings)
        return {name: given.get(name, option.value) for name, option in estimator_options().items()}

    def config(self) -> ReplayConfig:
        """The replay configuration of this cell: its settings translated as ``replay`` translates its flags."""
        values = {**dict(self.settings), "estimators": ",".join(self.estimators), "robot": self.robot}
        return replay_config(values)

    @property
    def key(self) -> str:
        """A stable identifier of the cell (same source and settings, defaults included: same key, anywhere)."""
        cell = {"source": self.source, "estimators": self.estimators, "seed": self.seed, "robot": self.robot}
        text = json.dumps({**cell, "options": self.values}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def make_cells(
    sources: Sequence[str],
    settings: Mapping[str, Sequence[Any]] | None = None,
    estimators: Sequence[str] = ESTIMATORS,
    runs: int = 1,
    robots: Sequence[int | str] = (),
) -> list[Cell]:
    """The cartesian product of sources (x robots for MRCLAM folders, x seeds for built-in worlds) and settings.

    Args:
        sources: Built-in worlds, stream files, dataset paths.
        settings: Values to try per estimator option (e.g. ``{"window": (5, 20), "robust": ("huber",)}``).
        estimators: Estimators each replay runs.
        runs: Noise seeds per built-in world (its base seed and the next ones).
        robots: MRCLAM robots (required for MRCLAM folders).

    Raises:
        ConfigError: An unknown option or a value out of range (told before anything runs).
    """
    if runs < 1:
        raise OnlineSlamError("sweep: --runs must be >= 1")
    combos = _combinations(settings or {})
    cells = []
    for source in sources:
        is_world = source in WORLDS and not Path(source).exists()
        seeds: list[int | None] = [WORLDS[source].seed + k for k in range(runs)] if is_world else [None]
        kind = None if is_world else registry.detect(source)
        needs_robot = (
            kind is not None and "robot" in registry.takes(kind) and registry.fields(kind)["robot"].metadata["required"]
        )
        robot_list: list[int | str | None] = list(robots) if needs_robot else [None]
        if needs_robot and not robots:
            raise OnlineSlamError(f"sweep: {source} is {kind} data; give --robot 1,2,...")
        for robot, seed, combo in itertools.product(robot_list, seeds, combos):
            cells.append(Cell(source, tuple(estimators), combo, seed, robot))
    return cells


def _combinations(settings: Mapping[str, Sequence[Any]]) -> list[tuple[tuple[str, Any], ...]]:
    """Every combination of the settings' values, each checked by translating it once."""
    options = estimator_options()
    for name, values in settings.items():
        if name not in options:
            raise ConfigError(f"sweep: {name!r} is no estimator option; options: {', '.join(options)}")
        for value in values:
            check_value(options[name], value)
    names = [n for n in options if n in settings]
    combos = [tuple(zip(names, chosen)) for chosen in itertools.product(*(settings[n] for n in names))]
    for combo in combos:
        replay_config(dict(combo), naming=flag)
    return combos


def run_cell(cell: Cell) -> list[dict[str, Any]]:
    """Replay one cell, with the options translated as ``replay`` translates them; one row per estimator (or
    one row holding the error)."""
    from online_slam.pipeline import replay

    head = {"cell": cell.key, "source": cell.source, "robot": cell.robot, "seed": cell.seed, **cell.values}
    try:
        config = cell.config()
        if cell.seed is not None:
            results = replay(WORLDS[cell.source].events(cell.seed), config, name=cell.source, validate=False)
        else:
            results = replay(cell.source, config)
    except Exception as exc:  # noqa: BLE001 - a failing cell is a row with its error, whatever it raised
        return [{**head, "estimator": "", **{f: None for f in FIGURES}, "error": f"{type(exc).__name__}: {exc}"}]
    rows = results.rows()
    out = []
    for name, result in results.estimators.items():  # dead reckoning's is left out: no setting changes it
        named = {name: rows[name], **{f"{name} robot {r}": figures.row() for r, figures in result.robots.items()}}
        out += [
            {**head, "estimator": n, **{f: getattr(row, f) for f in FIGURES}, "error": ""} for n, row in named.items()
        ]
    return out


# -- output -----------------------------------------------------------------------------------------------
def _value(text: str, column: str) -> Any:
    """A CSV cell as the row held it."""
    if text == "":
        return None if column != "error" else ""
    if column == "robot":  # an MRCLAM robot's number, or all
        return int(text) if text.isdigit() else text
    kind: type | None = float if column in FIGURES else int if column == "seed" else None
    option = OPTIONS.get(column)
    kind = option.kind if option is not None and column in SETTINGS else kind
    if kind is bool:
        return text == "True"
    return kind(text) if kind is not None else text


def read_rows(path: str | Path) -> list[dict[str, Any]]:
    """Rows already in an output file (CSV or Parquet); [] when it does not exist."""
    p = Path(path)
    if not p.exists():
        return []
    try:
        if p.suffix == ".parquet":
            import pandas as pd

            frame = pd.read_parquet(p)
            return [{c: (None if isinstance(v, float) and math.isnan(v) and c != "error" else v)
                     for c, v in row.items()} for row in frame.to_dict("records")]  # fmt: skip
        with p.open(newline="", encoding="utf-8") as handle:
            return [{c: _value(row.get(c, ""), c) for c in COLUMNS} for row in csv.DictReader(handle)]
    except (OSError, ValueError, KeyError) as exc:
        raise OnlineSlamError(f"{p}: cannot read the sweep's rows ({exc})") from None


def _append(path: Path, rows: list[dict[str, Any]], every_row: list[dict[str, Any]]) -> None:
    """Add one cell's rows to the output as soon as they exist (CSV: appended; Parquet: rewritten)."""
    if path.suffix == ".parquet":
        import pandas as pd

        pd.DataFrame(every_row, columns=list(COLUMNS)).to_parquet(path.with_suffix(".tmp"), index=False)
        os.replace(path.with_suffix(".tmp"), path)
        return
    new = not path.exists() or path.stat().st_size == 0
    with path.open("a", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(COLUMNS))
        if new:
            writer.writeheader()
        for row in rows:
            writer.writerow({c: ("" if row.get(c) is None else row.get(c)) for c in COLUMNS})
        handle.flush()
        os.fsync(handle.fileno())


@dataclass(frozen=True)
class SweepReport:
    """What a sweep did."""

    rows: list[dict[str, Any]]
    """Every row of the output (earlier runs' included), in cell order."""
    computed: int
    """Cells computed by this run."""
    skipped: int
    """Cells found already done in the output."""
    failed: int
    """Cells whose row holds an error."""


def sweep(
    cells: Sequence[Cell],
    out: str | Path | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> SweepReport:
    """Run the cells on Dask; write rows to ``out`` as cells finish; skip cells ``out`` already holds.

    Args:
        cells: The cells.
        out: Output file (``.csv`` or ``.parquet``), or None to keep the rows in memory only.
        scheduler: Address of a running Dask scheduler; None starts a ``LocalCluster`` (one process per worker).
        workers: Workers of the local cluster (default: the machine's cores).
        progress: Called with (cells done, cells in all) after each cell.
    """
    import dask
    from distributed import Client, LocalCluster, as_completed

    path = Path(out) if out is not None else None
    if path is not None and path.suffix not in (".csv", ".parquet"):
        raise OnlineSlamError(f"--output: expected a .csv or .parquet file, got {path.name}")
    earlier = read_rows(path) if path is not None else []
    done = {row["cell"] for row in earlier}
    todo = [c for c in cells if c.key not in done]
    rows = list(earlier)
    total, finished = len(cells), len(cells) - len(todo)
    if progress is not None:
        progress(finished, total)
    if todo:
        cluster = None
        try:
            if scheduler is None:
                n = workers or os.cpu_count() or 1
                # one BLAS thread per worker process: n workers share the cores instead of oversubscribing them
                single = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
                saved = {k: os.environ.get(k) for k in single}
                os.environ.update(single)
                try:
                    # the workers' statistical profiler samples the running task's stack 100 times a second; our
                    # tasks are pure Python, and it about doubled their time
                    with dask.config.set({"distributed.worker.profile.enabled": False}):
                        cluster = LocalCluster(
                            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
                        )
                finally:
                    for k, v in saved.items():
                        if v is None:
                            os.environ.pop(k, None)
                        else:
                            os.environ[k] = v
                client = Client(cluster)
            else:
                client = Client(scheduler, timeout="10s")
        except OSError as exc:
            raise OnlineSlamError(f"sweep: cannot reach the Dask scheduler at {scheduler} ({exc})") from None
        try:
            futures = [client.submit(run_cell, cell, key=f"cell-{cell.key}", pure=False) for cell in todo]
            for _, cell_rows in as_completed(futures, with_results=True):
                rows.extend(cell_rows)
                if path is not None:
                    _append(path, cell_rows, rows)
                finished += 1
                crash_point("cells", finished - (total - len(todo)))
                if progress is not None:
                    progress(finished, total)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    order = {c.key: k for k, c in enumerate(cells)}
    rows.sort(key=lambda r: (order.get(r["cell"], len(order)), r["estimator"]))
    failed = len({r["cell"] for r in rows if r["error"]})
    return SweepReport(rows, len(todo), total - len(todo), failed)


def summary(rows: Iterable[dict[str, Any]]) -> list[tuple[tuple, dict[str, tuple[float, float, int]]]]:
    """Mean and standard deviation of each figure per (source, robot, settings, estimator), over seeds.

    ``settings`` holds (name, value) of the options whose value differs between the rows (the rest are equal).
    """
    good = [row for row in rows if not row["error"]]
    varying = [name for name in SETTINGS if len({repr(row.get(name)) for row in good}) > 1]
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for row in good:
        settings = tuple((name, row.get(name)) for name in varying)
        groups.setdefault((row["source"], row["robot"], settings, row["estimator"]), []).append(row)
    out = []
    for key, members in groups.items():
        figures = {}
        for f in FIGURES:
            values = np.array([m[f] for m in members if m[f] is not None], dtype=float)
            if len(values):
                std = float(values.std(ddof=1)) if len(values) > 1 else 0.0
                figures[f] = (float(values.mean()), std, len(values))
        out.append((key, figures))
    return out
