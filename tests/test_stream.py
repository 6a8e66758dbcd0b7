"""Stream format v1: round trip, laziness, gzip and stdin, and one test per class of bad line."""

from __future__ import annotations

import gzip
import io
import json
import math
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from online_slam.errors import InputError
from online_slam.sources import (
    Header,
    LandmarkTruth,
    Observation,
    Odometry,
    Start,
    Truth,
    read_stream,
    square_world,
    write_stream,
)

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
positive = st.floats(1e-6, 1e3, allow_nan=False)
bearings = st.floats(-2 * math.pi, 2 * math.pi)
angles = bearings  # every angle of a stream is within [-2 pi, 2 pi]
ids = st.one_of(st.integers(-1000, 10**12), st.text(min_size=1, max_size=8))


@st.composite
def streams(draw: st.DrawFn) -> list:
    events: list = [Header(name=draw(st.text(max_size=10)), meta={"seed": draw(st.integers(0, 99))})]
    t = draw(st.floats(-100, 100))
    if draw(st.booleans()):
        sigma = draw(st.one_of(st.none(), st.tuples(positive, positive, positive)))
        events.append(Start(t=t, pose=draw(st.tuples(finite, finite, angles)), sigma=sigma))
    for _ in range(draw(st.integers(0, 12))):
        t += draw(st.floats(0, 10))
        kind = draw(st.sampled_from(["odometry", "observation", "truth", "landmark_truth", "cov"]))
        if kind == "odometry":
            events.append(Odometry(t=t, delta=draw(st.tuples(finite, finite, angles)), sigma=(0.1, 0.2, 0.3)))
        elif kind == "cov":
            a, b = draw(positive), draw(positive)
            events.append(Odometry(t=t, delta=(1.0, 0.0, 0.5), cov=((a, 0.0, 0.0), (0.0, b, 0.0), (0.0, 0.0, a))))
        elif kind == "observation":
            landmark, hidden = draw(st.one_of(st.none(), ids)), draw(st.one_of(st.none(), ids))
            widened = draw(st.one_of(st.none(), st.tuples(*[st.floats(1.0, 1e9)] * 2)))
            z = (draw(positive), draw(bearings))
            events.append(Observation(t, landmark, *z, sigma=(0.1, 0.01), truth_landmark=hidden, widened=widened))
        elif kind == "truth":
            events.append(Truth(t=t, pose=draw(st.tuples(finite, finite, finite))))
        else:
            events.append(LandmarkTruth(landmark=draw(ids), position=draw(st.tuples(finite, finite))))
    return events


@settings(max_examples=60, deadline=None)
@given(streams())
def test_write_then_read_round_trips(events: list) -> None:
    buffer = io.StringIO()
    write_stream(buffer, events)
    path = Path(f"/tmp/online-slam-roundtrip-{id(buffer)}.jsonl")
    path.write_text(buffer.getvalue())
    try:
        assert list(read_stream(path)) == events
    finally:
        path.unlink()


def test_square_world_round_trips_through_gzip(tmp_path: Path) -> None:
    events = list(square_world())
    path = tmp_path / "square.jsonl.gz"
    assert write_stream(path, events) == len(events)
    assert list(read_stream(path)) == events


def test_reader_is_lazy(tmp_path: Path) -> None:
    path = tmp_path / "s.jsonl"
    path.write_text('{"type": "odometry", "t": 1, "delta": [1, 0, 0], "sigma": [1, 1, 1]}\nnot json\n')
    reader = read_stream(path)
    assert isinstance(next(reader), Odometry)  # the bad second line is not read yet
    with pytest.raises(InputError):
        next(reader)


def test_reads_stdin(monkeypatch: pytest.MonkeyPatch) -> None:
    data = '{"type": "truth", "t": 0, "pose": [1, 2, 3]}\n'
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data.encode())))
    assert list(read_stream("-")) == [Truth(t=0.0, pose=(1.0, 2.0, 3.0))]


OK_ODO = {"type": "odometry", "t": 1, "delta": [1, 0, 0], "sigma": [0.1, 0.1, 0.01]}
OK_OBS = {"type": "observation", "t": 1, "landmark": 3, "range": 2.0, "bearing": 0.1, "sigma": [0.1, 0.01]}

