"""What a Rerun recording of every configuration costs ``compare``: time with and without ``--rrd``, and size.

Both runs are the library call behind ``online-slam compare`` (EKF, smoother W=20 K=1, batch), interleaved, best
of N each; the recording run adds the Rerun sink the CLI adds for ``--rrd``.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from online_slam.compare import CompareConfig, compare, replay_config
from online_slam.pipeline import estimator_names
from online_slam.sinks.recording import Layout, RerunConfig, RerunSink

SHIPPED = Path(__file__).resolve().parents[1] / "replay" / "mrclam6_robot1.jsonl.gz"
"""The MRCLAM Dataset 6 robot 1 stream in the repository's ``replay/`` folder, beside ``benchmarks/``."""


@dataclass(frozen=True)
class RecordingCost:
    """Best-of-N wall times of one comparison with and without a recording."""

    source: str
    """The stream compared."""
    poses: int
    """Its poses."""
    configurations: tuple[str, ...]
    """Estimators in the table (and the recording)."""
    plain_s: float
    """``compare`` alone."""
    recorded_s: float
    """``compare`` writing the ``.rrd``."""
    size_mib: float
    """Size of the recording, MiB."""


def measure_recording_cost(source: str | Path = SHIPPED, repeats: int = 3) -> RecordingCost:
    """Time ``compare`` on ``source`` without and with a recording of every configuration."""
    config = CompareConfig()
    folder = Path(tempfile.mkdtemp(prefix="online-slam-rrd-bench-"))
    plain, recorded, size, poses, names = [], [], 0.0, 0, ()
    try:
        for k in range(max(1, repeats)):
            started = time.perf_counter()
            comparison = compare(source, config)
            plain.append(time.perf_counter() - started)
            path = folder / f"run{k}.rrd"
            layout = Layout(*estimator_names(replay_config(config)))
            started = time.perf_counter()
            sink = RerunSink(RerunConfig(path=str(path)), str(source), layout)
            compare(source, config, sinks=[sink])
            recorded.append(time.perf_counter() - started)
            size = path.stat().st_size / 2**20
            poses, names = comparison.results.poses, layout.names[1:]
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return RecordingCost(str(source), poses, names, min(plain), min(recorded), size)
