"""Live in, estimates out: a stream read over TCP (one client at a time, an end line, a stop), the estimate
stream written per step (file, stdout, TCP), and the command with real processes: a paced feeder killed part-way
and another that continues, a reader of the estimates in its own process, a signal that ends the run."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import online_slam
from online_slam.errors import InputError
from online_slam.estimators.protocol import Snapshot
from online_slam.options import replay_config
from online_slam.sinks.emit import MOVE_M, EstimateStream, TcpLines, _Landmarks
from online_slam.sources import End, square_world, write_stream
from online_slam.sources.address import on_error_of, tcp_address
from online_slam.sources.stream import read_stream
from online_slam.sources.tcp import open_tcp
from online_slam.sources.validate import EventValidator, validate_events

CLI = [sys.executable, "-m", "online_slam"]
LISTENING = re.compile(r"listening on tcp://([\d.]+):(\d+)")


@pytest.fixture
def square(tmp_path: Path) -> Path:
    path = tmp_path / "square.jsonl"
    write_stream(path, square_world())
    return path


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


def _send(port: int, lines: list[str], tail: bytes = b"") -> None:
    with socket.create_connection(("127.0.0.1", port)) as client:
        client.sendall("".join(line + "\n" for line in lines).encode() + tail)


def _free_port() -> int:
    """A port nobody listens on (bound, then released)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


# -- the end line -----------------------------------------------------------------------------------------------
def test_an_end_line_ends_a_file_and_what_follows_is_not_read(tmp_path: Path, square: Path) -> None:
    lines = _lines(square)
    cut = tmp_path / "cut.jsonl"
    cut.write_text("\n".join([*lines[:80], '{"type": "end"}', "not json at all", *lines[80:]]) + "\n")
    events = list(read_stream(cut))
    assert events == list(read_stream(square))[:80]  # the header included
    assert End().to_record() == {"type": "end"}
    assert EventValidator("x").parse_record({"type": "end"}) == End()
    with pytest.raises(InputError, match="unknown field for an end event"):
        EventValidator("x").parse_record({"type": "end", "t": 1.0})
    world = list(square_world())
    items = [*world[:5], {"type": "end"}, *world[5:]]
    assert len(list(validate_events(items))) == 5


# -- addresses --------------------------------------------------------------------------------------------------
def test_tcp_addresses_and_the_live_defaults() -> None:
    assert tcp_address("tcp://127.0.0.1:0") == ("127.0.0.1", 0)
    assert tcp_address("tcp://[::1]:5000") == ("::1", 5000)
    for bad in ("tcp://127.0.0.1", "tcp://:5000", "tcp://host:99999", "udp://host:1", "tcp://host:1/path"):
        with pytest.raises(ValueError, match="expected tcp://HOST:PORT"):
            tcp_address(bad)
    assert on_error_of(None, "tcp://127.0.0.1:0") == on_error_of(None, "-") == "skip"
    assert on_error_of(None, "square") == "stop" and on_error_of("stop", "tcp://127.0.0.1:0") == "stop"


def test_an_address_that_cannot_be_listened_on_is_one_line() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(InputError, match=f"tcp://127.0.0.1:{port}: cannot listen"):
            open_tcp(f"tcp://127.0.0.1:{port}", tell=lambda _: None)