BAD_LINES = [
    ("{not json", "", "invalid JSON"),
    ("[1, 2]", "", "expected a JSON object"),
    (json.dumps({"type": "teleport", "t": 1}), "type", "unknown event type"),
    (json.dumps({**OK_ODO, "sigmas": [1, 1, 1]}), "sigmas", "unknown field"),
    (json.dumps({k: v for k, v in OK_ODO.items() if k != "delta"}), "delta", "missing required field"),
    (json.dumps({k: v for k, v in OK_ODO.items() if k != "sigma"}), "sigma", "missing noise"),
    (json.dumps({**OK_ODO, "delta": [1, 0]}), "delta", "list of 3 numbers"),
    (json.dumps({**OK_ODO, "delta": [1, "x", 0]}), "delta[1]", "expected a number"),
    ('{"type": "odometry", "t": 1, "delta": [1, NaN, 0], "sigma": [1, 1, 1]}', "delta[1]", "finite"),
    ('{"type": "observation", "t": 1, "landmark": 3, "range": Infinity, "bearing": 0, "sigma": [1, 1]}', "range", ""),
    (json.dumps({**OK_OBS, "range": -2.0}), "range", "range > 0"),
    (json.dumps({**OK_OBS, "range": 0}), "range", "range > 0"),
    (json.dumps({**OK_OBS, "bearing": 45.0}), "bearing", "in degrees?"),
    (json.dumps({**OK_OBS, "bearing": -6.3}), "bearing", "in degrees?"),
    (json.dumps({**OK_ODO, "delta": [1, 0, 90]}), "delta[2]", "in degrees?"),
    (json.dumps({**OK_OBS, "sigma": [0.1, 0.0]}), "sigma[1]", "> 0"),
    (json.dumps({**OK_OBS, "landmark": 1.5}), "landmark", "integer or a non-empty string"),
    (json.dumps({**OK_OBS, "landmark": True}), "landmark", "integer or a non-empty string"),
    (json.dumps({**OK_OBS, "truth_landmark": 1.5}), "truth_landmark", "integer or a non-empty string"),
    (json.dumps({**OK_OBS, "truth_landmark": ""}), "truth_landmark", "integer or a non-empty string"),
    (json.dumps({**OK_OBS, "truth_landmark": False}), "truth_landmark", "integer or a non-empty string"),
    (json.dumps({**OK_OBS, "truth_landmark": [3]}), "truth_landmark", "integer or a non-empty string"),
    (json.dumps({**OK_OBS, "t": True}), "t", "expected a number"),
    (json.dumps({**OK_OBS, "sigma": None, "cov": [[1, 2], [2, 1]]}).replace('"sigma": null, ', ""), "cov", "positive"),
    (json.dumps({**OK_OBS, "sigma": None, "cov": [[1, 0.5], [0, 1]]}).replace('"sigma": null, ', ""), "cov", "symm"),
    (json.dumps({**OK_OBS, "cov": [[1, 0], [0, 1]]}), "cov", "either sigma or cov"),
    (json.dumps({"type": "landmark_truth", "landmark": 1, "position": [1]}), "position", "list of 2"),
    (json.dumps({**OK_OBS, "widened": [0.5, 2.0]}), "widened[0]", "variance factor >= 1"),
    (json.dumps({**OK_OBS, "widened": [2.0, 1e13]}), "widened[1]", "magnitude <= 1e+09"),
    (json.dumps({**OK_OBS, "widened": 4.0}), "widened", "list of 2 numbers"),
    (json.dumps({**OK_OBS, "widened": [1.0, 1.0]}).replace("[1.0, 1.0]", "[NaN, 1]"), "widened[0]", "finite"),
]


@pytest.mark.parametrize(("line", "field", "expected"), BAD_LINES)
def test_bad_line_names_file_line_and_field(tmp_path: Path, line: str, field: str, expected: str) -> None:
    path = tmp_path / "bad.jsonl"
    path.write_text(json.dumps(OK_ODO) + "\n" + line + "\n")
    with pytest.raises(InputError) as info:
        list(read_stream(path))
    err = info.value
    assert (err.source, err.line, err.field) == (str(path), 2, field)
    assert expected in err.message
    assert str(err).startswith(f"{path}:2: ")
    assert "\n" not in str(err)


def test_time_going_backwards(tmp_path: Path) -> None:
    path = tmp_path / "back.jsonl"
    path.write_text(json.dumps({**OK_ODO, "t": 5}) + "\n" + json.dumps({**OK_OBS, "t": 4}) + "\n")
    with pytest.raises(InputError, match=r"back.jsonl:2: t: time goes backwards"):
        list(read_stream(path))


def test_start_after_timed_events_and_late_header(tmp_path: Path) -> None:
    path = tmp_path / "late.jsonl"
    path.write_text(json.dumps(OK_ODO) + "\n" + json.dumps({"type": "start", "t": 1, "pose": [0, 0, 0]}) + "\n")
    with pytest.raises(InputError, match="start must come before"):
        list(read_stream(path))
    path.write_text(json.dumps(OK_ODO) + "\n" + json.dumps({"type": "header", "version": 1}) + "\n")
    with pytest.raises(InputError, match="header must be the first line"):
        list(read_stream(path))


