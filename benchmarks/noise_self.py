"""``--noise self`` measured: the noise calibrated from the data alone, against the truth of what was misdeclared.

- ``simulated``: the grid world (or ``--world``: ``waypoint``, ``circle`` with range-bearing sightings, ``meet``:
  three robots of ``--poses`` / 3 poses each; 2000 poses, ``--poses``), seeds ``--first-seed`` (7) on, drawn with its
  true sigmas and declared with 0.3x and 3x the sigma, odometry and sensor separately (each covariance times 0.09
  or 9, built with :func:`~online_slam.frontend.noise.scaled_event`). For each: the recovered scale's relative error
  against the true one (1/0.09 or 1/9), and the EKF's and the smoother's online RMSE and mean NEES replayed with
  ``--noise self``, beside the stream declared right.
- ``mrclam``: Dataset 6, each robot and all five: the built-in model (fitted against Vicon), ``--noise self`` as it
  is (a stream that says ``sightings_correlated`` gets the odometry scale only), ``--noise self`` the other way (its
  sensor scale and biases applied too), and the stream with its odometry or its sightings' covariances times 0.09
  or 9, replayed as declared and with ``--noise self``.
- ``own``: Dataset 6's robots declared right: the sensor scale each reads against its sightings' own covariances,
  their range (the model's ``own_scale_range``), and how far each reading falls outside the other robots' range
  (left out).

One replay at a time: ``python -m benchmarks.noise_self simulated [--world grid] [--seeds 20] [--poses 2000]``,
``python -m benchmarks.noise_self mrclam [--folder PATH] [--streams 1,2,3,4,5,all]`` and
``python -m benchmarks.noise_self own [--folder PATH]``. Each replay's line is printed
as it finishes, then the summary.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from online_slam.evaluation.noise_self import SelfFit
from online_slam.frontend.noise import scaled_event
from online_slam.importers.mrclam.reader import read_mrclam
from online_slam.importers.mrclam.robots import read_mrclam_robots
from online_slam.pipeline import replay
from online_slam.pipeline.config import ReplayConfig
from online_slam.pipeline.noise import Fit, fit_source_noise, with_noise_fit
from online_slam.sources.events import Event
from online_slam.sources.meet import MeetConfig, meet_world
from online_slam.sources.worlds import (
    CircleConfig,
    GridConfig,
    WaypointConfig,
    circle_world,
    grid_world,
    waypoint_world,
)

FOLDER = "../shared/data/MRCLAM_Dataset6"
MISDECLARED = {
    "odometry 0.3x": (0.09, 1.0),
    "odometry 3x": (9.0, 1.0),
    "sensor 0.3x": (1.0, 0.09),
    "sensor 3x": (1.0, 9.0),
}
"""Each misdeclaration: the factors (odometry, sensor) the declared covariances are multiplied by."""
ONLINE = ("ekf", "smoother")


@dataclass(frozen=True)
class Figures:
    """One replay's figures (position RMSE against truth, metres)."""

    online: dict[str, float]
    """Online RMSE of the EKF and the smoother."""
    final: dict[str, float]
    """Final RMSE of every estimator run."""
    nees: dict[str, float]
    """Mean NEES of the EKF and the smoother."""
    fit: SelfFit | None = None
    """The self-fit the replay ran with, if any."""

    def line(self) -> str:
        """The figures on one line."""
        online = "  ".join(f"{k} {self.online[k]:.3f} m NEES {self.nees[k]:.2f}" for k in ONLINE)
        final = "  ".join(f"{k} {v:.3f}" for k, v in self.final.items())
        scales = "" if self.fit is None else f"  [scales {self.fit.odometry_scale:.3g} / {self.fit.sensor_scale:.3g}]"
        return f"online: {online}  final: {final}{scales}"


