"""The streams shipped in replay/ read cleanly and replay without a false alarm; square.jsonl is what the
simulator writes (to 1e-12)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
from conftest import REPLAY, SHARED_DATA, assert_close, needs_data

import online_slam
from online_slam.estimators import BatchConfig, SmootherConfig
from online_slam.estimators.smoother import WindowConfig
from online_slam.pipeline import ReplayConfig
from online_slam.sources import read_stream, square_world, write_stream

STREAMS = sorted(p for p in REPLAY.iterdir() if p.name.endswith((".jsonl", ".jsonl.gz")))


MRCLAM = SHARED_DATA / "MRCLAM_Dataset6"


@needs_data("MRCLAM_Dataset6")
def test_the_shipped_mrclam_stream_is_what_the_conversion_writes() -> None:
    """The shipped robot-1 stream is today's conversion, header included (``--noise fit`` reads it)."""
    from online_slam.importers.mrclam.reader import read_mrclam

    shipped = list(read_stream(REPLAY / "mrclam6_robot1.jsonl.gz"))
    assert_close(shipped, list(read_mrclam(MRCLAM, 1)), rtol=1e-12)  # sin, cos, exp: last bits differ by CPU
    assert shipped[0].meta["sightings_correlated"] is True
    assert shipped[0].meta["sightings_own_scale"] == {"range": [0.197, 0.509], "spread": 1.6}
    assert shipped[0].meta["odometry_bias"] == [0.05, 0.01]


def test_square_is_the_simulators_output(tmp_path: Path) -> None:
    write_stream(tmp_path / "square.jsonl", square_world())
    fresh = list(read_stream(tmp_path / "square.jsonl"))
    assert_close(list(read_stream(REPLAY / "square.jsonl")), fresh, rtol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("path", STREAMS, ids=[p.name for p in STREAMS])
def test_shipped_stream_replays(path: Path) -> None:
    assert sum(1 for _ in read_stream(path)) > 0
    # What is checked here does not depend on the window's size; sized by motion (the default) it keeps ~33 poses
    # of Victoria Park, which doubles this test's time: a 20-pose window keeps the suite within its budget.
    config = ReplayConfig(batch=BatchConfig(initial="ekf"), smoother=SmootherConfig(window=WindowConfig(distance=0.0)))
    if path.name.startswith("victoria_park"):
        # The smoother is two thirds of this replay's time (33 of 49 s) and is not what is checked on this stream
        # (the batch's minimum, started from the EKF); the shipped MRCLAM and cityTrees streams replay it.
        config = replace(config, estimators=("ekf", "batch"))
    warned: list[str] = []
    results = online_slam.replay(path, config, on_warning=warned.append)
    assert results.error is None and results.poses > 1
    # a clean stream raises no false alarm (tests/test_units.py checks the built-in worlds)
    assert warned == [] and results.warning is None
    if results.odometry.rmse_m is not None:  # with truth, every estimator beats dead reckoning
        for name, result in results.estimators.items():
            assert result.final_rmse_m < results.odometry.rmse_m, name
    if path.name.startswith("victoria_park"):
        # No truth: the batch's minimum is checked instead. GTSAM's best on the same data is chi-square 4,678
        # (LM started from iSAM2's result; ANCHORS.md); issue 12 asks for <= 4,700. LM from composed odometry
        # stops at 210,199.
        chi2 = 2.0 * results.estimators["batch"].details["final_cost"]
        assert chi2 <= 4700.0, chi2
