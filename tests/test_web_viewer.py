"""A comparison recording rendered by Rerun's own web viewer in headless Chromium: the map shows every estimate.

The viewer is served by ``rerun --serve-web`` (the rerun-sdk's binary) and rendered by Debian's ``chromium``
(``.ci/run`` installs it) driven by Playwright (dev extra) with the software rasterizer. The screenshot is kept at
``$ONLINE_SLAM_SCREENSHOT`` when that is set (for release notes); otherwise in the test's temporary folder.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rerun", reason="rerun-sdk is not installed")
playwright = pytest.importorskip("playwright.sync_api", reason="playwright (dev extra) is not installed")
Image = pytest.importorskip("PIL.Image", reason="Pillow is not installed")

from online_slam.sinks.recording import Layout  # noqa: E402

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="no chromium (.ci/run installs Debian's package)")

FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",  # this machine's network is closed: no background connections
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",  # WebGL on the CPU
    "--enable-unsafe-swiftshader",
]
SIZE = (1400, 900)
CONFIGS = ("odometry", "ekf", "smoother W=10..120 D=18 K=1 invariant", "smoother W=20..120 D=18 K=1 invariant", "batch")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_http(url: str, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(url, timeout=2) as response:
                if response.status == 200:
                    return
        except OSError:
            time.sleep(0.2)
    raise AssertionError(f"the web viewer never answered at {url}")


def _map_pixels(shot: np.ndarray, rgb: tuple[int, int, int], tolerance: int = 30) -> int:
    """Pixels of this colour in the map view (the left 3/5 of the layout, below the top bar)."""
    h, w, _ = shot.shape
    region = shot[int(0.06 * h) : int(0.94 * h), : int(0.58 * w)].astype(int)
    return int((np.abs(region - np.array(rgb)).max(axis=2) <= tolerance).sum())


def test_web_viewer_draws_every_configuration_on_the_map(tmp_path: Path, processes) -> None:
    rrd = tmp_path / "c.rrd"
    exe = shutil.which("online-slam")
    assert exe is not None
    done = subprocess.run(
        [exe, "compare", "square", "--window", "10,20", "--rrd", str(rrd), "--quiet"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    grpc, web = _free_port(), _free_port()
    processes(
        ["rerun", "--serve-web", "--port", str(grpc), "--web-viewer-port", str(web), str(rrd)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    _wait_http(f"http://127.0.0.1:{web}/", timeout=60)
    url = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy"
    shot_path = Path(os.environ.get("ONLINE_SLAM_SCREENSHOT") or tmp_path / "viewer.png")
    colors = Layout(CONFIGS[:-1], CONFIGS[-1:]).colors()
    counts: dict[str, int] = {}
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=FLAGS)
        try:
            page = browser.new_page(viewport={"width": SIZE[0], "height": SIZE[1]})
            page.goto(url)
            deadline = time.monotonic() + 120  # the viewer's wasm compiles on the CPU first
            while time.monotonic() < deadline:
                time.sleep(2)
                page.screenshot(path=str(shot_path))
                shot = np.asarray(Image.open(shot_path).convert("RGB"))
                counts = {name: _map_pixels(shot, colors[name]) for name in CONFIGS}
                if min(counts.values()) >= 150:
                    break
        finally:
            browser.close()
    shot = np.asarray(Image.open(shot_path).convert("RGB"))
    assert shot.shape[:2] == (SIZE[1], SIZE[0])
    assert shot.std() > 10 and len(np.unique(shot.reshape(-1, 3), axis=0)) > 500, "blank screenshot"
    assert min(counts.values()) >= 150, f"map pixels per estimator colour: {counts}"
    assert _map_pixels(shot, colors["truth"]) >= 150  # the true path and landmarks in grey
