"""``online-slam inspect PATH.rrd``: read a recording back through Rerun's query API and summarise it, or show
one step of it (``--step N``)."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from online_slam.errors import OnlineSlamError


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "inspect",
        help="summarise a Rerun recording written by 'replay --rrd' or 'compare --rrd'",
        description="Read a recording back (no re-running): source, steps, time span, estimators, errors, latency.",
    )
    p.add_argument("path", help="a .rrd file written by 'online-slam replay --rrd' or 'compare --rrd'")
    p.add_argument("--step", type=int, metavar="N", help="print only the state at step N (poses, landmarks, events)")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")


def _fmt(value: object) -> str:
    return "-" if value is None else f"{value:.4f}" if isinstance(value, float) else str(value)


def _source(summary: Any) -> str:
    """The source, and its robot when the stream names one."""
    return summary.source if summary.robot is None else f"{summary.source}, robot {summary.robot}"


def run(args: argparse.Namespace) -> int:
    """Print the summary, or one step's state."""
    from online_slam.sinks.recording import Recording

    with Recording(args.path) as recording:
        summary = recording.summary()
        state = None
        if args.step is not None:
            if not 0 <= args.step < summary.steps:
                raise OnlineSlamError(f"--step: {args.step} is outside the recording's steps 0..{summary.steps - 1}")
            state = recording.state_at(args.step, summary.layout, summary.robots)
    if args.json:
        print(json.dumps(_json(summary, state), indent=2))
    elif state is not None:
        _print_step(args.path, summary, state)
    else:
        _print_summary(args.path, summary)
    return 0


def _json(summary: Any, state: dict[str, Any] | None) -> dict[str, Any]:
    """What ``inspect --json`` prints: the summary, or with ``--step`` that step's state alone."""
    head = {"source": summary.source, "robot": summary.robot, "robots": summary.robots, "steps": summary.steps}
    if state is not None:
        return {**head, "state": state}
    return {
        **head,
        "time_span_s": list(summary.time_span),
        "estimators": list(summary.estimators),
        "results": summary.results,
        "latency_ms": summary.latency_ms,
        "logged": summary.figures,
        "recording": summary.layout.to_json(),
    }


def _print_summary(path: str, summary: Any) -> None:
    t0, t1 = summary.time_span
    print(f"recording: {path}")
    print(f"source: {_source(summary)}")
    print(f"steps: {summary.steps}   time span: {t0:.3f} .. {t1:.3f} s ({t1 - t0:.3f} s)")
    print(f"estimators: {', '.join(summary.estimators)}")
    if summary.robots:
        print(f"robots: {', '.join(f'{robot} (entities .../{part})' for robot, part in summary.robots.items())}")
    if summary.results.get("error"):
        print(f"input stopped early: {summary.results['error']}")
    colors = summary.layout.to_json()["colors"]
    width = max([len("estimator"), *map(len, summary.estimators)]) + 2
    entities = {name: "/" + summary.layout.world(name) for name in summary.estimators}
    room = max([len("entity"), *map(len, entities.values())]) + 2
    header = f"{'estimator':<{width}}{'entity':<{room}}{'colour':<9}{'final RMSE m':>13}{'online RMSE m':>15}"
    print(header + f"{'landmark RMSE m':>17}{'step ms median/p95/max':>26}")
    for name, figures in summary.results.get("estimators", {}).items():
        lat = summary.latency_ms.get(name)
        latency = f"{lat['median']:.2f} / {lat['p95']:.2f} / {lat['max']:.2f}" if lat else "-"
        final = _fmt(figures.get("final_rmse_m"))
        print(
            f"{name:<{width}}{entities.get(name, '-'):<{room}}{colors.get(name, '-'):<9}{final:>13}"
            f"{_fmt(figures.get('online_rmse_m')):>15}{_fmt(figures.get('landmark_rmse_m')):>17}{latency:>26}"
        )
        for robot, mine in (figures.get("robots") or {}).items():
            label = f"  robot {robot}"
            final, online = _fmt(mine.get("final_rmse_m")), _fmt(mine.get("online_rmse_m"))
            print(f"{label:<{width + room + 9}}{final:>13}{online:>15}")
    if summary.figures:
        logged = ", ".join(
            f"{name} {f['online_rmse_m']:.4f} m / NEES "
            + (f"{f['nees_mean']:.2f}" if np.isfinite(f["nees_mean"]) else "- (no heading truth)")
            for name, f in summary.figures.items()
        )
        print(f"recomputed from the logged series (online RMSE / mean NEES): {logged}")


def _print_step(path: str, summary: Any, state: dict[str, Any]) -> None:
    """One step: each estimator's newest pose and landmark count (aligned whatever the names), then its events."""
    t = "" if state.get("t") is None else f", t = {state['t']:.3f} s"
    print(f"{path} ({_source(summary)}): step {state['step']} of 0..{summary.steps - 1}{t}")
    estimators = state["estimators"]
    width = max([len("estimator"), *map(len, estimators)]) + 2
    print(f"{'estimator':<{width}}{'x m':>10}{'y m':>10}{'theta rad':>11}{'landmarks':>11}")
    for name, est in estimators.items():
        x, y, th = est["pose"]
        print(f"{name:<{width}}{x:>10.3f}{y:>10.3f}{th:>11.3f}{est['landmarks']:>11d}")
    prefix = f"step {state['step']}: "
    events = [e.removeprefix(prefix) for e in state["events"]]
    print("events:" if events else "events: none")
    for event in events:
        print(f"  {event}")
