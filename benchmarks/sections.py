"""The benchmark sections: each measures, then prints its table and its ratios against peers run alongside."""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from online_slam.errors import OnlineSlamError
from online_slam.sources.worlds import GridConfig

if TYPE_CHECKING:
    from benchmarks.big import BigRow


def _repeats(args: argparse.Namespace, default: int = 3) -> int:
    """Timed repeats of a measurement: ``--repeats`` if given, else ``default``."""
    return max(1, default if args.repeats is None else args.repeats)


def _batch(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.batch import run_batch_bench  # with GTSAM: imported when a section needs it

    bench = run_batch_bench(world, repeats=_repeats(args))
    print(
        f"batch solve: grid world, {bench.poses} poses, {bench.landmarks} landmarks, "
        f"{bench.observations} observations (best of {_repeats(args)}, from composed odometry)"
    )
    print(f"{'solver':<28}{'time s':>10}{'iterations':>12}{'final 0.5*chi2':>18}")
    for t in [bench.ours] + ([bench.peer] if bench.peer else []):
        print(f"{t.label:<28}{t.seconds:>10.3f}{t.iterations:>12d}{t.final_cost:>18.3f}")
    if bench.peer:
        print(f"ratio online-slam / GTSAM: {bench.ours.seconds / bench.peer.seconds:.2f}x (target <= 2x)")
    else:
        print("GTSAM not installed: pip install '.[peers]' to measure the ratio")


def _ekf_update(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.ekf import time_updates

    try:
        counts = tuple(int(v) for v in args.landmarks.split(",") if v.strip())
    except ValueError:
        raise OnlineSlamError(f"--landmarks: expected comma-separated integers, got {args.landmarks!r}") from None
    print("EKF update with one range-bearing observation: structured vs filterpy's stock ExtendedKalmanFilter.update")
    print(f"{'landmarks':>10}{'state':>8}{'structured ms':>16}{'stock ms':>12}{'speed-up':>10}")
    for t in time_updates(counts):
        ratio = t.stock_ms / t.structured_ms
        print(f"{t.landmarks:>10d}{3 + 2 * t.landmarks:>8d}{t.structured_ms:>16.3f}{t.stock_ms:>12.3f}{ratio:>9.1f}x")
    print("target: >= 10x at 500 landmarks")


def _online_steps(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.ekf import paired_rounds, time_smoother, time_steps

    n, rows = time_steps(world)
    windows = tuple(int(w) for w in args.windows.split(",") if w.strip())
    rows[1:1] = time_smoother(world, windows)
    print(f"online step latency: grid world, {n} poses (one update per step; iSAM2 relinearizeSkip 1, threshold 0.01)")
    print("(smoother W=... rows: the window alone, no global relinearization)")
    print(f"{'estimator':<20}{'median ms':>11}{'p95 ms':>9}{'p99 ms':>9}{'max ms':>9}{'online RMSE m':>15}")
    for r in rows:
        print(
            f"{r.label:<20}{r.median_ms:>11.3f}{r.p95_ms:>9.3f}{r.p99_ms:>9.3f}{r.max_ms:>9.2f}{r.online_rmse_m:>15.4f}"
        )
    peer = next((r for r in rows if r.label.startswith("GTSAM")), None)
    if peer is not None:
        for r in rows:
            if r is not peer and r.label != "smoother default":
                print(f"ratio {r.label} / iSAM2 median (runs above): {r.median_ms / peer.median_ms:.2f}x")
        rounds = paired_rounds(world, _repeats(args))
        median = [r.smoother_median_ms / r.peer_median_ms for r in rounds]
        p99 = [r.smoother_p99_ms / r.peer_p99_ms for r in rounds]
        print(f"smoother default and iSAM2 back to back, {len(rounds)} rounds (alternating order), median ms: "
              + ", ".join(f"{r.smoother_median_ms:.2f} / {r.peer_median_ms:.2f}" for r in rounds))  # fmt: skip
        print(f"ratio smoother default / iSAM2 median: {np.median(median):.2f}x (rounds: "
              + ", ".join(f"{x:.2f}" for x in median) + ")")  # fmt: skip
        print(f"ratio smoother default / iSAM2 p99: {np.median(p99):.2f}x (rounds: "
              + ", ".join(f"{x:.2f}" for x in p99) + ")")  # fmt: skip
        print(f"target: smoother default median <= 1.0x iSAM2's: {_met(float(np.median(median)) <= 1.0)}")
        print(f"target: smoother default p99 <= 0.5x iSAM2's: {_met(float(np.median(p99)) <= 0.5)}")
    print(f"target: EKF median <= 2 ms: {_met(rows[0].median_ms <= 2.0)}")


def _met(ok: bool) -> str:
    return "met" if ok else "NOT met"


def _big(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.big import BIG_WORLD, run_big_world

    c = BIG_WORLD
    rows, batch = run_big_world(c)
    print(f"big world: grid {c.blocks}x{c.blocks} blocks of {c.block_size:g} m, {c.poses} poses, {c.landmarks} "
          f"landmarks placed, seed {c.seed}; batch final {batch[0]:.4f} m, landmarks {batch[1]:.4f} m")  # fmt: skip
    _big_table(rows, batch)


def _waypoint(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.big import WAYPOINT_WORLD, run_big_world

    w = WAYPOINT_WORLD
    rows, batch = run_big_world(w)
    print(f"waypoint world: {w.poses} poses {w.step:g} m apart towards random goals, {w.landmarks} landmarks "
          f"over {w.size:g} m, range {w.min_range:g}-{w.sensor_range:g} m, seed {w.seed}; "
          f"batch final {batch[0]:.4f} m, landmarks {batch[1]:.4f} m")  # fmt: skip
    _big_table(rows, batch)


def _big_table(rows: list[BigRow], batch: tuple[float, float]) -> None:
    """The big or waypoint world's table and targets: ours first, iSAM2 after when it ran."""
    print(f"{'estimator':<18}{'online m':>10}{'final m':>9}{'landm. m':>10}{'median ms':>11}{'p95':>8}{'p99':>8}"
          f"{'max':>9}{'total s':>9}")  # fmt: skip
    for r in rows:
        landmark = f"{r.landmark_rmse_m:>10.4f}" if r.landmark_rmse_m is not None else f"{'-':>10}"
        print(f"{r.label:<18}{r.online_rmse_m:>10.4f}{r.final_rmse_m:>9.4f}{landmark}{r.median_ms:>11.2f}"
              f"{r.p95_ms:>8.2f}{r.p99_ms:>8.2f}{r.max_ms:>9.1f}{r.total_s:>9.1f}")  # fmt: skip
    ours = rows[0]
    print(f"target: smoother final <= 1.05x batch: {ours.final_rmse_m / batch[0]:.3f}x, "
          f"{_met(ours.final_rmse_m <= 1.05 * batch[0])}")  # fmt: skip
    if ours.landmark_rmse_m is not None:
        ratio = ours.landmark_rmse_m / batch[1]
        print(f"target: smoother landmark RMSE <= 1.05x batch's: {ratio:.3f}x, {_met(ratio <= 1.05)}")
    peer = next((r for r in rows if r.label.startswith("GTSAM")), None)
    if peer is not None:
        online = ours.online_rmse_m / peer.online_rmse_m
        print(f"ratio smoother default / iSAM2 median: {ours.median_ms / peer.median_ms:.2f}x; "
              f"max: {ours.max_ms / peer.max_ms:.2f}x; online RMSE: {online:.2f}x")  # fmt: skip


def _api(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.api import measure_api_overhead

    # A few per cent between runs of a 1 s loop: the best of 5 (the default) is stable.
    repeats = _repeats(args, default=5)
    rows = measure_api_overhead(world, repeats=repeats)
    print(f"library API overhead: grid world, {world.poses} poses (best of {repeats}, interleaved)")
    print(
        f"{'estimator':<10}{'direct s':>10}{'Slam scans s':>14}{'overhead':>10}{'Slam sightings s':>18}{'overhead':>10}"
    )
    for r in rows:
        scans, single = r.scans_s / r.direct_s - 1.0, r.sightings_s / r.direct_s - 1.0
        print(
            f"{r.estimator:<10}{r.direct_s:>10.3f}{r.scans_s:>14.3f}{scans:>10.1%}{r.sightings_s:>18.3f}{single:>10.1%}"
        )
    for r in rows:
        verdict = "met" if r.scans_s <= 1.05 * r.direct_s else "NOT met"
        print(f"target: {r.estimator} through the API with scans <= 1.05x direct: {verdict}")


def _recording(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.recording import SHIPPED, measure_recording_cost

    source = args.recording_source or SHIPPED
    if args.recording_source is None and not SHIPPED.exists():
        raise OnlineSlamError(f"recording: the shipped stream {SHIPPED} is missing; give --recording-source")
    r = measure_recording_cost(source, repeats=_repeats(args))
    print(f"compare --rrd: {r.source} ({r.poses} poses; {', '.join(r.configurations)}), best of {_repeats(args)}")
    overhead = r.recorded_s / r.plain_s - 1.0
    print(f"compare {r.plain_s:.3f} s, with --rrd {r.recorded_s:.3f} s: overhead {overhead:.1%} "
          f"(target <= 30%: {'met' if overhead <= 0.30 else 'NOT met'}); recording {r.size_mib:.2f} MiB")  # fmt: skip


def _association(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.association import time_association

    scans = max(1, args.scans)
    rows = time_association(scans=scans)
    print(f"association without ids: time per scan (median of {scans} random scans) and share paired right")
    print(f"{'landmarks':>10}{'sightings':>11}{'nn ms':>9}{'nn right':>10}{'jcbb ms':>10}{'jcbb right':>12}")
    pairs = {(r.landmarks, r.sightings, r.method): r for r in rows}
    for m, k in sorted({(r.landmarks, r.sightings) for r in rows}):
        nn, jc = pairs[(m, k, "nn")], pairs[(m, k, "jcbb")]
        print(f"{m:>10}{k:>11}{nn.median_ms:>9.2f}{nn.accuracy:>10.1%}{jc.median_ms:>10.2f}{jc.accuracy:>12.1%}")


def _checkpoint(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.reliability import measure_checkpoint_overhead

    r = measure_checkpoint_overhead(world, every=100, repeats=_repeats(args))
    ratio = r.checkpointed_s / r.plain_s - 1.0
    print(
        f"checkpoint overhead: grid world, {r.poses} poses, EKF + smoother + batch, a checkpoint every {r.every} steps"
    )
    print(f"replay {r.plain_s:.3f} s, with checkpoints {r.checkpointed_s:.3f} s: overhead {ratio:.1%} "
          f"(last checkpoint {r.size_mib:.1f} MiB; best of {_repeats(args)})")  # fmt: skip
    print(f"target: overhead <= 10%: {'met' if ratio <= 0.10 else 'NOT met'}")


def _fuzz(args: argparse.Namespace, world: GridConfig) -> None:
    try:
        from benchmarks.fuzz import run_fuzz
    except ImportError:  # pragma: no cover - hypothesis is a dev extra
        raise OnlineSlamError("fuzz needs hypothesis: pip install '.[dev]'") from None
    started = time.perf_counter()
    report = run_fuzz(examples=max(1, args.fuzz_cases))
    print(f"fuzzing: {report.total} generated cases in {time.perf_counter() - started:.1f} s; only InputError came out")
    for name, count in report.cases.items():
        print(f"  {name:<16}{count:>7} cases, {report.input_errors.get(name, 0):>6} refused with InputError")


def _soak(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.reliability import soak

    runs = soak(poses=args.soak_poses)
    print(f"soak: grid world, {args.soak_poses} poses (190 landmarks: bounded map), one estimator per run, --rrd on")
    marks = sorted({m for r in runs for m in r.memory_mib})
    head = "".join(f"{'RSS@' + format(m, ','):>13}" for m in marks)
    print(
        f"{'estimator':<10}{head}{'first 10k ms':>16}{'last 10k ms':>15}{'online RMSE':>13}{'rrd MiB':>9}{'total s':>9}"
    )
    for r in runs:
        memory = "".join(f"{r.memory_mib.get(m, float('nan')):>10.0f} MiB" for m in marks)
        first, last = f"{r.first_ms[0]:.2f}/{r.first_ms[1]:.2f}", f"{r.last_ms[0]:.2f}/{r.last_ms[1]:.2f}"
        rmse = f"{r.online_rmse_m:.3f} m" if r.online_rmse_m is not None else "-"
        print(f"{r.estimator:<10}{memory}{first:>16}{last:>15}{rmse:>13}{r.rrd_mib:>9.1f}{r.total_s:>9.1f}")
    print("step times are median/p95; memory is the whole process (trajectory, truth and per-step figures kept)")


def _robust(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.robustness import run_robustness

    try:
        levels = sorted({0.0, *(float(v) for v in args.wrong_ids.split(",") if v.strip())})
    except ValueError:
        raise OnlineSlamError(f"--wrong-ids: expected fractions like 0.05,0.1, got {args.wrong_ids!r}") from None
    if not all(0.0 <= v < 1.0 for v in levels):
        raise OnlineSlamError(f"--wrong-ids: fractions must be in [0, 1), got {args.wrong_ids!r}")
    rows = run_robustness(world, tuple(levels))
    print(f"robustness: grid world, {world.poses} poses, a fraction of sightings given a wrong landmark id; default")
    print("flags; GTSAM iSAM2 with a Cauchy(3) kernel on the observations, same streams (position RMSE, m)")
    head = f"{'wrong ids':>10}{'EKF online':>12}{'smoother online':>17}{'smoother final':>16}{'batch final':>13}"
    print(f"{head}{'iSAM2 online':>14}{'iSAM2 final':>13}")
    for r in rows:
        peer = "".join(f"{v:>14.3f}" if v is not None else f"{'-':>14}" for v in (r.isam2_online,))
        peer += f"{r.isam2_final:>13.3f}" if r.isam2_final is not None else f"{'-':>13}"
        print(f"{r.wrong_ids:>10.0%}{r.ekf_online:>12.3f}{r.smoother_online:>17.3f}{r.smoother_final:>16.3f}"
              f"{r.batch_final:>13.3f}{peer}")  # fmt: skip
    clean = rows[0].batch_final
    for r in rows[1:]:
        worst_online = max(r.ekf_online, r.smoother_online) / clean
        worst_final = max(r.smoother_final, r.batch_final) / clean
        print(
            f"{r.wrong_ids:.0%} wrong ids: online <= {worst_online:.2f}x, final <= {worst_final:.2f}x the clean batch"
        )


def _mrclam(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.mrclam import HUBER, run_robot

    folder = Path(args.mrclam)
    print(f"MRCLAM Dataset 6: default smoother beside GTSAM iSAM2 + Huber {HUBER} on the same steps (ATE vs Vicon, m);")
    print("iSAM2 LS: iSAM2 without a kernel (plain least squares, the core of our default cost)")
    print(f"{'robot':<7}{'poses':>6}{'online':>9}{'iSAM2':>9}{'ratio':>7}{'iSAM2 LS':>10}{'final':>9}{'iSAM2':>9}"
          f"{'iSAM2 LS':>10}{'ms':>7}{'iSAM2 ms':>10}")  # fmt: skip

    def cell(v: float | None, width: int = 9) -> str:
        return f"{v:>{width}.3f}" if v is not None else f"{'-':>{width}}"

    met = 0
    for robot in range(1, 6):
        r = run_robot(folder, robot)
        ratio = f"{r.online_m / r.peer_online_m:>7.2f}" if r.peer_online_m else f"{'-':>7}"
        met += bool(r.peer_online_m and r.online_m <= r.peer_online_m)
        print(f"{r.robot:<7}{r.poses:>6}{r.online_m:>9.3f}{cell(r.peer_online_m)}{ratio}{cell(r.plain_online_m, 10)}"
              f"{r.final_m:>9.3f}{cell(r.peer_final_m)}{cell(r.plain_final_m, 10)}{r.median_ms:>7.2f}"
              f"{cell(r.peer_median_ms, 10)}")  # fmt: skip
    print(f"target: smoother online ATE <= iSAM2's per robot: {met} of 5 met")


def _heldout(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.heldout import TARGETS, run_heldout, worst

    cells = run_heldout(args.mrclam, args.workers)
    print("MRCLAM Dataset 6, held-out: the model fitted on one part, scored on another (defaults; RMSE vs Vicon, m)")
    print(f"{'fitted on, scored on':<44}{'stream':>7}{'EKF on':>8}{'sm. on':>8}{'EKF fin':>8}{'sm. fin':>8}"
          f"{'batch':>8}{'EKF NEES':>9}{'sm. NEES':>9}")  # fmt: skip
    for c in cells:
        mark = " *" if c.held_out else ""
        print(f"{c.scheme + mark:<44}{c.stream!s:>7}{c.online['ekf']:>8.3f}{c.online['smoother']:>8.3f}"
              f"{c.final['ekf']:>8.3f}{c.final['smoother']:>8.3f}{c.final['batch']:>8.3f}{c.nees['ekf']:>9.2f}"
              f"{c.nees['smoother']:>9.2f}")  # fmt: skip
        if c.so_far is not None:
            print(f"{'  every pose kept (MAP so far)':<51}{'':>8}{c.so_far[0]:>8.3f}{'':>32}{c.so_far[1]:>9.2f}")
    for whole_run, cells_of in ((False, "replays of a part"), (True, "whole runs, second half scored")):
        w = worst(cells, whole_run)
        print(f"* held out. Worst held-out figures, {cells_of}: online {w['online_m']:.3f} m (target <= "
              f"{TARGETS['online_m']:g}), mean NEES {w['nees']:.2f} (target <= {TARGETS['nees']:g}), smoother or "
              f"batch final / EKF final {w['final_over_ekf']:.2f}x (target <= 1.05x)")  # fmt: skip
    print("every pose kept (a one-robot replay of a part that misses a target): the smoother marginalizing nothing, "
          "each step approximately the MAP of the data so far; a miss it shares is not the window's or the "
          "filter's")  # fmt: skip


def _unknown_ids(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.unknown_ids import TARGET, run_unknown_ids

    pairs = run_unknown_ids(args.mrclam, args.workers)
    print("MRCLAM Dataset 6 without ids (--association jcbb) beside the barcodes (RMSE vs Vicon, m; known -> jcbb)")
    print(f"{'robot':<7}{'EKF online':>16}{'smoother final':>18}{'batch final':>16}{'ratio':>13}{'right':>7}"
          f"{'left out':>10}")  # fmt: skip
    met = 0
    for known, jcbb in pairs:
        ratio = max(jcbb.smoother_final / known.smoother_final, jcbb.batch_final / known.batch_final)
        met += ratio <= TARGET
        print(f"{known.robot!s:<7}{known.ekf_online:>7.3f} -> {jcbb.ekf_online:.3f}"
              f"{known.smoother_final:>9.3f} -> {jcbb.smoother_final:.3f}{known.batch_final:>7.3f} -> "
              f"{jcbb.batch_final:.3f}{ratio:>12.2f}x{jcbb.paired_right or 0.0:>7.3f}"
              f"{jcbb.left_out or 0:>10}")  # fmt: skip
    print(f"target: smoother and batch final within {TARGET}x the known-id figure: {met} of {len(pairs)} met")


def _odometry_bias(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.odometry_bias import BIAS, PRIORS, run_heldout, run_odometry_bias, table

    rows = run_odometry_bias(args.mrclam, args.workers)
    print(f"the EKF's odometry bias state (none; prior sigmas {PRIORS}): online RMSE m / mean NEES, each stream "
          f"as logged and biased ({BIAS[0]:.3f} of its distances, {BIAS[1]:g} rad/s added)")  # fmt: skip
    print(table(rows))
    if args.mrclam:
        print("held out (benchmarks.heldout's held-out cells; whole runs: their second half): EKF online m / mean "
              "NEES, without the bias state, then with each prior")  # fmt: skip
        cells = run_heldout(args.mrclam, args.workers)
        for scheme, stream, figures in cells:
            text = " | ".join(f"{online:.3f} / {nees:.2f}" for online, nees in figures)
            print(f"{scheme:<44}{stream:<5}{text}")
        for k, prior in enumerate(((0.0, 0.0), *PRIORS)):
            worst = max(f[k][0] for _, _, f in cells), max(f[k][1] for _, _, f in cells)
            better = sum(f[k][0] < f[0][0] for _, _, f in cells)
            print(f"prior {prior}: worst online {worst[0]:.3f} m, worst mean NEES {worst[1]:.2f}; "
                  f"{better} of {len(cells)} cells below the EKF without it")  # fmt: skip


def _misdeclared(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.misdeclared import MODES, run_misdeclared, verdicts

    rows = run_misdeclared(args.mrclam, args.workers)
    print("declared noise that is wrong (the data unchanged, sigmas declared 0.3x or 3x), --adapt-noise off and on "
          "(the default); RMSE m")  # fmt: skip
    print(f"{'stream':<16}{'declared':<16}{'adapt':<7}{'EKF on':>8}{'sm. on':>8}{'sm. fin':>8}{'batch':>8}"
          f"{'EKF NEES':>10}{'sm. NEES':>10}")  # fmt: skip
    for r in rows:
        print(
            f"{r.stream:<16}{r.case:<16}{r.adapt:<7}{r.online['ekf']:>8.3f}"
            f"{r.online['smoother']:>8.3f}{r.final['smoother']:>8.3f}{r.final['batch']:>8.3f}{r.nees['ekf']:>10.2f}"
            f"{r.nees['smoother']:>10.2f}"
        )
    for adapt in MODES:
        v = verdicts(rows, adapt)
        print(f"--adapt-noise {adapt}: worst online error / as declared "
              f"{v['online_ratio']:.2f}x (target <= 3x); worst smoother final / batch final "
              f"{v['smoother_over_batch']:.2f}x (target <= 1.5x); worst mean NEES {v['nees']:.2f}")  # fmt: skip


def _sweep(args: argparse.Namespace, world: GridConfig) -> None:
    from online_slam.sweep import make_cells, run_cell, sweep

    folder = Path(args.mrclam)
    cells = make_cells([str(folder)], windows=(20, 50, 100), robots=(1, 2, 3, 4, 5))
    started = time.perf_counter()
    for cell in cells:
        run_cell(cell)
    serial = time.perf_counter() - started
    started = time.perf_counter()
    report = sweep(cells, workers=2)
    parallel = time.perf_counter() - started
    n = len(cells)
    print(f"sweep: MRCLAM Dataset 6, 5 robots x 3 windows (20, 50, 100) = {n} replays, EKF + smoother + batch")
    print(f"one after the other: {serial:.1f} s; Dask LocalCluster with 2 workers: {parallel:.1f} s "
          f"(cluster start and stop included); speed-up {serial / parallel:.2f}x")  # fmt: skip
    overhead = (2 * parallel - serial) / n
    print(f"Dask overhead per task (time beyond a perfect 2x split, per replay): {overhead:.2f} s; "
          f"{report.failed} failed")  # fmt: skip


def _circle(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.circle import CIRCLE_WORLDS, ESDE, run_circle

    band, rows = run_circle(args.circle_runs, args.workers)
    print(f"circle worlds (esde's protocol): {args.circle_runs} Monte Carlo runs from seed 0;")
    print(f"figures over esde's steps 5..399 (0-based 4..398); 95% ANEES band: {band[0]:.2f} .. {band[1]:.2f}")
    head = f"{'ANEES':>7}{'in band':>9}{'landmark ANEES':>16}{'position RMSE m':>17}{'heading RMSE':>14}"
    print(f"{'world':<11}{'estimator':<34}{head}")
    for r in rows:
        landmark = f"{r.landmark_anees:>16.2f}" if r.landmark_anees is not None else f"{'-':>16}"
        print(f"{r.world:<11}{r.label:<34}{r.anees:>7.2f}{r.in_band:>9.0%}{landmark}{r.position_rmse_m:>17.4f}"
              f"{r.heading_rmse_rad:>14.4f}")  # fmt: skip
    print("; ".join(f"{name}: {what}" for name, what in CIRCLE_WORLDS.items()))
    for label, (anees, rmse) in ESDE.items():
        print(f"{'circle':<11}{'esde ' + label + ' (100 runs)':<34}{anees:>7.2f}{'':>25}{rmse:>17.4f}")
    from benchmarks.esde_port import run as port

    for at, label in (("estimate", "port of esde's standard EKF"), ("truth", "EKF with Jacobians at the truth")):
        p = port(range(args.circle_runs), jacobians_at=at)
        print(f"{'circle':<11}{label:<34}{p.anees:>7.2f}{p.in_band:>9.0%}{'-':>16}{p.position_rmse_m:>17.4f}")
    print(
        "(the port: esde's simulation and EKF written from its Matlab code, on the same draws as `circle`; at the "
        "truth: consistent by construction, the accuracy no EKF can expect to beat on these streams)"
    )


def _timing(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.timing import buffer_cost, latency_check, live_rows, mount_rows, same_time_change, twin_rows

    seeds = range(args.timing_seeds)
    print(f"sensor timing: the timing world (60 s at 1 m/s, odometry at 10 Hz, scans at 2 Hz), {len(seeds)} seeds;")
    print("mean online position RMSE (batch: final) and mean NEES over the seeds, errors after --align se2")

    def table(rows: list, reference: str) -> None:
        base = rows[0]
        print(f"{'stream':<58}{'EKF m':>8}{'smoother m':>12}{'batch m':>9}{'EKF NEES':>10}{'sm. NEES':>10}")
        for r in rows:
            o, n = r.online, r.nees
            print(f"{r.label:<58}{o['ekf']:>8.4f}{o['smoother']:>12.4f}{o['batch']:>9.4f}{n['ekf']:>10.2f}"
                  f"{n['smoother']:>10.2f}")  # fmt: skip
        for r in rows[1:]:
            ratios = ", ".join(f"{k} {r.online[k] / base.online[k]:.3f}x" for k in r.online)
            nees = ", ".join(f"{k} {r.nees[k] / base.nees[k]:.3f}x" for k in r.nees)
            print(f"  {r.label} / {reference}: RMSE {ratios}; NEES {nees}")

    table(twin_rows(seeds), "twin")
    print("the same in the first pose's frame (--align anchor: mostly the map's rotation against the start's frame)")
    table(twin_rows(seeds, align="anchor"), "twin")
    table(mount_rows(seeds), "centre")
    check = latency_check()
    print(f"arrival order (each sighting line 0-150 ms late, {check.out_of_order} after a later odometry line), "
          f"--max-latency 0.2: largest change of a figure {check.largest_change:.2e}, {check.skipped} skipped; "
          f"Slam in arrival order: trajectory within {check.slam_gap_m:.1e} m of the ordered feed "
          f"({check.slam_lag} poses still held), pose predicted to the last odometry within "
          f"{check.slam_now_gap_m:.1e} m")  # fmt: skip
    print(f"sightings written before the odometry of their time: largest change of a figure {same_time_change():.2e}")
    print("a robot's loop: Slam.estimate(at=t) at each odometry line's arrival, sightings 0-150 ms late, "
          "--max-latency 0.2 (position RMSE against the truth at t, mean over the seeds; worst ratio to the ordered "
          "feed over the seeds; median ms per odometry line: the lines added and the query)")  # fmt: skip
    print(f"{'estimator':<11}{'ordered m':>11}{'held=False m':>14}{'held=True m':>13}{'worst False':>13}"
          f"{'worst True':>12}{'ms ordered / False / True':>28}")  # fmt: skip
    for r in live_rows(seeds):
        ms = " / ".join(f"{v:.2f}" for v in r.query_ms)
        print(f"{r.estimator:<11}{r.ordered_m:>11.4f}{r.predicted_m:>14.4f}{r.held_m:>13.4f}{r.worst[0]:>12.3f}x"
              f"{r.worst[1]:>11.3f}x{ms:>28}")  # fmt: skip
    plain, held = buffer_cost(world.poses, _repeats(args))
    print(f"grid world {world.poses} poses, EKF and smoother: {plain:.2f} s without a reorder buffer, "
          f"{held:.2f} s with --max-latency 0.2: {held / plain:.3f}x (target <= 1.1x)")  # fmt: skip


def _live(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.live import TARGET_MS, measure_live_cost

    r = measure_live_cost(world, repeats=_repeats(args))
    print(f"live input: the grid world ({r.poses} poses, {r.lines} lines; replayed: its first {r.replay_poses} "
          f"poses, EKF, --max-latency 0.5) from a file and over TCP from a feeder process (best of "
          f"{_repeats(args)}, interleaved)")  # fmt: skip
    print(f"{'':<20}{'poses':>7}{'file s':>9}{'TCP s':>9}{'per step ms':>13}")
    print(f"{'reading alone, CPU':<20}{r.poses:>7}{r.read_file_s:>9.3f}{r.read_tcp_s:>9.3f}{r.per_step_ms:>13.4f}")
    print(f"{'replay, wall':<20}{r.replay_poses:>7}{r.file_s:>9.3f}{r.tcp_s:>9.3f}{r.replay_per_step_ms:>13.4f}")
    print(f"target: the socket costs <= {TARGET_MS} ms per step (reading alone; the replay adds the machine's "
          f"noise): {r.per_step_ms:.4f} ms, {_met(r.per_step_ms <= TARGET_MS)}")  # fmt: skip


Section = Callable[[argparse.Namespace, GridConfig], None]
"""Measures, then prints: given the options and the grid world they describe."""


def _bag(args: argparse.Namespace, world: GridConfig) -> None:
    from benchmarks.bags import time_reading

    root = Path(__file__).resolve().parents[1]
    raw = Path(os.environ.get("ONLINE_SLAM_DATA") or root.parent / "shared" / "data") / "victoria_park_acfr_ascii"
    if not raw.is_dir():  # the excerpt shipped in replay/
        raw = root / "replay" / "victoria_park_raw_45s"
    rows = time_reading(raw, _repeats(args))
    print(f"reading a ROS bag: raw Victoria Park ({raw.name}) as bags (benchmarks/bags.py), best of {_repeats(args)}")
    print(f"{'storage':<12}{'messages':>10}{'read s':>9}{'messages/s':>12}{'to events s':>13}{'messages/s':>12}")
    for name, n, read, events in rows:
        print(f"{name:<12}{n:>10d}{read:>9.3f}{n / read:>12,.0f}{events:>13.3f}{n / events:>12,.0f}")
    print("read: the topics decoded and the laser detector run; to events: all of the importer. Target >= 50,000/s")


SECTIONS: dict[str, Section] = {
    "batch": _batch,
    "ekf-update": _ekf_update,
    "online": _online_steps,
    "api": _api,
    "checkpoint": _checkpoint,
    "recording": _recording,
    "live": _live,
    "association": _association,
    "fuzz": _fuzz,
    "robust": _robust,
    "bag": _bag,
    "big": _big,
    "waypoint": _waypoint,
    "circle": _circle,
    "timing": _timing,
    "mrclam": _mrclam,
    "heldout": _heldout,
    "misdeclared": _misdeclared,
    "unknown-ids": _unknown_ids,
    "odometry-bias": _odometry_bias,
    "sweep": _sweep,
    "soak": _soak,
}
"""Every section by name, in the order they run."""
DEFAULT_SECTIONS = tuple(SECTIONS)[:-11]
"""The big and waypoint worlds (5000 poses beside iSAM2, minutes), the circle protocol (100 Monte Carlo runs,
minutes), the sensor timing (seeded worlds, minutes), MRCLAM, its held-out figures, misdeclared noise (worlds and
MRCLAM), MRCLAM without ids, the odometry bias state (worlds and MRCLAM), the sweep (MRCLAM data) and the soak
(100,000 poses, minutes) run only when asked for
(``--only``)."""
MRCLAM_SECTIONS = ("mrclam", "heldout", "unknown-ids", "sweep")
"""The sections that read the MRCLAM Dataset 6 folder (``--mrclam``)."""
