"""Checkpoints of a replay: kill -9 half-way, resume, same figures; damaged or foreign checkpoints refused."""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from conftest import assert_close
from inprocess import run_cli as cli

from online_slam.checkpoint import FORMAT_VERSION, read_checkpoint
from online_slam.faults import CRASH_VARIABLE
from online_slam.sources.stream import write_stream
from online_slam.sources.worlds import GridConfig, grid_world

EXE = [shutil.which("online-slam")] if shutil.which("online-slam") else [sys.executable, "-m", "online_slam"]


def figures(document: dict) -> dict:
    """Every figure of the results JSON but timings."""
    out = json.loads(json.dumps(document))
    for estimator in out["estimators"].values():
        for key in ("total_s", "step_ms", "solve_s", "final_solve_s"):
            estimator.pop(key, None)
    return out


def assert_same_figures(a: dict, b: dict, tolerance: float = 1e-9) -> None:
    assert_close(figures(a), figures(b), rtol=tolerance, where="results")


@pytest.fixture(scope="module")
def stream(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    folder = tmp_path_factory.mktemp("resume")
    path = folder / "grid300.jsonl"  # a global solve starts at step 200 and is handed over at 250
    write_stream(path, grid_world(GridConfig(poses=300, seed=10)))
    done = cli("replay", str(path), "--json", str(folder / "whole.json"), "--quiet")
    assert done.returncode == 0, done.stderr
    return path, json.loads((folder / "whole.json").read_text())


@pytest.mark.slow
def test_kill_9_half_way_then_resume_gives_the_uninterrupted_figures(stream, tmp_path: Path) -> None:
    path, whole = stream
    folder = tmp_path / "ck"
    killed = subprocess.run(
        [*EXE, "replay", str(path), "--quiet", "--checkpoint", str(folder), "--checkpoint-every", "100"],
        capture_output=True, env={**os.environ, CRASH_VARIABLE: "steps:250"}, timeout=300,
    )  # fmt: skip
    assert killed.returncode == -signal.SIGKILL, killed.stderr  # at step 250, wherever the machine's speed
    saved = read_checkpoint(folder / "replay.ckpt", "replay")["engine"]["state"]["steps"]
    assert saved == 200
    out = tmp_path / "resumed.json"
    done = cli("replay", str(path), "--resume", str(folder), "--json", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    assert_same_figures(json.loads(out.read_text()), whole)


def _rewrite(source: Path, target: Path, edit) -> None:
    with zipfile.ZipFile(source) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    edit(members)
    with zipfile.ZipFile(target, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)


@pytest.mark.slow
def test_damaged_foreign_and_other_version_checkpoints_are_one_line_exit_2(stream, tmp_path: Path) -> None:
    path, _ = stream
    small = tmp_path / "small.jsonl"
    write_stream(small, grid_world(GridConfig(poses=300, seed=11)))
    good = tmp_path / "good"
    assert cli("replay", str(small), "--quiet", "--checkpoint", str(good), "--checkpoint-every", "50").returncode == 0
    checkpoint = good / "replay.ckpt"

    def refused(folder: Path, source: Path, *extra: str) -> str:
        done = cli("replay", str(source), "--resume", str(folder), "--quiet", *extra)
        assert done.returncode == 2, done.stdout + done.stderr
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("online-slam: error: ") and "Traceback" not in done.stderr
        return lines[0]

    cut = tmp_path / "cut"
    cut.mkdir()
    data = checkpoint.read_bytes()
    (cut / "replay.ckpt").write_bytes(data[: len(data) // 3])
    assert "not a usable checkpoint" in refused(cut, small)
    assert "another source" in refused(good, path)  # another file
    for other in (FORMAT_VERSION - 1, 99):  # a file of the previous layout, one of a later version
        version = tmp_path / f"version{other}"
        version.mkdir()

        def bump(members: dict, other: int = other) -> None:
            manifest = json.loads(members["manifest.json"])
            manifest["format_version"] = other
            members["manifest.json"] = json.dumps(manifest).encode()

        _rewrite(checkpoint, version / "replay.ckpt", bump)
        assert f"format version {other}; this version reads {FORMAT_VERSION}" in refused(version, small)
    settings = refused(good, small, "--window", "7")
    assert "other settings (here " in settings and "=7, there " in settings, settings  # names the field
    missing = refused(tmp_path / "nowhere", small)
    assert "no such checkpoint" in missing
    # the same file name, other contents: the events the checkpoint had consumed differ
    write_stream(small, grid_world(GridConfig(poses=300, seed=12)))
    assert "its events differ" in refused(good, small)


def test_checkpoint_files_are_written_atomically(tmp_path: Path) -> None:
    from online_slam.checkpoint import write_checkpoint

    target = tmp_path / "state.ckpt"
    write_checkpoint(target, "test", {"a": 1})

    import numpy as np

    with pytest.raises(TypeError):
        write_checkpoint(target, "test", {"a": 2, "bad": object()})
    assert read_checkpoint(target, "test") == {"a": 1}  # the previous checkpoint is intact
    assert [p.name for p in tmp_path.iterdir()] == ["state.ckpt"]  # no temporary left behind
    write_checkpoint(target, "test", {"x": np.arange(3.0), "ids": [1, "a"], "t": (1, 2), "m": {3: "x"}})
    back = read_checkpoint(target, "test")
    assert back["ids"] == [1, "a"] and back["t"] == (1, 2) and back["m"] == {3: "x"}
    assert back["x"].tolist() == [0.0, 1.0, 2.0] and back["x"].flags.writeable
    digest = hashlib.sha256(io.BytesIO(target.read_bytes()).getvalue()).hexdigest()
    assert len(digest) == 64


def test_a_checkpoint_that_cannot_be_written_stops_the_replay_and_keeps_the_last_one(
    stream, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk at the third write (step 150): the figures so far, the error, step 100's checkpoint."""
    from online_slam.errors import OnlineSlamError
    from online_slam.pipeline import Checkpointing, replay, run

    path, _ = stream
    folder = tmp_path / "ck"
    written: list[int] = []
    real = run.write_checkpoint

    def disk_full(target: Path, kind: str, state: run.ReplayCheckpoint) -> None:
        if len(written) == 2:
            raise OnlineSlamError(f"cannot write checkpoint {target}: No space left on device")
        written.append(state.engine.state.steps)
        real(target, kind, state)

    monkeypatch.setattr(run, "write_checkpoint", disk_full)
    results = replay(str(path), checkpoint=Checkpointing(folder, 50))
    assert results.error is not None and "No space left on device" in results.error
    assert results.poses == 151 and written == [50, 100]  # the pose pending at the failure is kept
    assert read_checkpoint(folder / "replay.ckpt", "replay")["engine"]["state"]["steps"] == 100
    assert sorted(p.name for p in folder.iterdir()) == ["replay.ckpt"]


@pytest.mark.slow
def test_an_interrupt_keeps_the_work_and_a_checkpoint_to_resume_from(stream, tmp_path: Path) -> None:
    """Ctrl-C (SIGINT after step 250, at a point the machine's speed does not decide): exit 130 with the table, the
    JSON of the 251 poses so far and a checkpoint written there; resuming gives the uninterrupted figures."""
    path, whole = stream
    folder, partial = tmp_path / "ck", tmp_path / "partial.json"
    stopped = subprocess.run(
        [*EXE, "replay", str(path), "--json", str(partial), "--checkpoint", str(folder), "--checkpoint-every", "100"],
        capture_output=True, text=True, env={**os.environ, CRASH_VARIABLE: "steps:250:INT"}, timeout=300,
    )  # fmt: skip
    assert stopped.returncode == 130, stopped.stderr
    assert "stopped early: interrupted; figures cover the 251 poses" in stopped.stdout
    assert "online-slam: interrupted after 251 poses" in stopped.stderr and "Traceback" not in stopped.stderr
    document = json.loads(partial.read_text())
    assert document["error"] == "interrupted" and document["poses"] == 251
    assert set(document["estimators"]) == {"ekf", "smoother", "batch"}
    assert read_checkpoint(folder / "replay.ckpt", "replay")["engine"]["state"]["steps"] == 250
    out = tmp_path / "resumed.json"
    done = cli("replay", str(path), "--resume", str(folder), "--json", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    assert_same_figures(json.loads(out.read_text()), whole)