def test_live_options_are_checked_before_anything_runs(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from online_slam.cli.main import main

    cases = {
        ("square", "--emit-estimator", "ekf"): "--emit-estimator: give --emit DEST too",
        ("square", "--json", "-", "--emit", "-"): "both would write to stdout",
        ("square", "--emit", str(tmp_path / "e.jsonl"), "--emit-estimator", "batch"): "'batch' estimates no step",
        ("square", "--emit", "tcp://nohost"): "--emit: expected tcp://HOST:PORT",
        ("square", "--emit", str(tmp_path / "no" / "e.jsonl")): "--emit: cannot write",
        ("tcp://127.0.0.1:0", "--noise", "fit"): "give a file, not a TCP stream",
        ("tcp://127.0.0.1:0", "--robot", "2"): "--robot applies to dataset files, not to a TCP stream",
    }
    for args, message in cases.items():
        assert main(["replay", *args]) == 2, args
        assert message in capsys.readouterr().err, args


# -- the TCP source, in this process -----------------------------------------------------------------------------
def _listen(**kw) -> tuple[int, list[str], object]:
    told: list[str] = []
    name, events = open_tcp("tcp://127.0.0.1:0", tell=told.append, **kw)
    port = int(name.rsplit(":", 1)[1])
    assert told == [f"listening on tcp://127.0.0.1:{port}"]
    return port, told, events


def test_clients_one_after_another_make_one_stream_and_a_cut_line_is_skipped(square: Path) -> None:
    lines = _lines(square)
    skipped: list[InputError] = []
    port, told, events = _listen(on_error=skipped.append)

    def feed() -> None:
        _send(port, lines[:70], tail=lines[70][:15].encode())  # goes away part-way through line 71
        _send(port, lines[70:] + ['{"type": "end"}'])

    feeder = threading.Thread(target=feed)
    feeder.start()
    got = list(events)
    feeder.join()
    assert got == list(read_stream(square))
    assert [e.reason for e in skipped] == ["cut_line"] and skipped[0].line == 71
    assert sum(" connected" in m for m in told) == 2 and sum("disconnected" in m for m in told) == 1


def test_a_stop_ends_the_stream_while_it_waits() -> None:
    stopped = threading.Event()
    port, _, events = _listen(stop=stopped.is_set)
    _send(port, ['{"type": "start", "t": 0.0, "pose": [0, 0, 0]}'])
    threading.Timer(0.3, stopped.set).start()
    started = time.perf_counter()
    assert len(list(events)) == 1
    assert time.perf_counter() - started < 2.0
    with pytest.raises(OSError):  # no longer listening
        socket.create_connection(("127.0.0.1", port), timeout=1.0).close()


def test_a_replay_over_tcp_equals_the_replay_of_the_file(square: Path) -> None:
    port, stopped, holder = _free_port(), threading.Event(), {}
    address = f"tcp://127.0.0.1:{port}"

    def run() -> None:
        holder["results"] = online_slam.replay(address, replay_config({"source": address}), stop=stopped.is_set)

    replayer = threading.Thread(target=run)
    replayer.start()
    try:
        client = _connect(port)
        with client:
            client.sendall("".join(line + "\n" for line in [*_lines(square), '{"type": "end"}']).encode())
        replayer.join(30)
    finally:
        stopped.set()
        replayer.join(10)
    live, file = holder["results"], online_slam.replay(str(square))
    assert live.error is None and live.poses == file.poses == 25
    for name in ("ekf", "smoother", "batch"):
        assert math.isclose(live.estimators[name].final_rmse_m, file.estimators[name].final_rmse_m, rel_tol=1e-9)


def _connect(port: int, timeout: float = 10.0) -> socket.socket:
    """Connect once the port listens."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return socket.create_connection(("127.0.0.1", port))
        except ConnectionRefusedError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.02)


# -- the estimate stream ----------------------------------------------------------------------------------------
def _snapshot(ids: tuple, xy: list, sigma: float | None = None) -> Snapshot:
    covs = None if sigma is None else np.tile(np.eye(2) * sigma**2, (len(ids), 1, 1))
    return Snapshot("ekf", 0, 0.0, np.zeros(3), np.eye(3), ids, np.array(xy, dtype=float).reshape(-1, 2), covs)


def test_landmarks_are_sent_when_new_or_moved_beyond_the_threshold() -> None:
    book = _Landmarks()
    assert book.changes(_snapshot((1, 2), [[0, 0], [5, 5]])) == ([0, 1], [])
    assert book.changes(_snapshot((1, 2), [[0.5 * MOVE_M, 0], [5, 5]])) == ([], [])
    assert book.changes(_snapshot((1, 2, 3), [[1.2 * MOVE_M, 0], [5, 5], [7, 7]])) == ([0, 2], [])  # it added up
    assert book.changes(_snapshot((3, 1), [[7, 7], [1.2 * MOVE_M, 0.0]])) == ([], [2])  # 2 left, order changed
    assert book.changes(_snapshot((3, 1, 2), [[7, 7.5], [0, 0], [9, 9]])) == ([0, 1, 2], [])
    wide = _Landmarks()  # sigma 1 m: it must move 0.1 m
    wide.changes(_snapshot((1,), [[0, 0]], sigma=1.0))
    assert wide.changes(_snapshot((1,), [[0.05, 0]], sigma=1.0)) == ([], [])
    assert wide.changes(_snapshot((1,), [[0.15, 0]], sigma=1.0)) == ([0], [])


def test_emit_to_a_file_writes_a_line_per_step(tmp_path: Path, square: Path) -> None:
    path = tmp_path / "estimates.jsonl"
    sink = EstimateStream(str(path), ("ekf", "smoother"))
    results = online_slam.replay(str(square), sinks=[sink])
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    assert len(lines) == 2 * results.poses and sink.writer.dropped == 0
    last = lines[-2]
    assert last["estimator"] == "ekf" and last["step"] == results.poses - 1 and last["robot"] is None
    assert set(last) >= {"t", "step", "robot", "estimator", "pose", "cov", "landmarks"}
    assert np.allclose(last["pose"], results.estimates["ekf"].poses[-1], atol=1e-9)
    sent = {item["id"] for line in lines if line["estimator"] == "ekf" for item in line["landmarks"]}
    assert sent == set(results.estimates["ekf"].landmark_ids)


def test_a_tcp_reader_that_is_not_there_costs_lines_not_the_run(square: Path) -> None:
    told: list[str] = []
    port = _free_port()
    sink = EstimateStream(f"tcp://127.0.0.1:{port}", ("ekf",), tell=told.append)
    results = online_slam.replay(str(square), sinks=[sink])
    assert results.error is None and sink.writer.dropped == results.poses
    assert len([m for m in told if m.startswith("warning")]) == 1
    assert told[-1].endswith(f"{results.poses} of {results.poses} lines dropped (no reader (Connection refused))")


def test_a_tcp_reader_gets_every_line_and_one_coming_late_gets_the_rest() -> None:
    port = _free_port()
    writer = TcpLines(f"tcp://127.0.0.1:{port}", tell=lambda _: None)
    writer.write("lost\n")  # nobody listens yet
    time.sleep(0.1)
    with socket.create_server(("127.0.0.1", port)) as server:
        time.sleep(0.6)  # beyond the retry interval
        for k in range(100):
            writer.write(f"{k}\n")
        writer.close()
        client, _ = server.accept()
        with client:
            received = b""
            while chunk := client.recv(1 << 16):
                received += chunk
    assert received.decode().split() == [str(k) for k in range(100)] and writer.dropped == 1


# -- the command, with real processes ---------------------------------------------------------------------------
FEEDER = """
import socket, sys, time
port, first, last, rate, cut = (int(a) for a in sys.argv[1:6])
lines = open(sys.argv[6]).read().splitlines()[first:last]
with socket.create_connection(("127.0.0.1", port)) as client:
    for line in lines:
        client.sendall((line + "\\n").encode())
        time.sleep(1.0 / rate)
    if cut:
        client.sendall(b'{"type": "odometry", "t"')
        print("cut", flush=True)
        time.sleep(60)
    client.sendall(b'{"type": "end"}\\n')
"""
READER = """
import socket, sys
with socket.create_server(("127.0.0.1", 0)) as server:
    print(server.getsockname()[1], flush=True)
    client, _ = server.accept()
    with client, client.makefile() as lines:
        for line in lines:
            print(line, end="", flush=True)
"""


def _env() -> dict[str, str]:
    root = str(Path(__file__).resolve().parents[1])
    return {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}


def _port_of(replay: subprocess.Popen) -> int:
    line = replay.stderr.readline()
    found = LISTENING.search(line)
    assert found, line
    return int(found[2])


@pytest.mark.slow
def test_a_killed_feeder_is_survived_and_a_reader_process_gets_every_step(
    processes, tmp_path: Path, square: Path
) -> None:
    reader = processes([sys.executable, "-c", READER], stdout=subprocess.PIPE, text=True)
    reader_port = int(reader.stdout.readline())
    report = tmp_path / "live.json"
    replay = processes(
        [*CLI, "replay", "tcp://127.0.0.1:0", "--emit", f"tcp://127.0.0.1:{reader_port}", "--json", str(report)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(),
    )  # fmt: skip
    port = _port_of(replay)
    n = len(_lines(square))
    killed = processes([sys.executable, "-c", FEEDER, str(port), "0", "90", "400", "1", str(square)],
                       stdout=subprocess.PIPE, text=True)  # fmt: skip
    assert killed.stdout.readline() == "cut\n"  # 90 lines sent, then a part of one
    killed.kill()
    killed.wait(10)
    rest = processes([sys.executable, "-c", FEEDER, str(port), "90", str(n), "400", "0", str(square)])
    assert rest.wait(20) == 0
    out, err = replay.communicate(timeout=60)
    assert replay.returncode == 0, err
    assert "cut line" in err and err.count("connected to") == 2
    estimates = [json.loads(line) for line in reader.stdout.read().splitlines()]
    assert reader.wait(10) == 0
    live, file = json.loads(report.read_text()), online_slam.replay(str(square))
    assert live["poses"] == file.poses == len(estimates) and live["input"]["skipped_by_reason"] == {"cut_line": 1}
    for name in ("ekf", "smoother", "batch"):
        assert math.isclose(live["estimators"][name]["final_rmse_m"], file.estimators[name].final_rmse_m, rel_tol=1e-9)
    assert [e["step"] for e in estimates] == list(range(file.poses))
    assert np.allclose(estimates[-1]["pose"], file.estimates["ekf"].poses[-1], atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_ends_a_live_run_with_the_figures_of_what_came(
    processes, tmp_path: Path, square: Path, signum: int
) -> None:
    estimates = tmp_path / "estimates.jsonl"
    replay = processes([*CLI, "replay", "tcp://127.0.0.1:0", "--emit", str(estimates), "--max-latency", "0"],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env())  # fmt: skip
    port = _port_of(replay)
    lines = _lines(square)
    with socket.create_connection(("127.0.0.1", port)) as client:  # connected, then silent
        client.sendall("".join(line + "\n" for line in lines[:60]).encode())
        deadline = time.monotonic() + 20
        while len(estimates.read_text().splitlines()) < 5 and time.monotonic() < deadline:
            time.sleep(0.05)
        replay.send_signal(signum)
        out, err = replay.communicate(timeout=20)
    assert replay.returncode == 130, err
    assert "interrupted after" in err and "ekf" in out
    assert len(estimates.read_text().splitlines()) >= 5
