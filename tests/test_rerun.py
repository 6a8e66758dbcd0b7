"""Rerun recordings: replay writes one, Rerun's own API reads it back; inspect; the blueprint."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from inprocess import run_cli as cli

pytest.importorskip("rerun", reason="rerun-sdk is not installed")
pytest.importorskip("datafusion", reason="rerun-sdk[catalog] is not installed")

from conftest import stop_process_tree  # noqa: E402

from online_slam.sinks.recording import Recording, blueprint_views  # noqa: E402


@pytest.fixture(scope="module")
def square_recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    folder = tmp_path_factory.mktemp("rrd")
    rrd, out = folder / "square.rrd", folder / "square.json"
    done = cli("replay", "square", "--rrd", str(rrd), "--json", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    return rrd, json.loads(out.read_text())


@pytest.mark.slow
def test_recording_reads_back_with_the_json_figures(square_recording: tuple[Path, dict]) -> None:
    rrd, results = square_recording
    with Recording(rrd) as recording:
        summary = recording.summary()
        paths = recording.entity_paths()
        last = recording.state_at(24)
    assert summary.source == "square" and summary.steps == results["poses"] == 25
    assert summary.time_span == (0.0, 24.0)
    assert summary.estimators == ("ekf", "smoother", "batch")
    for name in ("ekf", "smoother", "batch"):
        for key in ("final_rmse_m", "landmark_rmse_m", "endpoint_gap_m"):
            assert summary.results["estimators"][name][key] == results["estimators"][name][key]
    for name in ("ekf", "smoother"):
        assert summary.latency_ms[name]["median"] == pytest.approx(results["estimators"][name]["step_ms"]["median"])
        assert summary.latency_ms[name]["max"] == pytest.approx(results["estimators"][name]["step_ms"]["max"])
    expected = {
        "/world/truth/path", "/world/truth/landmarks", "/world/odometry/path", "/world/observations",
        "/world/ekf/pose", "/world/ekf/pose_cov", "/world/ekf/landmarks", "/world/ekf/landmark_cov",
        "/world/smoother/pose", "/world/smoother/window", "/world/batch/path", "/world/batch/landmarks",
        "/metrics/ekf/step_ms", "/metrics/ekf/position_error_m", "/metrics/ekf/nees", "/metrics/ekf/nis",
        "/metrics/smoother/cost_after", "/metrics/smoother/iterations", "/events",
    }  # fmt: skip
    assert expected <= set(paths)
    ekf = last["estimators"]["ekf"]
    assert ekf["landmarks"] == 12 and abs(ekf["pose"][0]) < 0.2 and abs(ekf["pose"][1]) < 0.2


@pytest.mark.slow
def test_recorded_errors_are_the_tables_even_after_se2_alignment(tmp_path: Path) -> None:
    rrd, out = tmp_path / "se2.rrd", tmp_path / "se2.json"
    done = cli("replay", "square", "--align", "se2", "--rrd", str(rrd), "--json", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    results = json.loads(out.read_text())
    with Recording(rrd) as recording:
        for name in ("ekf", "smoother"):
            steps, errors = recording.metric(name, "position_error_m")
            assert steps == list(range(25))
            rmse = float(np.sqrt(np.mean(np.square(errors))))
            assert rmse == pytest.approx(results["estimators"][name]["online_rmse_m"], rel=1e-6)  # float32 in Rerun
            _, nees = recording.metric(name, "nees")
            assert np.mean(nees) == pytest.approx(results["estimators"][name]["nees_mean"], rel=1e-5)


def test_default_blueprint_is_in_the_recording(square_recording: tuple[Path, dict]) -> None:
    views = blueprint_views(square_recording[0])
    kinds = {(v.kind, v.origin) for v in views}
    assert ("2D", "/world") in kinds and ("TextLog", "/events") in kinds
    series = {v.name: v.contents for v in views if v.kind == "TimeSeries"}
    assert set(series["position error (m)"]) == {"/metrics/ekf/position_error_m", "/metrics/smoother/position_error_m"}
    assert set(series["step time (ms)"]) == {"/metrics/ekf/step_ms", "/metrics/smoother/step_ms"}


@pytest.fixture(scope="module")
def compare_recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, str]:
    folder = tmp_path_factory.mktemp("compare")
    rrd, out = folder / "c.rrd", folder / "c.json"
    done = cli("compare", "square", "--window", "10,20", "--rrd", str(rrd), "--json", str(out))
    assert done.returncode == 0, done.stderr
    return rrd, json.loads(out.read_text()), done.stdout


CONFIGS = ("ekf", "smoother W=10..120 D=18 K=1 invariant", "smoother W=20..120 D=18 K=1 invariant", "batch")


@pytest.mark.slow
def test_compare_recording_holds_every_configuration_with_the_tables_figures(compare_recording) -> None:
    rrd, table, _ = compare_recording
    assert tuple(n for n in table["estimators"] if n != "odometry") == CONFIGS
    with Recording(rrd) as recording:
        summary = recording.summary()
        paths = set(recording.entity_paths())
    assert summary.estimators == CONFIGS
    entities = summary.layout.entities
    assert entities[CONFIGS[1]] == "smoother_W10..120_D18_K1_invariant"
    assert entities[CONFIGS[2]] == "smoother_W20..120_D18_K1_invariant"
    assert len(set(summary.layout.to_json()["colors"].values())) == len(summary.layout.names)  # one colour each
    for name in CONFIGS:
        row, stored = table["estimators"][name], summary.results["estimators"][name]
        for key in ("final_rmse_m", "online_rmse_m", "landmark_rmse_m", "endpoint_gap_m"):
            assert stored.get(key) == row[key]
        root = "/" + summary.layout.world(name)
        assert f"{root}/path" in paths and f"{root}/landmarks" in paths
        if name != "batch":  # online configurations: every step, and the table's figures from the logged series
            assert f"{root}/pose" in paths
            assert summary.figures[name]["online_rmse_m"] == pytest.approx(row["online_rmse_m"], rel=1e-6)
            assert summary.figures[name]["nees_mean"] == pytest.approx(row["nees_mean"], rel=1e-5)
            assert summary.latency_ms[name]["median"] == pytest.approx(row["step_ms"]["median"])
    views = {v.name: v.contents for v in blueprint_views(rrd) if v.kind == "TimeSeries"}
    for figure, title in (("position_error_m", "position error (m)"), ("step_ms", "step time (ms)")):
        expected = {f"/{summary.layout.metrics(n)}/{figure}" for n in CONFIGS if n != "batch"}
        assert set(views[title]) == expected
    done = subprocess.run(["rerun", "rrd", "verify", str(rrd)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr


@pytest.mark.slow
def test_inspect_lists_every_configuration_of_a_comparison(compare_recording) -> None:
    rrd, table, _ = compare_recording
    done = cli("inspect", str(rrd))
    assert done.returncode == 0, done.stderr
    lines = {line.split("  ")[0]: line for line in done.stdout.splitlines()}
    for name in CONFIGS:
        line = lines[name]
        assert f"{table['estimators'][name]['final_rmse_m']:.4f}" in line
        if name != "batch":
            assert f"{table['estimators'][name]['online_rmse_m']:.4f}" in line
    state = json.loads(cli("inspect", str(rrd), "--step", "24", "--json").stdout)["state"]
    assert set(state["estimators"]) >= {"odometry", *CONFIGS[:-1], "truth"}


@pytest.mark.slow
def test_inspect_prints_summary_and_step(square_recording: tuple[Path, dict]) -> None:
    rrd, results = square_recording
    done = cli("inspect", str(rrd))
    assert done.returncode == 0, done.stderr
    assert "source: square" in done.stdout and "steps: 25" in done.stdout
    assert f"{results['estimators']['batch']['final_rmse_m']:.4f}" in done.stdout
    done = cli("inspect", str(rrd), "--step", "12", "--json")
    state = json.loads(done.stdout)["state"]
    assert state["step"] == 12 and set(state["estimators"]) >= {"odometry", "ekf", "smoother", "truth"}
    assert any("relinearized" in e for e in state["events"])


@pytest.mark.slow
def test_inspect_step_shows_that_step_alone_aligned(compare_recording) -> None:
    rrd = compare_recording[0]
    done = cli("inspect", str(rrd), "--step", "24")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == f"{rrd} (square): step 24 of 0..24, t = 24.000 s"
    assert not any(line.startswith(("recording:", "source:", "steps:", "estimators:")) for line in lines)
    rows = lines[1 : lines.index(next(line for line in lines if line.startswith("events")))]
    assert [row.split("  ")[0] for row in rows] == ["estimator", "odometry", *CONFIGS[:-1], "truth"]
    assert len({len(row) for row in rows}) == 1  # every column lines up, whatever the names' lengths
    assert rows[1].split()[-1] == "12"  # landmarks: a count


@pytest.mark.slow
def test_recorded_events_name_ids_as_ids(square_recording: tuple[Path, dict]) -> None:
    done = cli("inspect", str(square_recording[0]), "--step", "0")
    assert done.returncode == 0, done.stderr
    assert "landmarks initialised" not in done.stdout
    assert re.search(r"^  ekf: initialised landmark ids \w+, \w+, \w+$", done.stdout, re.MULTILINE), done.stdout


@pytest.mark.slow
def test_the_robot_is_in_the_recording_and_inspect(mrclam_head: Path, tmp_path: Path) -> None:
    head, rrd = mrclam_head, tmp_path / "robot1.rrd"
    done = cli("replay", str(head), "--estimators", "ekf", "--rrd", str(rrd), "--quiet")
    assert done.returncode == 0, done.stderr
    with Recording(rrd) as recording:
        assert recording.summary().robot == 1
    text = cli("inspect", str(rrd)).stdout
    assert f"source: {head}, robot 1" in text.splitlines()
    assert json.loads(cli("inspect", str(rrd), "--json").stdout)["robot"] == 1
    assert json.loads(cli("inspect", str(rrd), "--json", "--step", "3").stdout)["robot"] == 1
    assert cli("inspect", str(rrd), "--step", "3").stdout.startswith(f"{rrd} ({head}, robot 1): step 3 of 0..")


@pytest.mark.slow
@pytest.mark.parametrize("case", ["truncated", "text", "missing", "step"])
def test_inspect_bad_files_give_one_line_and_exit_2(
    square_recording: tuple[Path, dict], tmp_path: Path, case: str
) -> None:
    rrd = square_recording[0]
    target, extra = tmp_path / f"{case}.rrd", []
    if case == "truncated":
        target.write_bytes(rrd.read_bytes()[: rrd.stat().st_size // 2])
    elif case == "text":
        target.write_text("not a recording\n")
    elif case == "step":
        target, extra = rrd, ["--step", "99"]
    done = cli("inspect", str(target), *extra)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("online-slam: error:")


@pytest.mark.slow
def test_live_stream_reaches_a_viewer_and_rate_paces(tmp_path: Path, processes) -> None:
    rerun_cli = shutil.which("rerun")
    if rerun_cli is None:
        pytest.skip("the rerun command is not installed")
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    saved = tmp_path / "live.rrd"
    # `rerun` is a Python wrapper around the viewer binary: the fixture stops the whole tree
    server = processes(
        [rerun_cli, "--port", str(port), "--save", str(saved)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        time.sleep(2.0)
        done = cli("replay", "square", "--connect", f"rerun+http://127.0.0.1:{port}/proxy", "--rate", "50", "--quiet")
        assert done.returncode == 0, done.stderr
        time.sleep(1.0)
    finally:
        stop_process_tree(server)
    with Recording(saved, complete=False) as recording:  # a stream saved by the viewer has no footer
        summary = recording.summary()
    assert summary.steps == 25 and summary.source == "square"


@pytest.mark.slow
def test_unreachable_viewer_is_one_line_before_the_replay(tmp_path: Path) -> None:
    out, rrd = tmp_path / "r.json", tmp_path / "r.rrd"
    done = cli("replay", "square", "--connect", "rerun+http://127.0.0.1:9/proxy", "--json", str(out), "--rrd", str(rrd))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    ours = [line for line in done.stderr.splitlines() if line.startswith("online-slam:")]
    assert len(ours) == 1 and "no Rerun viewer answers" in ours[0] and "127.0.0.1:9" in ours[0]
    assert "rerun --serve-web" in ours[0]  # how to start one
    assert done.stdout == "" and not out.exists() and not rrd.exists()  # told before any replay work


def test_rate_paces_steps_to_the_streams_clock() -> None:
    """``--rate``: each step waits until the wall clock has run its stream time over the rate (a fake clock)."""
    from online_slam.sinks.live import Pacer

    now, slept = [100.0], []

    def sleep(seconds: float) -> None:
        slept.append(seconds)
        now[0] += seconds

    pacer = Pacer(50.0, clock=lambda: now[0], sleep=sleep)
    for t, work in ((3.0, 0.0), (4.0, 0.01), (5.0, 0.05), (9.0, 0.0)):
        pacer.on_step(SimpleNamespace(t=t), {}, None)
        now[0] += work  # the step's own computing time
    assert slept == pytest.approx([0.02, 0.01, 0.03])  # due at 100 + (t - 3) / 50; the second step's work overran