def figures(events: Iterable[Event], config: ReplayConfig) -> Figures:
    """Replay and take the figures (and the self-fit it printed, with ``--noise self``)."""
    told: list[Fit] = []
    results = replay(events, config, on_noise_fit=told.append)
    e = results.estimators
    fit = told[0] if told and isinstance(told[0], SelfFit) else None
    return Figures(
        {k: e[k].online_rmse_m for k in ONLINE},
        {k: e[k].final_rmse_m for k in config.estimators},
        {k: e[k].nees_mean for k in ONLINE},
        fit,
    )


def misdeclared(events: Sequence[Event], factors: tuple[float, float]) -> list[Event]:
    """The stream with its declared odometry and sighting covariances multiplied by ``factors``."""
    return cast("list[Event]", [scaled_event(e, *factors) for e in events])  # stream events stay events


def self_config(config: ReplayConfig) -> ReplayConfig:
    """The configuration with ``--noise self``."""
    return dataclasses.replace(config, dataset={**config.dataset, "noise": "self"})


# -- simulated ------------------------------------------------------------------------------------------------
WORLDS: dict[str, Callable[[int, int], Iterable[Event]]] = {
    "grid": lambda poses, seed: grid_world(GridConfig(poses=poses, seed=seed)),
    "waypoint": lambda poses, seed: waypoint_world(WaypointConfig(poses=poses, seed=seed)),
    "circle": lambda poses, seed: circle_world(CircleConfig(poses=poses, seed=seed, model="range-bearing")),
    "meet": lambda poses, seed: meet_world(MeetConfig(poses=poses // 3, seed=seed)),
}
"""The simulated worlds, by (poses, seed)."""


def simulated(
    seeds: int, poses: int, say: Callable[[str], None] = print, world: str = "grid", first_seed: int = GridConfig.seed
) -> dict[str, dict[str, float]]:
    """Every seed and misdeclaration (see the module's docstring); the summary per misdeclaration."""
    config = ReplayConfig(estimators=ONLINE)
    rows: dict[str, list[tuple[float, float, Figures, Figures]]] = {name: [] for name in MISDECLARED}
    for seed in range(first_seed, first_seed + seeds):
        events = list(WORLDS[world](poses, seed))
        right = figures(events, config)
        say(f"seed {seed} declared right: {right.line()}")
        for name, factors in MISDECLARED.items():
            got = figures(misdeclared(events, factors), self_config(config))
            assert got.fit is not None  # --noise self told its fit
            errors = (got.fit.odometry_scale * factors[0] - 1.0, got.fit.sensor_scale * factors[1] - 1.0)
            fitted, other = errors if factors[0] != 1.0 else errors[::-1]
            rows[name].append((fitted, other, got, right))
            say(f"seed {seed} {name} --noise self: scale error {fitted:+.3f} (other {other:+.3f}); {got.line()}")
    summary = {name: _summary(cells) for name, cells in rows.items()}
    say(f"\nworst / median over {seeds} seeds (RMSE x: online RMSE with --noise self over the stream declared right)")
    columns = ("scale error", "other scale error", *(f"{k} RMSE x" for k in ONLINE), *(f"{k} NEES" for k in ONLINE))
    say("misdeclared    " + "".join(f"{c:>20}" for c in columns) + "  ekf NEES declared right")
    for name, s in summary.items():
        cells = [f"{s[c + ' worst']:.3f} / {s[c + ' median']:.3f}" for c in columns]
        right = f"{s['ekf NEES declared right worst']:.2f} / {s['ekf NEES declared right median']:.2f}"
        say(f"{name:<15}" + "".join(f"{c:>20}" for c in cells) + f"  {right:>23}")
    return summary


def _summary(cells: list[tuple[float, float, Figures, Figures]]) -> dict[str, float]:
    """Worst and median of the scale errors, the RMSE ratios (self over declared right) and the NEES."""
    out = {}
    columns = {
        "scale error": [abs(c[0]) for c in cells],
        "other scale error": [abs(c[1]) for c in cells],
        **{f"{k} RMSE x": [c[2].online[k] / c[3].online[k] for c in cells] for k in ONLINE},
        **{f"{k} NEES": [c[2].nees[k] for c in cells] for k in ONLINE},
        "ekf NEES declared right": [c[3].nees["ekf"] for c in cells],
    }
    for name, values in columns.items():
        out[f"{name} worst"] = float(np.max(values))
        out[f"{name} median"] = float(np.median(values))
    return out


# -- MRCLAM ---------------------------------------------------------------------------------------------------
def mrclam(folder: str, streams: Sequence[str], say: Callable[[str], None] = print) -> None:
    """Every stream and variant of the module's docstring, one line each."""
    config = ReplayConfig()
    for stream in streams:
        events = list(read_mrclam_robots(folder) if stream == "all" else read_mrclam(folder, int(stream)))
        say(f"{stream} built-in: {figures(events, config).line()}")
        fitted = figures(events, self_config(config))
        say(f"{stream} --noise self: {fitted.line()}")
        assert fitted.fit is not None  # --noise self told its fit
        say(f"{stream}   biases: {[(b.sensor, b.range_m, b.bearing_rad, b.significant) for b in fitted.fit.biases]}")
        applied = with_noise_fit(config, dataclasses.replace(fitted.fit, sightings_correlated=False))
        say(f"{stream} --noise self, sensor scale and biases applied: {figures(events, applied).line()}")
        for name, factors in MISDECLARED.items():
            wrong = misdeclared(events, factors)
            say(f"{stream} {name} as declared: {figures(wrong, config).line()}")
            say(f"{stream} {name} --noise self: {figures(wrong, self_config(config)).line()}")


def own(folder: str, robots: Sequence[int] = (1, 2, 3, 4, 5), say: Callable[[str], None] = print) -> dict[int, float]:
    """Each robot's own-covariance reading declared right (``--noise self``'s fit; no replay), their range, and the
    factor by which each reading falls outside the other robots' range (1: inside)."""
    readings: dict[int, float] = {}
    for robot in robots:
        fit, _ = fit_source_noise(list(read_mrclam(folder, robot)), self_config(ReplayConfig()))
        assert isinstance(fit, SelfFit) and fit.own_sensor_scale is not None  # MRCLAM's lines say their widening
        readings[robot] = fit.own_sensor_scale
        say(f"robot {robot}: own-covariance sensor scale {fit.own_sensor_scale:.4g}")
    say(f"range (own_scale_range) {min(readings.values()):.4g} - {max(readings.values()):.4g}")
    for robot, value in readings.items():
        others = [v for r, v in readings.items() if r != robot]
        if others:
            out = max(1.0, min(others) / value, value / max(others))
            say(f"robot {robot}: {out:.3g}x outside the other robots' range {min(others):.4g} - {max(others):.4g}")
    return readings


def main(argv: Sequence[str] | None = None) -> None:
    """Run one part (see the module's docstring)."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.noise_self", description=__doc__.splitlines()[0])
    parser.add_argument("part", choices=("simulated", "mrclam", "own"))
    parser.add_argument("--world", choices=tuple(WORLDS), default="grid", help="simulated: the world")
    parser.add_argument("--seeds", type=int, default=20, help="simulated: seeds")
    parser.add_argument("--first-seed", type=int, default=GridConfig.seed, help="simulated: the first seed")
    parser.add_argument("--poses", type=int, default=GridConfig.poses, help="simulated: poses of the world")
    parser.add_argument("--folder", default=FOLDER, help="mrclam, own: the Dataset 6 folder")
    parser.add_argument("--streams", default="1,2,3,4,5,all", help="mrclam: robots (1..5) and/or all")
    args = parser.parse_args(argv)
    if args.part == "simulated":
        simulated(args.seeds, args.poses, lambda text: print(text, flush=True), args.world, args.first_seed)
    elif args.part == "own":
        own(args.folder, say=lambda text: print(text, flush=True))
    else:
        mrclam(args.folder, args.streams.split(","), lambda text: print(text, flush=True))


if __name__ == "__main__":
    main()
