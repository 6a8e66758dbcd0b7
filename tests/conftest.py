"""Shared test helpers: numerical Jacobians and the shared data folder."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from online_slam.factors.graph import FactorGraph, evaluate
from online_slam.geometry import wrap

if os.environ.get("PYTEST_XDIST_WORKER"):
    # As many workers as cores: each worker's BLAS on one thread, and the processes its tests start (OpenBLAS's
    # threads spin while they wait: two per worker on two cores, test_circle_smoother and test_outlier_worlds took
    # 67 s, on one 57 s). The estimators hold it to one thread anyway while they work.
    threadpool_limits(limits=1, user_api="blas")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

DATA_VARIABLE = "ONLINE_SLAM_DATA"
REPLAY = Path(__file__).resolve().parents[1] / "replay"
"""The streams shipped with the project (replay/)."""
SHARED_DATA = Path(os.environ.get(DATA_VARIABLE) or Path(__file__).resolve().parents[2] / "shared" / "data")
"""The real datasets: ``$ONLINE_SLAM_DATA``, by default ``../shared/data`` beside the repository."""
REAL_DATA_SKIP = "real data: "


@pytest.fixture
def mrclam_head(tmp_path: Path) -> Path:
    """The first 120 lines of replay/'s MRCLAM robot-1 stream as a file: a short stream whose header names the
    robot."""
    import gzip
    import itertools

    head = tmp_path / "head.jsonl"
    with gzip.open(Path(__file__).resolve().parents[1] / "replay" / "mrclam6_robot1.jsonl.gz", "rt") as lines:
        head.write_text("".join(itertools.islice(lines, 120)), encoding="utf-8")
    return head


def needs_data(relative: str) -> pytest.MarkDecorator:
    """Skip a test when the real dataset ``relative`` (a folder or file under :data:`SHARED_DATA`) is absent."""
    return pytest.mark.skipif(
        not (SHARED_DATA / relative).exists(),
        reason=f"{REAL_DATA_SKIP}{relative} is not in {SHARED_DATA} (set {DATA_VARIABLE})",
    )


def assert_close(a: object, b: object, rtol: float = 1e-12, where: str = "") -> None:
    """a equals b with floats (anywhere in dataclasses, dicts, sequences, arrays) equal to ``rtol``.

    For what one CPU computes and another recomputes: ``np.sin``, ``exp`` and BLAS kernels differ in the last
    bits between CPUs, so values written on one machine are compared to a fresh computation with a tolerance.
    """
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), f"{where}: {type(a).__name__} != {type(b).__name__}"
        for f in dataclasses.fields(a):
            assert_close(getattr(a, f.name), getattr(b, f.name), rtol, f"{where}.{f.name}")
    elif isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f"{where}: keys {sorted(a)} != {sorted(b)}"
        for k in a:
            assert_close(a[k], b[k], rtol, f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple, np.ndarray)) and not isinstance(a, str):
        assert len(a) == len(b), f"{where}: length {len(a)} != {len(b)}"
        for k, (x, y) in enumerate(zip(a, b)):
            assert_close(x, y, rtol, f"{where}[{k}]")
    elif isinstance(a, (float, np.floating)) and not isinstance(b, bool):
        assert isinstance(b, (float, int, np.floating)), f"{where}: {a!r} != {b!r}"
        assert math.isclose(a, b, rel_tol=rtol, abs_tol=rtol) or (math.isnan(a) and math.isnan(b)), (
            f"{where}: {a!r} != {b!r}"
        )
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def numerical_graph_jacobian(
    graph: FactorGraph, poses: np.ndarray, landmarks: np.ndarray, eps: float = 1e-6
) -> np.ndarray:
    """Forward-difference Jacobian of a factor graph's whitened residuals over its free variables: every pose but
    the first (held fixed), then every landmark."""
    r = evaluate(graph, poses, landmarks)
    n = 3 * (len(poses) - 1) + landmarks.size
    numerical = np.zeros((len(r), n))
    for c in range(n):
        dx = np.zeros(n)
        dx[c] = eps
        p, l = poses.copy(), landmarks.copy()
        p[1:] += dx[: 3 * (len(poses) - 1)].reshape(-1, 3)
        l += dx[3 * (len(poses) - 1) :].reshape(-1, 2)
        numerical[:, c] = (evaluate(graph, p, l) - r) / eps
    return numerical


def numerical_jacobian(
    f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, angle_outputs: tuple[int, ...] = (), eps: float = 1e-6
) -> np.ndarray:
    """Central-difference Jacobian of f at x; angle outputs are differenced through wrap()."""
    x = np.asarray(x, dtype=float)
    columns = []
    for k in range(x.size):
        step = np.zeros_like(x)
        step.flat[k] = eps
        diff = np.asarray(f(x + step)) - np.asarray(f(x - step))
        for i in angle_outputs:
            diff[..., i] = wrap(diff[..., i])
        columns.append(diff / (2 * eps))
    return np.stack(columns, axis=-1)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


# Heaviest modules first (measured seconds per module, largest first): `--dist loadfile` hands whole modules to the
# two workers in collection order as they free up (with `--no-loadscope-reorder`, see pyproject.toml: by default
# pytest-xdist 3.8 reorders modules by their number of tests, which put the 156 s MRCLAM module last), so long
# modules collected last would leave one worker running alone at the end.
HEAVY_FIRST = (
    "test_real_datasets.py", "test_smoother.py", "test_circle_smoother.py", "test_outlier_worlds.py",
    "test_importers.py", "test_unknown_association.py", "test_adaptation.py", "test_circle.py",
    "test_position_sightings.py", "test_cli.py", "test_outliers.py", "test_robots.py", "test_noise_self.py",
    "test_checkpoint.py", "test_sweep.py", "test_web_viewer.py", "test_slam_api.py", "test_compare.py",
    "test_resume.py", "test_shipped_replays.py", "test_multi_robot.py", "test_units.py", "test_timing.py",
    "test_ekf.py", "test_rerun.py", "test_acfr.py", "test_gtsam_crosscheck.py", "test_fuzz.py",
)  # fmt: skip


# The floating-point-sensitive modules: `.ci/run` runs their fast tests (and those marked `portable`) again under
# every OpenBLAS kernel family the CPU can run, since BLAS kernels round differently (see .ci/run).
PORTABLE_MODULES = (
    "test_ekf.py", "test_smoother.py", "test_solver.py", "test_article.py", "test_shipped_replays.py",
    "test_geometry.py", "test_models.py", "test_checkpoint.py", "test_slam_api.py", "test_odometry_bias.py",
)  # fmt: skip


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Collect the heaviest modules first (a stable sort: each module stays whole and in its own order); mark the
    fast tests of the floating-point-sensitive modules ``portable``."""
    rank = {name: k for k, name in enumerate(HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
    for item in items:
        if item.path.name in PORTABLE_MODULES and item.get_closest_marker("slow") is None:
            item.add_marker(pytest.mark.portable)


# -- processes: every test stops what it starts, children included -------------------------------------------
import contextlib  # noqa: E402
import subprocess  # noqa: E402
import time  # noqa: E402
import uuid  # noqa: E402

import psutil  # noqa: E402

SESSION_MARK = "ONLINE_SLAM_TEST_SESSION"
os.environ[SESSION_MARK] = uuid.uuid4().hex  # inherited by every process a test starts, and by theirs
_SESSION_START = time.time()


def _marked_processes() -> list[psutil.Process]:
    """Live processes started during this session (at any depth, re-parented or not), but this one."""
    me, mark = os.getpid(), os.environ[SESSION_MARK]
    found = []
    for process in psutil.process_iter(["pid", "create_time"]):
        try:
            if process.pid == me or process.info["create_time"] < _SESSION_START - 1:
                continue
            if process.environ().get(SESSION_MARK) != mark or process.status() == psutil.STATUS_ZOMBIE:
                continue
            if process.ppid() == me and "multiprocessing" in " ".join(process.cmdline()):
                continue  # multiprocessing's resource tracker / forkserver: lives as long as this process, by design
            found.append(process)
        except (psutil.NoSuchProcess, psutil.AccessDenied, psutil.ZombieProcess):
            continue
    return found


def stop_process_tree(process: subprocess.Popen | psutil.Process, timeout: float = 10.0) -> None:
    """Terminate a process and all its descendants (found before it dies, so orphans are not missed)."""
    try:
        root = psutil.Process(process.pid) if isinstance(process, subprocess.Popen) else process
        tree = [root, *root.children(recursive=True)]
    except psutil.NoSuchProcess:  # already gone (its own children, if any, are caught by the autouse check)
        tree = []
    for p in tree:
        with contextlib.suppress(psutil.NoSuchProcess):
            p.terminate()
    _, alive = psutil.wait_procs(tree, timeout=timeout)
    for p in alive:
        with contextlib.suppress(psutil.NoSuchProcess):
            p.kill()
    psutil.wait_procs(alive, timeout=timeout)
    if isinstance(process, subprocess.Popen):
        process.wait(timeout=timeout)


def stop_marked_processes() -> None:
    """Stop every process this session started that still runs: the orphans of a process that was killed."""
    for process in _marked_processes():
        stop_process_tree(process)


@pytest.fixture
def processes():
    """Start processes for a test (``processes(cmd, **popen_kwargs)``); each tree is stopped at teardown."""
    started: list[subprocess.Popen] = []

    def start(command: list[str], **kwargs) -> subprocess.Popen:
        process = subprocess.Popen(command, **kwargs)
        started.append(process)
        return process

    yield start
    for process in started:
        stop_process_tree(process)


@pytest.fixture(autouse=True)
def no_process_outlives_its_test():
    """Fail a test that leaves a process behind (and stop the process)."""
    yield
    deadline = time.monotonic() + 5.0
    leaked = _marked_processes()
    while leaked and time.monotonic() < deadline:  # give exiting processes (pool workers) a moment
        time.sleep(0.1)
        leaked = _marked_processes()
    if leaked:
        described = ", ".join(f"{p.pid} {' '.join(p.cmdline()[:3])}" for p in leaked if p.is_running())
        for p in leaked:
            stop_process_tree(p)
        pytest.fail(f"processes outlived the test: {described}")


def circle_anees(
    config: object, seeds: tuple[int, ...] = tuple(range(100, 120)), poses: int | None = None
) -> tuple[float, float, float]:
    """The one online estimator of ``config`` (a ReplayConfig) over seeded runs of the circle world (esde's protocol;
    ``poses``: that many instead of esde's 400, scored the same way, from the 5th to the last but one): (its pose
    ANEES over those steps, the low and high ends of the 95% band for that many runs)."""
    from online_slam.compare import run_errors, summarise
    from online_slam.pipeline import replay
    from online_slam.sources.worlds import WORLDS, CircleConfig, circle_world

    world = CircleConfig() if poses is None else CircleConfig(poses=poses)
    scored = WORLDS["circle"].scored if poses is None else (4, poses - 2)
    outcomes = []
    for seed in seeds:
        results = replay(circle_world(dataclasses.replace(world, seed=seed)), config, name="circle", validate=False)
        outcomes.append((results.rows(), run_errors(results)))
    mc = summarise(outcomes, seeds, scored)
    (anees,) = mc.anees.values()
    low, high = mc.anees_bounds
    return anees, low, high


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:  # noqa: ANN001
    """Say which tests the absence of real data skipped (CI prints it: a green run may have left them out)."""
    skipped = [
        report for report in terminalreporter.stats.get("skipped", [])
        if isinstance(report.longrepr, tuple) and REAL_DATA_SKIP in str(report.longrepr[2])
    ]  # fmt: skip
    if skipped:
        terminalreporter.section("real data")
        terminalreporter.write_line(
            f"{len(skipped)} tests skipped: no real data in {SHARED_DATA} (set {DATA_VARIABLE})"
        )
        for report in skipped:
            terminalreporter.write_line(f"  {report.nodeid}")