def test_unsupported_version_and_format(tmp_path: Path) -> None:
    path = tmp_path / "v2.jsonl"
    path.write_text(json.dumps({"type": "header", "format": "online-slam", "version": 2}) + "\n")
    with pytest.raises(InputError, match=r"v2.jsonl:1: version: unsupported version 2"):
        list(read_stream(path))
    path.write_text(json.dumps({"type": "header", "format": "g2o"}) + "\n")
    with pytest.raises(InputError, match=r"v2.jsonl:1: format: expected 'online-slam'"):
        list(read_stream(path))


def test_truncated_gzip(tmp_path: Path) -> None:
    path = tmp_path / "cut.jsonl.gz"
    write_stream(path, square_world())
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="truncated or corrupt gzip"):
        list(read_stream(path))


def test_not_gzip_and_not_utf8(tmp_path: Path) -> None:
    fake = tmp_path / "fake.jsonl.gz"
    fake.write_text("plain text\n")
    with pytest.raises(InputError, match="gzip"):
        list(read_stream(fake))
    binary = tmp_path / "binary.jsonl"
    binary.write_bytes(b"\xff\xfe\x00garbage\n")
    with pytest.raises(InputError, match="UTF-8"):
        list(read_stream(binary))


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="cannot open"):
        list(read_stream(tmp_path / "nope.jsonl"))


def test_blank_lines_are_skipped_and_counted(tmp_path: Path) -> None:
    path = tmp_path / "blank.jsonl"
    path.write_text("\n\n" + json.dumps(OK_ODO) + "\n\n{bad\n")
    with pytest.raises(InputError) as info:
        list(read_stream(path))
    assert info.value.line == 5


def test_gzip_text_equals_plain(tmp_path: Path) -> None:
    plain, packed = tmp_path / "a.jsonl", tmp_path / "a.jsonl.gz"
    write_stream(plain, square_world())
    write_stream(packed, square_world())
    assert gzip.decompress(packed.read_bytes()).decode() == plain.read_text()


def test_events_given_as_an_iterable_are_checked_like_a_files_lines() -> None:
    """``replay(iterable)``: objects and dict records pass the stream's rules; a bad one ends or is skipped."""
    from online_slam.pipeline import ReplayConfig, replay
    from online_slam.sources.events import Observation, Odometry, Start

    odo = {"sigma": (0.1, 0.1, 0.01)}
    seen = {"sigma": (0.1, 0.01)}
    good = [Start(0.0, (0.0, 0.0, 0.0)), Odometry(1.0, (1.0, 0.0, 0.0), **odo), Observation(1.0, 1, 2.0, 0.1, **seen)]
    good.append(Odometry(2.0, (1.0, 0.0, 0.0), **odo))
    bad = Observation(2.0, 1, float("nan"), 0.0, **seen)
    tail = [Observation(2.0, 1, 1.0, 0.1, **seen), Odometry(3.0, (1.0, 0.0, 0.0), **odo)]
    stopped = replay([*good, bad, *tail], ReplayConfig(estimators=("ekf",)))
    assert stopped.error == "<events>:5: range: expected a finite number, got NaN" and stopped.poses == 3
    skipped = replay([*good, bad, *tail], ReplayConfig(estimators=("ekf",), on_error="skip"))
    assert skipped.error is None and skipped.poses == 4 and skipped.input.skipped_lines == 1
    records = replay([e.to_record() for e in (*good, *tail)], ReplayConfig(estimators=("ekf",)))
    assert records.poses == 4 and records.observations == 2
    with pytest.raises(InputError, match=r"<events>:1: expected an event or a stream-v1 record, got str"):
        replay(["start"])
    in_degrees = {"type": "observation", "t": 1.0, "landmark": 1, "range": 2.0, "bearing": 45.0, "sigma": [0.1, 0.01]}
    refused = replay([e.to_record() for e in good[:3]] + [in_degrees], ReplayConfig(estimators=("ekf",)))
    assert refused.error.startswith("<events>:4: bearing: expected radians within [-2 pi, 2 pi], got 45.0")


def test_hidden_true_landmark_is_read_written_and_left_out_when_absent(tmp_path: Path) -> None:
    """``truth_landmark``: an int or a non-empty string id, as a landmark's; absent (or null) when None."""
    path = tmp_path / "hidden.jsonl"
    unknown = {k: v for k, v in OK_OBS.items() if k != "landmark"}
    lines = [OK_ODO, {**unknown, "truth_landmark": 3}, {**OK_OBS, "truth_landmark": "tree-7"}, {**OK_OBS}]
    lines.append({**unknown, "truth_landmark": None})
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    events = list(read_stream(path))
    assert [(e.landmark, e.truth_landmark) for e in events[1:]] == [(None, 3), (3, "tree-7"), (3, None), (None, None)]
    assert events[1].to_record() == {**unknown, "t": 1.0, "truth_landmark": 3}
    assert "truth_landmark" not in events[3].to_record() and "truth_landmark" not in events[4].to_record()
    again = tmp_path / "again.jsonl"
    write_stream(again, events)
    assert list(read_stream(again)) == events
