"""Sweeps on Dask: rows equal replay's, on a local cluster and on a real scheduler with two workers; resume."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from inprocess import run_cli

pytest.importorskip("distributed", reason="dask[distributed] is not installed")

from conftest import stop_marked_processes  # noqa: E402

from online_slam.faults import CRASH_VARIABLE  # noqa: E402
from online_slam.options import flag  # noqa: E402
from online_slam.sources.worlds import WORLDS  # noqa: E402
from online_slam.sweep import FIGURES, make_cells, run_cell, sweep  # noqa: E402

EXE = [shutil.which("online-slam")] if shutil.which("online-slam") else [sys.executable, "-m", "online_slam"]
DETERMINISTIC = [f for f in FIGURES if f not in ("step_median_ms", "step_p95_ms", "total_s")]


def by_key(rows: list[dict]) -> dict:
    return {(r["cell"], r["estimator"]): r for r in rows}


def assert_same(a: list[dict], b: list[dict]) -> None:
    a, b = by_key(a), by_key(b)
    assert a.keys() == b.keys()
    for key in a:
        for f in DETERMINISTIC:
            x, y = a[key][f], b[key][f]
            assert (x is None and y is None) or abs(x - y) <= 1e-9, (key, f, x, y)


@pytest.fixture(scope="module")
def cells() -> list:
    return make_cells(["square"], {"window": (5, 10), "robust": ("auto", "none")}, runs=2)


@pytest.fixture(scope="module")
def local_rows(cells) -> list[dict]:
    return sweep(cells, workers=2).rows


def replayed(*args: str) -> dict:
    """``online-slam replay ARGS --json -``: the figures replay prints for these options."""
    done = run_cli("replay", *args, "--json", "-", "--quiet")
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)["estimators"]


def assert_row_is_replay(rows: list[dict], cell, reference: dict) -> None:
    """Every deterministic figure of the cell's rows equals replay's, to the last digit."""
    assert {r["estimator"] for r in rows if r["cell"] == cell.key} == set(reference)
    for name, figures in reference.items():
        row = by_key(rows)[(cell.key, name)]
        for f in DETERMINISTIC:
            assert row[f] == figures.get(f), (name, f)


@pytest.mark.slow
def test_local_sweep_rows_equal_replay(cells, local_rows) -> None:
    assert len(cells) == 8 and len(local_rows) == 8 * 3
    assert {dict(c.settings)["window"] for c in cells} == {5, 10} and local_rows[0]["window_distance"] == 18.0
    for cell in [c for c in cells if c.seed == WORLDS["square"].seed]:  # the world replay runs by name
        flags = [text for name, value in cell.settings for text in (flag(name), str(value))]
        assert_row_is_replay(local_rows, cell, replayed("square", *flags))


@pytest.mark.slow
def test_a_sweep_cell_gives_replays_figures_with_huber() -> None:
    """A sweep's outlier setting is replay's (a sweep once used another Huber threshold than replay's)."""
    for settings, flags in (({"robust": ("huber",)}, ()), ({"robust": ("cauchy",), "robust_scale": (2.5,)},
                                                            ("--robust-scale", "2.5"))):  # fmt: skip
        (cell,) = make_cells(["square"], {**settings, "window": (8,)})
        reference = replayed("square", "--robust", settings["robust"][0], "--window", "8", *flags)
        assert_row_is_replay(run_cell(cell), cell, reference)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_a_real_scheduler_with_two_workers_gives_the_local_rows(cells, local_rows, processes, tmp_path) -> None:
    dask = shutil.which("dask")
    if dask is None:
        pytest.skip("the dask command is not installed")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    processes([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"], **quiet)
    processes(
        [dask, "worker", address, "--nworkers", "2", "--nthreads", "1", "--no-dashboard", "--local-directory",
         str(tmp_path)], **quiet,
    )  # fmt: skip
    from distributed import Client

    deadline = time.monotonic() + 60
    while True:  # wait for both workers
        try:
            with Client(address, timeout="2s") as client:
                if len(client.scheduler_info()["workers"]) >= 2:
                    break
        except OSError:
            pass
        assert time.monotonic() < deadline, "the Dask workers did not come up"
        time.sleep(0.5)
    out = tmp_path / "cluster.csv"
    done = subprocess.run(
        [*EXE, "sweep", "square", "--window", "5,10", "--robust", "auto,none", "--runs", "2", "--scheduler", address,
         "--output", str(out)], capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "8 replays: 8 computed" in done.stdout
    from online_slam.sweep import read_rows

    assert_same(read_rows(out), local_rows)


@pytest.mark.slow
def test_a_killed_sweep_resumes_without_computing_a_cell_twice(cells, local_rows, processes, tmp_path) -> None:
    out = tmp_path / "sweep.csv"
    command = [*EXE, "sweep", "square", "--window", "5,10", "--robust", "auto,none", "--runs", "2", "--workers", "1",
               "--output", str(out), "--quiet"]  # fmt: skip
    first = processes(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                      env={**os.environ, CRASH_VARIABLE: "cells:3"})  # fmt: skip
    assert first.wait(timeout=300) == -signal.SIGKILL  # killed once 3 of 8 cells are written
    stop_marked_processes()  # its Dask worker, orphaned
    with out.open() as handle:
        kept = {row["cell"] for row in csv.DictReader(handle)}
    assert len(kept) == 3
    again = subprocess.run([c for c in command if c != "--quiet"], capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert "8 replays: 5 computed, 3 already in the output" in again.stdout
    from online_slam.sweep import read_rows

    rows = read_rows(out)
    assert len(rows) == len(by_key(rows)) == 24  # no cell twice
    assert_same(rows, local_rows)


@pytest.mark.slow
def test_a_failing_cell_is_a_row_not_a_dead_sweep(tmp_path: Path) -> None:
    missing = str(tmp_path / "missing.jsonl")
    report = sweep(make_cells(["square", missing], {"gate_probability": (0.999,)}, estimators=("ekf",)), workers=1)
    errors = [r for r in report.rows if r["error"]]
    assert report.failed == 1 and len(errors) == 1 and "no such file" in errors[0]["error"]
    assert any(r["estimator"] == "ekf" and r["final_rmse_m"] is not None for r in report.rows)


@pytest.mark.slow
def test_parquet_output_round_trips_and_resumes(cells, local_rows, tmp_path: Path) -> None:
    from online_slam.sweep import read_rows

    out = tmp_path / "rows.parquet"
    first = sweep(cells[:2], out=out, workers=1)
    again = sweep(cells[:3], out=out, workers=1)
    assert first.computed == 2 and again.computed == 1 and again.skipped == 2
    rows = read_rows(out)
    assert len(rows) == 9
    assert_same(rows, [r for r in local_rows if r["cell"] in {c.key for c in cells[:3]}])


def test_a_yes_no_option_sweeps_its_values(tmp_path: Path) -> None:
    """``--adapt-noise`` in a sweep was a bare flag that could only say yes (the default): it takes values now."""
    out = tmp_path / "s.csv"
    done = run_cli("sweep", "square", "--estimators", "ekf", "--workers", "1", "--adapt-noise", "true,false",
                   "-o", str(out), "--quiet")  # fmt: skip
    assert done.returncode == 0, done.stderr
    with out.open(newline="") as f:
        assert sorted(row["adapt_noise"] for row in csv.DictReader(f)) == ["False", "True"]
    refused = run_cli("sweep", "square", "--adapt-noise", "maybe", "-o", str(out))
    assert refused.returncode == 2 and "expected comma-separated true or false, got 'maybe'" in refused.stderr
