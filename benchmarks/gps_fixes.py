"""Victoria Park with GPS fixes: the raw log replayed twice against the same held-back GPS, without and with one
GPS reading every ``--every`` seconds given as a ``position`` fix (``python -m benchmarks.gps_fixes``).

Both replays read the stream the importer writes with ``--gps-fix-every``: its truth leaves out the readings used
as fixes, so both are scored against the same held-back GPS; the run without fixes drops the ``position`` lines.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Iterator

import numpy as np

from online_slam.importers.acfr import AcfrOptions
from online_slam.importers.acfr.reader import read_acfr
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sources.events import Event, Position

DATA = "../shared/data/victoria_park_acfr_ascii"
"""The raw log's folder, from a worktree of the repository."""


def events(folder: str, every: float, sigma: float, fixes: bool) -> Iterator[Event]:
    """The log's events with GPS fixes every ``every`` seconds, or without them (the same truth)."""
    for event in read_acfr(folder, fixes=(every, sigma)):
        if fixes or not isinstance(event, Position):
            yield event


SINCE = (0.0, 2.0, 5.0, 10.0, 20.0, 30.0)
"""Bins of seconds since the last fix for the online error's breakdown."""


def since_last_fix(times: np.ndarray, errors: np.ndarray, fixes: np.ndarray) -> dict[str, float]:
    """Online position RMSE by seconds since the last fix (the same bins with or without fixes given)."""
    k = np.searchsorted(fixes, times, side="right") - 1
    since = np.where(k >= 0, times - fixes[np.maximum(k, 0)], np.nan)
    out = {}
    for a, b in zip(SINCE[:-1], SINCE[1:], strict=True):
        e = errors[(since >= a) & (since < b) & np.isfinite(errors)]
        out[f"{a:g}-{b:g} s"] = round(float(np.sqrt(np.mean(e**2))), 3) if len(e) else float("nan")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=DATA, help="the raw Victoria Park folder")
    parser.add_argument("--every", type=float, default=30.0, help="seconds between GPS fixes")
    parser.add_argument("--sigma", type=float, default=AcfrOptions().gps_sigma, help="GPS fix sigma, metres")
    parser.add_argument("--estimators", default="ekf,smoother", help="estimators to run")
    args = parser.parse_args()
    config = ReplayConfig(estimators=tuple(args.estimators.split(",")))
    figures, medians = {}, {}
    fix_times = np.array([e.t for e in events(args.data, args.every, args.sigma, True) if isinstance(e, Position)])
    for label, fixes in (("without fixes", False), ("with fixes", True)):
        results = replay(events(args.data, args.every, args.sigma, fixes), config, name=label)
        figures[label] = {name: row.final_rmse_m for name, row in results.rows().items()}
        online = {name: row.online_rmse_m for name, row in results.rows().items()}
        print(label, "online", json.dumps(online), flush=True)
        print(label, "final", json.dumps(figures[label]), flush=True)
        used = {
            name: {k: v for k, v in e.info.items() if k.startswith("fixes_")} for name, e in results.estimates.items()
        }
        print(label, "fixes", json.dumps(used), flush=True)
        for name, series in results.series.items():
            by = since_last_fix(series.t, series.position_error_m, fix_times)
            print(label, name, "online RMSE by time since the last fix", json.dumps(by), flush=True)
            errors = series.position_error_m[np.isfinite(series.position_error_m)]
            medians[(label, name)] = float(np.median(errors))
            spread = {f"p{q}": round(float(np.percentile(errors, q)), 3) for q in (50, 90, 99)}
            print(label, name, "online error percentiles", json.dumps(spread), flush=True)
    for name, base in figures["without fixes"].items():
        fixed = figures["with fixes"][name]
        if base and fixed is not None:
            print(f"{name}: {fixed:.3f} m / {base:.3f} m = {fixed / base:.3f}")
    for (label, name), median in medians.items():
        if label == "with fixes" and ("without fixes", name) in medians:
            base = medians[("without fixes", name)]
            print(f"{name} online median error: {median:.3f} m / {base:.3f} m = {median / base:.3f}")


if __name__ == "__main__":
    main()
