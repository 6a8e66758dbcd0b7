"""Every option of the engine, defined once: name, type, default, help, owner, help group, where it lands.

The table :data:`OPTIONS` is the only place an option is described. From it come the flags of ``replay``,
``compare``, ``sweep`` and ``convert`` (:func:`add_options`), the check of ``Slam(**options)``
(:func:`check_value`), the one translation of option values into a :class:`~online_slam.pipeline.ReplayConfig`
(:func:`replay_config`, used by the CLI, ``Slam`` and sweeps) and the docs' option list (:func:`markdown`,
``docs/options.md``). Defaults come from the configuration dataclasses, never typed by hand; an option that is
no configuration field (``robust``, the dataset's) holds its own default here. So that ``--help`` loads no
numerical library, the configuration dataclasses live in import-light modules (:data:`CONFIGS`), whose fields
are read directly.

After changing the table or a configuration default, regenerate the page:
``python -c "from online_slam.options import markdown; print(markdown(), end='')" > docs/options.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import importlib
import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

from online_slam.errors import ConfigError
from online_slam.importers import registry
from online_slam.option_values import bools, list_of, positive
from online_slam.sources.address import on_error_of
from online_slam.sources.worlds import WORLDS
from online_slam.wording import counted

if TYPE_CHECKING:
    from online_slam.pipeline import ReplayConfig

GROUPS = ("input", "estimators", "EKF", "smoother", "association", "outliers", "output", "live/checkpoint", "runs")
"""Help groups, in the order ``--help`` and the docs list them."""
ADVANCED = frozenset({
    "align", "first_observation_only", "keyframe_angle", "keyframe_time", "max_iterations", "gate_probability",
    "gate_persistence", "ekf_update", "ekf_linearization", "window_distance", "window_max", "relinearize_every",
    "global_every", "global_delay", "smoother_linearization", "global_information_max", "new_density", "convention",
    "pose_covariance", "rival",
})  # fmt: skip
"""The research knobs, by option name: what a user seldom sets. ``--help`` leaves them out, ``--help-all`` shows
them and docs/options.md marks them."""
ESTIMATOR_OWNERS = frozenset({"ekf", "smoother", "batch", "front-end", "association"})
"""Owners of the estimator options: those ``replay``, ``compare``, ``sweep`` and ``Slam`` all accept."""
_SHARED = frozenset({"front-end", "association"})
"""Owners whose options apply to every estimator."""
CONFIGS = {
    "ReplayConfig": "online_slam.pipeline.config",
    "Checkpointing": "online_slam.pipeline.config",
    "MapConfig": "online_slam.pipeline.config",
    "CompareConfig": "online_slam.compare_config",
    "BatchConfig": "online_slam.estimators.batch_config",
    "EkfConfig": "online_slam.estimators.ekf_config",
    "AssociationConfig": "online_slam.estimators.association_config",
    "AdaptationConfig": "online_slam.estimators.adaptation_config",
    "SmootherConfig": "online_slam.estimators.smoother.config",
    "WindowConfig": "online_slam.estimators.smoother.config",
    "GlobalConfig": "online_slam.estimators.smoother.config",
    "RobustLoss": "online_slam.factors.robust",
    "FrontEndConfig": "online_slam.frontend.steps",
    "KeyframeConfig": "online_slam.frontend.steps",
    "SolverConfig": "online_slam.solvers.config",
}
"""The import-light module of each configuration dataclass an option's default is read from."""
CHOICE_HOMES = {
    "association": ("online_slam.estimators.association_config", "ASSOCIATION_CHOICES"),
    "robust": ("online_slam.estimators.presets", "ROBUST_CHOICES"),
    "ekf_linearization": ("online_slam.estimators.ekf_config", "LINEARIZATIONS"),
    "smoother_linearization": ("online_slam.estimators.smoother.config", "LINEARIZATIONS"),
    "peer": ("online_slam.compare_config", "PEERS"),
    "pose_covariance": ("online_slam.estimators.ekf_config", "POSE_COVARIANCES"),
}
"""Where the choices of an option are defined: (module, name)."""
CHOICES: dict[str, tuple[str, ...]] = {
    name: getattr(importlib.import_module(home), attr) for name, (home, attr) in CHOICE_HOMES.items()
}
"""Allowed values of the options whose choices the estimators define, read from where they are defined."""


@dataclass(frozen=True)
class Option:
    """One option: ``--window-distance`` on the command line, ``window_distance=`` for ``Slam``."""

    name: str
    """Python name (``Slam`` keyword, parsed attribute); the flag is ``--`` + the name with ``-`` for ``_``."""
    help: str
    """One line for ``--help`` and the docs."""
    group: str
    """Help group (one of :data:`GROUPS`)."""
    owners: tuple[str, ...]
    """What it configures: ``ekf``, ``smoother``, ``batch``, ``front-end``, ``association`` (the estimator
    options), ``dataset``, ``replay`` (what runs and how it is scored) or ``cli`` (output, live, checkpoints)."""
    kind: type = str
    """Value type: ``int``, ``float``, ``str`` or ``bool`` (a flag without a value)."""
    field: tuple[str, str] | None = None
    """The configuration field the default is read from: (dataclass name in :data:`CONFIGS`, field name)."""
    default: Any = None
    """The default of an option that is no configuration field (None: not given)."""
    unset: str = ""
    """What happens when the option is not given, for options whose default is None (e.g. ``detected``)."""
    lands: tuple[str, ...] = ()
    """Where the value goes in a :class:`ReplayConfig`: dotted field paths (a dict's key last)."""
    choices: tuple[str, ...] = ()
    """Allowed values of a ``str`` option (empty: any)."""
    metavar: str | None = None
    """Placeholder of the value in ``--help``."""
    unit: str = ""
    """Unit of a number (``rad`` defaults are shown in degrees too)."""
    positive: bool = False
    """The value must be > 0: refused as the command line is parsed (every command that takes it, list items
    too) and by :func:`replay_config`."""
    commands: tuple[str, ...] = ("replay", "compare", "sweep")
    """Commands that take it."""
    nargs: str | None = None
    """argparse ``nargs`` (a positional's ``?``/``+``, ``?`` for an optional value)."""
    const: str | None = None
    """Value of a flag given without its optional value."""
    short: str = ""
    """A one-letter spelling besides the flag (``-o``), or empty."""
    parse: Callable[[str], Any] | None = None
    """How the command line's text becomes a value, when not by ``kind`` (``--robot``: a number or ``all``)."""

    @property
    def flag(self) -> str:
        """The command-line spelling (a positional's name as is)."""
        return self.name if self.positional else "--" + self.name.replace("_", "-")

    @property
    def positional(self) -> bool:
        """A positional argument (the source)."""
        return self.name in ("source", "sources")

    @property
    def value(self) -> Any:
        """The default value (the configuration field's, read from its dataclass)."""
        if self.field is None or self.unset:
            return self.default
        value = field_default(self.field)
        return ",".join(value) if isinstance(value, tuple) else value

    @property
    def estimator(self) -> bool:
        """An estimator option (``Slam`` and ``sweep`` take it)."""
        return set(self.owners) <= ESTIMATOR_OWNERS

    def fits(self, estimator: str) -> bool:
        """Whether it configures this estimator (or every estimator)."""
        return estimator in self.owners or bool(_SHARED & set(self.owners))

    def shown_default(self) -> str:
        """The default as a user reads it (``0.35 rad (20.1 deg)``, ``off``...)."""
        if self.unset and self.field is not None and field_default(self.field) is not None:
            return f"{self.unset}; {readable(field_default(self.field), self.unit)} once another is given"
        if self.unset or self.value is None:
            return self.unset
        return readable(self.value, self.unit)


@functools.cache
def field_default(field: tuple[str, str]) -> Any:
    """A configuration field's default value (its factory's product when it has one), read from the dataclass."""
    cls = getattr(importlib.import_module(CONFIGS[field[0]]), field[0])
    spec = next(f for f in dataclasses.fields(cls) if f.name == field[1])
    if spec.default is not dataclasses.MISSING:
        return spec.default
    factory = cast("Callable[[], Any]", spec.default_factory)  # a configuration field without a default has one
    return factory()


def readable(value: Any, unit: str = "") -> str:
    """A value for people: ``0.5``, ``inf``, ``0.35 rad (20.1 deg)``, ``18 m``."""
    if isinstance(value, bool) or value is None:
        return {True: "on", False: "off", None: "none"}[value]
    if isinstance(value, float) and math.isinf(value):
        return "no limit"
    text = f"{value:g}" if isinstance(value, float) else str(value)
    if unit == "rad":
        return f"{value:.3g} rad ({math.degrees(value):.3g} deg)"
    return f"{text} {unit}" if unit else text


def _estimator(name: str, help: str, group: str, owner: str, field: tuple[str, str], **kw: Any) -> Option:
    """An estimator option read from a configuration field (its type is the field default's); an association field
    lands in the EKF's and the smoother's."""
    if field[0] == "AssociationConfig":
        kw.setdefault("lands", (f"ekf.association.{field[1]}", f"smoother.association.{field[1]}"))
    kind = type(field_default(field))
    return Option(name, help, group, (owner,), kind=kind, field=field, **kw)


_DATASET = ("replay", "compare", "convert")


def _dataset_options() -> list[Option]:
    """The importers' options (:mod:`online_slam.importers.registry`): one flag per field name, for every format
    that reads it; a sweep takes a list of a ``listed`` one."""
    out = []
    for name, (f, _) in registry.dataset_options().items():
        m = f.metadata
        commands = (*_DATASET, "sweep") if m["listed"] else _DATASET
        unset = m["unset"] or ("off" if m["kind"] is bool else "")
        out.append(Option(name, m["help"], "input", ("dataset",), kind=m["kind"], metavar=m["metavar"],
                          choices=m["choices"], unset=unset, positive=m["positive"], parse=m["parse"],
                          lands=(f"dataset.{name}",), commands=commands))  # fmt: skip
    return out


_WORLD_NAMES = ", ".join(WORLDS)

OPTIONS: dict[str, Option] = {o.name: o for o in (
    # -- input ----------------------------------------------------------------------------------------------
    Option("source", f"stream file (.jsonl/.gz), '-' (stdin), tcp://HOST:PORT (listen, one client at a time), "
           f"dataset path, or world ({_WORLD_NAMES})", "input",
           ("replay",), default="square", nargs="?", commands=("replay", "compare")),
    Option("sources", f"stream files, dataset paths or worlds ({_WORLD_NAMES})", "input", ("replay",),
           nargs="+", commands=("sweep",)),
    Option("format", "dataset format", "input", ("dataset",), choices=registry.names(), unset="detected",
           lands=("dataset.format",), commands=("replay", "compare")),
    *_dataset_options(),
    Option("noise", "the noise the source declares (builtin), fitted to its truth (fit), or to its own data (self: "
           "no truth; each sensor's bias too) (replay: print the figures, then replay with them; compare: each run "
           "fitted on its own data, unprinted)", "input", ("replay",), choices=("builtin", "fit", "self"),
           unset="builtin", lands=("dataset.noise",), commands=("replay", "compare")),
    _estimator("odometry_noise_scale", "multiply every odometry covariance of the source by S (a sigma by "
               "sqrt(S)), e.g. as --noise fit prints it", "input", "front-end",
               ("FrontEndConfig", "odometry_noise_scale"), metavar="S", positive=True,
               lands=("frontend.odometry_noise_scale",)),
    _estimator("sensor_noise_scale", "multiply every sighting's covariance of the source by S", "input",
               "front-end", ("FrontEndConfig", "sensor_noise_scale"), metavar="S", positive=True,
               lands=("frontend.sensor_noise_scale",)),
    Option("odometry_bias_scale", "EKF only: estimate each robot's odometry bias with the state, the share of each "
           "logged distance that is not real, with this prior sigma (0: none)", "input", ("ekf",), kind=float,
           field=("FrontEndConfig", "odometry_bias_scale"), unset="the header's odometry_bias, else 0", metavar="S",
           lands=("frontend.odometry_bias_scale",)),
    Option("odometry_bias_rate", "... and the heading rate the odometry adds to each turn (counter-clockwise "
           "positive), with this prior sigma in rad/s (0: none)", "input", ("ekf",), kind=float,
           field=("FrontEndConfig", "odometry_bias_rate"), unit="rad/s", unset="the header's odometry_bias, else 0",
           metavar="W", lands=("frontend.odometry_bias_rate",)),
    Option("max_latency", "lines may arrive up to S seconds late (a reorder buffer puts them in time order, "
           "delaying the estimate by S); later ones are skipped and counted", "input", ("front-end",), kind=float,
           field=("FrontEndConfig", "max_latency"), unset="0 for files, 0.5 s for stdin, tcp://", metavar="S", unit="s",
           lands=("frontend.max_latency",)),
    Option("fix_correlation", "time constant of fixes' errors (a GPS's wander): each fix's covariance widened by its "
           "correlation with the previous one; 0: none", "input", ("front-end",), kind=float, unit="s", metavar="S",
           field=("FrontEndConfig", "fix_correlation"), unset="header, else 0", lands=("frontend.fix_correlation",)),
    Option("on_error", "a bad line of a stream: stop there, or report it on stderr and skip it", "input",
           ("replay",), choices=("stop", "skip"), unset="stop for files, skip for stdin and tcp://",
           lands=("on_error",), commands=_DATASET),
    Option("strict", "exit 2 when most of the first sightings are rejected or lines skipped (wrong units? "
           "sigmas?), keeping the figures before it; without it, one warning names the likely cause", "input",
           ("replay",), kind=bool, field=("ReplayConfig", "strict"), lands=("strict",), commands=("replay",)),
    Option("map", "start from this map (online-slam-map JSON): its landmarks as one prior with the map's joint "
           "covariance (or each its own, when the map has none); the stream's start pose must be in the map's frame",
           "input", ("replay",), metavar="PATH",
           field=("MapConfig", "path"), unset="none", lands=("map.path",), commands=("replay",)),
    Option("map_fixed", "--map's landmarks are known: held where the map puts them", "input", ("replay",),
           kind=bool, field=("MapConfig", "fixed"), lands=("map.fixed",), commands=("replay",)),
    Option("map_only", "with --map: skip (and count) sightings of landmarks not in the map (no new landmarks)", "input",
           ("replay",), kind=bool, field=("MapConfig", "only"), lands=("map.only",), commands=("replay",)),
    # -- estimators -----------------------------------------------------------------------------------------
    Option("estimators", "comma-separated estimators to run (ekf, smoother, batch)", "estimators", ("replay",),
           field=("ReplayConfig", "estimators"), metavar="NAMES", lands=("estimators",)),
    Option("align", "frame of the errors: first pose's truth at its start prior, or least-squares SE(2) fit",
           "estimators", ("replay",), field=("ReplayConfig", "alignment"), choices=("anchor", "se2"),
           lands=("alignment",), commands=("replay", "compare")),
    _estimator("first_observation_only", "keep only the first sighting of each landmark (the article's ablation)",
               "estimators", "front-end", ("FrontEndConfig", "first_observation_only"),
               lands=("frontend.first_observation_only",)),
    Option("keyframe_distance", "merge observation-free steps up to this distance", "estimators", ("front-end",),
           kind=float, field=("KeyframeConfig", "max_distance"), unset="off", metavar="M", unit="m",
           lands=("frontend.keyframing.max_distance",)),
    Option("keyframe_angle", "... and up to this rotation", "estimators", ("front-end",), kind=float,
           field=("KeyframeConfig", "max_angle"), unset="off", metavar="RAD", unit="rad",
           lands=("frontend.keyframing.max_angle",)),
    Option("keyframe_time", "... and up to this time span", "estimators", ("front-end",), kind=float,
           field=("KeyframeConfig", "max_time"), unset="off", metavar="S", unit="s",
           lands=("frontend.keyframing.max_time",)),
    _estimator("batch_init", "batch: start from odometry or an online estimator's final estimate (auto: the "
               "smoother's if it runs, else the EKF's, else odometry)", "estimators", "batch",
               ("BatchConfig", "initial"), choices=("auto", "odometry", "ekf", "smoother"), lands=("batch.initial",)),
    _estimator("max_iterations", "batch: most Levenberg-Marquardt iterations", "estimators", "batch",
               ("SolverConfig", "max_iterations"), metavar="N", lands=("batch.solver.max_iterations",)),
    # -- EKF ------------------------------------------------------------------------------------------------
    _estimator("gate_probability", "chi-square gate on each sighting's NIS, 2 dof (1 = off)", "EKF", "ekf",
               ("EkfConfig", "gate_probability"), metavar="P", lands=("ekf.gate_probability",)),
    _estimator("gate_persistence", "use a landmark's sighting after N-1 gated ones in a row (the filter drifted; "
               "0 = always reject)", "EKF", "ekf", ("EkfConfig", "gate_persistence"), metavar="N",
               lands=("ekf.gate_persistence",)),
    _estimator("ekf_update", "one update per step with all sightings (joint) or one per sighting", "EKF", "ekf",
               ("EkfConfig", "update"), choices=("joint", "sequential"), lands=("ekf.update",)),
    _estimator("ekf_linearization", "where the EKF's Jacobians are evaluated: the current estimate (standard: the "
               "textbook EKF, overconfident), each variable's first estimate (fej), fej's prediction with the "
               "standard sighting Jacobians projected to see nothing of the unobservable directions (oc), or the "
               "standard ones with the error taken on the group of the pose and map (invariant). fej, oc and "
               "invariant are consistent on esde's circle protocol. fej and oc take one robot; invariant's updates "
               "are standard from a second robot's start on", "EKF", "ekf", ("EkfConfig", "linearization"),
               choices=CHOICES["ekf_linearization"], lands=("ekf.linearization",)),
    Option("pose_covariance", "EKF and smoother: how the newest pose's covariance is reported (NEES, recordings, "
           "--emit, Slam): curved, the second moment of the belief read as an arc about the pivot its heading "
           "correlation implies; linear, as linearized. The estimates are the same", "estimators",
           ("ekf", "smoother"), field=("EkfConfig", "pose_covariance"), choices=CHOICES["pose_covariance"],
           lands=("ekf.pose_covariance", "smoother.pose_covariance")),
    Option("adapt_noise", "EKF and smoother: the declared covariances inflated while the innovations show them too "
           "small, the sensor's shrunk while too wide unless the source declares it widened for correlation "
           "(on by default; --no-adapt-noise: as declared)", "estimators",
           ("ekf", "smoother"), kind=bool, field=("AdaptationConfig", "enabled"),
           lands=("ekf.adaptation.enabled", "smoother.adaptation.enabled")),
    # -- smoother -------------------------------------------------------------------------------------------
    _estimator("window", "W: fewest poses the window keeps (compare: a list)", "smoother", "smoother",
               ("WindowConfig", "size"), metavar="W", lands=("smoother.window.size",)),
    _estimator("window_distance", "keep poses beyond W until the window's path is this long, up to --window-max "
               "poses (0 = exactly W poses)", "smoother", "smoother", ("WindowConfig", "distance"),
               metavar="M", unit="m", lands=("smoother.window.distance",)),
    _estimator("window_max", "most poses the window keeps for --window-distance", "smoother", "smoother",
               ("WindowConfig", "max_poses"), metavar="N", lands=("smoother.window.max_poses",)),
    _estimator("relinearize_every", "K: relinearize and solve every K steps (compare: a list)", "smoother",
               "smoother", ("SmootherConfig", "relinearize_every"), metavar="K", lands=("smoother.relinearize_every",)),
    _estimator("global_every", "re-solve the whole history every N steps, and at once after a window solve turns "
               "its oldest pose by over 0.05 rad; re-anchor the prior (0 = never)", "smoother", "smoother",
               ("GlobalConfig", "every"), metavar="N", lands=("smoother.global_solve.every",)),
    _estimator("global_delay", "hand each global solve (a background thread) over D steps later, or N/50 after "
               "step N if longer (0 = at once)", "smoother", "smoother", ("GlobalConfig", "delay"),
               metavar="D", lands=("smoother.global_solve.delay",)),
    _estimator("smoother_linearization", "how the smoother linearizes the variables its marginal prior holds, "
               "once poses leave the window: at the current estimate (standard); at the prior's linearization "
               "point, re-anchored at each global solve (fej); or at the current estimate, with the prior's "
               "covariance carried there as the invariant EKF carries its own (invariant). fej and invariant "
               "start window solves undamped; they are consistent where standard is overconfident, and their steps "
               "are slower (benchmarks/RESULTS.md)",
               "smoother", "smoother", ("SmootherConfig", "linearization"),
               choices=CHOICES["smoother_linearization"], lands=("smoother.linearization",)),
    _estimator("global_information_max", "at re-anchoring also relinearize the prior's covariance while it holds "
               "at most L landmarks (0 = never)", "smoother", "smoother",
               ("GlobalConfig", "information_max"), metavar="L",
               lands=("smoother.global_solve.information_max",)),
    # -- association ----------------------------------------------------------------------------------------
    Option("association", "pair sightings by the stream's ids (known), nearest neighbour (nn) or joint "
           "compatibility (jcbb); auto: known when the first sighting has an id, else jcbb (Slam: known)",
           "association", ("association",), field=("ReplayConfig", "association"),
           choices=("auto", *CHOICES["association"]), lands=("association",)),
    _estimator("new_density", "nn/jcbb: start a new landmark when a pairing is less likely than an unmapped "
               "landmark at this density (0 = off)", "association", "association",
               ("AssociationConfig", "new_density"), metavar="D", unit="per m^2"),
    _estimator("rival", "nn/jcbb: leave a scan out when another pairing, putting the robot elsewhere, has at least F "
               "times the chosen one's likelihood (larger: fewer left out; 0 = off)", "association", "association",
               ("AssociationConfig", "rival"), metavar="F"),
    # -- outliers -------------------------------------------------------------------------------------------
    Option("robust", "smoother and batch: auto (Cauchy tail beyond 5.3 sigmas in the window, batch robust pass "
           "when residuals show outliers), none (least squares), huber or cauchy (with --robust-scale)",
           "outliers", ("smoother", "batch"), default=CHOICES["robust"][0], choices=CHOICES["robust"]),
    Option("robust_scale", "huber/cauchy threshold", "outliers", ("smoother", "batch"), kind=float,
           field=("RobustLoss", "scale"), metavar="S", unit="sigmas", positive=True),
    # -- output ---------------------------------------------------------------------------------------------
    Option("json", "write the results as JSON ('-': stdout, the table then on stderr)", "output", ("cli",),
           metavar="PATH", commands=("replay", "compare")),
    Option("tum", "write TUM trajectories for evo (truth, odometry, each estimator final and _online; several "
           "robots: one file per robot, NAME_robot<ID>.tum)", "output", ("cli",), metavar="DIR", commands=("replay",)),
    Option("plot", "write the figures (map, error, NEES, latency) to this PNG", "output", ("cli",),
           metavar="PATH", commands=("compare",)),
    Option("map_out", "write the final map: the batch's positions if it ran, else the smoother's, else the EKF's; "
           "covariances of the smoother, else the EKF (convert: the source's landmark truth, known)", "output",
           ("cli",), metavar="PATH", commands=("replay", "convert")),
    Option("rrd", "log every step to a Rerun recording (.rrd) (compare: every configuration in one)", "output",
           ("cli",), metavar="PATH", commands=("replay", "compare")),
    Option("output", "the command's output file: simulate and convert write a stream (.jsonl; .gz compresses; "
           "convert FORMAT stream: .g2o), sweep its rows (.csv or .parquet, written as replays finish: re-running "
           "skips the replays it holds)", "output", ("cli",), metavar="PATH", short="-o",
           unset="stdout ('-'); sweep: memory only", commands=("simulate", "convert", "sweep")),
    Option("quiet", "print no table, no summary and no progress", "output", ("cli",), kind=bool, default=False),
    # -- live / checkpoint ----------------------------------------------------------------------------------
    Option("connect", "stream the recording to a running Rerun viewer (default address, or a rerun+http:// URL)",
           "live/checkpoint", ("cli",), metavar="ADDR", nargs="?", const="default",
           commands=("replay", "compare")),
    Option("rate", "pace the replay at R times the stream's clock", "live/checkpoint", ("cli",), kind=float,
           metavar="R", unset="as fast as possible", commands=("replay",)),
    Option("emit", "write a JSON line per step as estimated: to a file, '-' (stdout; the table on stderr) or tcp://HOST:"
           "PORT (a reader listening there)", "live/checkpoint", ("cli",), metavar="DEST", commands=("replay",)),
    Option("emit_estimator", "whose estimate --emit writes, or all", "live/checkpoint", ("cli",), metavar="NAME",
           unset="the first online one of --estimators", commands=("replay",)),
    Option("checkpoint", "save the whole replay state to DIR/replay.ckpt every --checkpoint-every steps",
           "live/checkpoint", ("cli",), metavar="DIR", commands=("replay",)),
    Option("checkpoint_every", "steps between checkpoints", "live/checkpoint", ("cli",), kind=int,
           field=("Checkpointing", "every"), metavar="N", commands=("replay",)),
    Option("resume", "continue from DIR's checkpoint (same source and options; figures equal an uninterrupted "
           "run's)", "live/checkpoint", ("cli",), metavar="DIR", commands=("replay",)),
    # -- runs -----------------------------------------------------------------------------------------------
    Option("runs", "noise seeds per simulated world (compare: Monte Carlo runs)", "runs", ("cli",), kind=int,
           field=("CompareConfig", "runs"), metavar="N", commands=("compare", "sweep"), positive=True),
    Option("workers", "processes (compare: Monte Carlo runs; sweep: local cluster)", "runs", ("cli",), kind=int,
           metavar="N", unset="all cores", commands=("compare", "sweep"), positive=True),
    Option("scheduler", "a running Dask scheduler, e.g. tcp://host:8786", "runs", ("cli",), metavar="ADDRESS",
           unset="a local cluster", commands=("sweep",)),
    Option("peer", "with --runs: also run on every run's stream, and report beside the estimators' ANEES, share in "
           "band and RMSE: isam2, GTSAM's iSAM2 (the 'peers' extra; newest pose's marginalCovariance); ideal, the EKF "
           "with every Jacobian at the true state (consistency's yardstick); a comma-separated list for both", "runs",
           ("cli",), choices=CHOICES["peer"], unset="none", commands=("compare",)),
)}  # fmt: skip
"""Every option, by name, grouped by concern."""


def estimator_options() -> dict[str, Option]:
    """The estimator options (``Slam`` and ``sweep`` take exactly these; ``replay`` and ``compare`` too)."""
    return {name: o for name, o in OPTIONS.items() if o.estimator}


# -- values ---------------------------------------------------------------------------------------------------
def check_value(option: Option, value: Any) -> None:
    """Refuse a value of the wrong type or out of the option's choices (``Slam(**options)``, list items).

    Raises:
        ConfigError: Naming the option, what it expects and what it got.
    """
    kind, number = option.kind, isinstance(value, (int, float)) and not isinstance(value, bool)
    ok = {bool: isinstance(value, bool), int: number and isinstance(value, int),
          float: number and not math.isnan(value)}.get(kind, isinstance(value, str))  # fmt: skip
    if not ok:
        raise ConfigError(
            f"option {option.name}: expected {kind.__name__}, got {value!r} ({for_command(option.help, 'Slam')})"
        )
    if option.choices and value not in option.choices:
        raise ConfigError(f"option {option.name}: expected one of {', '.join(option.choices)}, got {value!r}")


def replay_config(values: Mapping[str, Any], naming: Callable[[str], str] = str) -> ReplayConfig:
    """The replay configuration that option values ask for (missing or None values keep their defaults).

    The one translation of options into configurations: ``replay``, ``compare``, ``sweep`` and ``Slam`` call it.

    Args:
        values: Option values by name (e.g. ``vars(args)``); names that are no option are ignored.
        naming: How an option is named in error messages (the CLI passes its flag).

    Raises:
        ConfigError: A value out of range, naming the option.
    """
    from online_slam.estimators.presets import robust_settings
    from online_slam.factors.robust import RobustLoss
    from online_slam.frontend.steps import KeyframeConfig
    from online_slam.pipeline import ReplayConfig

    config = ReplayConfig()
    if any(values.get(name) is not None for name in ("keyframe_distance", "keyframe_angle", "keyframe_time")):
        config = dataclasses.replace(config, frontend=dataclasses.replace(config.frontend, keyframing=KeyframeConfig()))
    given = {name: v for name, v in values.items() if name in OPTIONS and v is not None}
    given["on_error"] = on_error_of(given.get("on_error"), values.get("source"))
    for name, value in given.items():
        option = OPTIONS[name]
        if option.positive and not value > 0:
            raise ConfigError(f"{naming(name)}: must be > 0, got {value}")
        if name == "estimators":
            value = tuple(n.strip().lower() for n in value.split(",") if n.strip())
        try:
            for path in option.lands:
                config = _set(config, path.split("."), value)
        except ValueError as exc:
            raise ConfigError(f"{naming(name)}: {exc}") from None
    _check_estimators(config.estimators, given, naming)
    _check_noise(given, naming)
    robust, scale = given.get("robust", OPTIONS["robust"].value), given.get("robust_scale", RobustLoss.scale)
    smoother, batch = robust_settings(robust, scale, config.smoother, config.batch)
    return dataclasses.replace(config, smoother=smoother, batch=batch)


def _check_estimators(running: tuple[str, ...], given: Mapping[str, Any], naming: Callable[[str], str]) -> None:
    """Refuse an empty estimator list, and a setting (other than its default) of an estimator that does not run."""
    from online_slam.pipeline import ESTIMATORS

    if not running:
        raise ConfigError(f"{naming('estimators')}: give at least one of {', '.join(ESTIMATORS)}")
    for name, value in given.items():
        owners = set(OPTIONS[name].owners)
        if owners <= set(ESTIMATORS) and not owners & set(running) and value != OPTIONS[name].value:
            whose = " and the ".join(sorted(owners))
            raise ConfigError(
                f"{naming(name)}: a setting of the {whose}, which does not run (estimators: {', '.join(running)})"
            )


def _check_noise(given: Mapping[str, Any], naming: Callable[[str], str]) -> None:
    """Refuse a noise scale given with ``--noise fit`` or ``--noise self``, which fit the scales."""
    if (mode := given.get("noise")) not in ("fit", "self"):
        return
    for name in ("odometry_noise_scale", "sensor_noise_scale"):
        if given.get(name, 1.0) != 1.0:
            raise ConfigError(f"{naming(name)}: --noise {mode} fits the scale; give one or the other")


def _set(target: Any, path: list[str], value: Any) -> Any:
    """``target`` with the field (or dict key) at ``path`` replaced; every dataclass on the way re-validated."""
    head, rest = path[0], path[1:]
    if isinstance(target, dict):
        return {**target, head: value}
    inner = _set(getattr(target, head), rest, value) if rest else value
    return dataclasses.replace(target, **{head: inner})


# -- command line ---------------------------------------------------------------------------------------------
def flag(name: str) -> str:
    """An option's command-line spelling."""
    return OPTIONS[name].flag


def add_options(parser: argparse.ArgumentParser, command: str, lists: Iterable[str] = ()) -> None:
    """Add the command's options to a parser, one argument group per concern.

    Args:
        parser: The command's parser.
        command: ``replay``, ``compare``, ``sweep`` or ``convert``.
        lists: Options that take comma-separated lists (compare's window grid, sweep's settings).
    """
    chosen = [o for o in OPTIONS.values() if command in o.commands]
    groups = {g: parser.add_argument_group(g) for g in GROUPS if any(o.group == g for o in chosen)}
    hidden = []
    for option in chosen:
        action = add_option(groups[option.group], option, option.name in set(lists), command)
        if option.name in ADVANCED:
            hidden.append((action, action.help))
            action.help = argparse.SUPPRESS
    if hidden:
        told = f"show this help with {counted(len(hidden), 'advanced option')} (research knobs) too"
        parser.add_argument("--help-all", action=_HelpAll, hidden=hidden, help=told)


class _HelpAll(argparse.Action):
    """``--help-all``: the help with the advanced options shown, then exit."""

    def __init__(self, option_strings: list[str], dest: str, hidden: list, help: str | None = None) -> None:
        super().__init__(option_strings, argparse.SUPPRESS, nargs=0, default=argparse.SUPPRESS, help=help)
        self.hidden = hidden

    def __call__(self, parser: argparse.ArgumentParser, namespace: Any, values: Any, option: Any = None) -> None:
        for action, text in self.hidden:
            action.help = f"[advanced] {text}"
        parser.print_help()
        parser.exit()


_NOTE = re.compile(r" \(((?:replay|compare|sweep|convert|Slam): [^()]*)\)")
"""A help text's note for some commands: ``(compare: a list)``, ``(compare: Monte Carlo runs; sweep: ...)``."""


def for_command(help: str, command: str) -> str:
    """A help text as one command shows it: its own part of each per-command note kept, the others' dropped."""

    def own(match: re.Match[str]) -> str:
        parts = [part.split(": ", 1) for part in match.group(1).split("; ")]
        kept = [text for name, text in parts if name == command]
        return f" ({kept[0]})" if kept else ""

    return _NOTE.sub(own, help)


def add_option(group: Any, option: Option, listed: bool, command: str) -> argparse.Action:
    """Add one option to an argparse group; its action."""
    shown = option.shown_default()
    told = for_command(option.help, command)
    text = f"{told} (default: {shown})" if shown and option.kind is not bool else told
    kw: dict[str, Any] = {"help": text.replace("%", "%%")}
    parse = positive(option.parse or option.kind) if option.positive else option.parse or option.kind
    if option.kind is bool:
        if listed:  # alone: on; or the values to run, e.g. ``--adapt-noise true,false``
            kw.update(nargs="?", const=(True,), type=bools, metavar="{true,false}[,...]")
        else:  # on by default: --no-NAME turns it off
            flag = argparse.BooleanOptionalAction if option.value is True else "store_true"
            kw.update(action=flag, default=option.default)
    elif listed:
        values = "{" + ",".join(option.choices) + "}" if option.choices else option.metavar or "N"
        read = list_of(parse, f"{option.kind.__name__}s", option.choices)
        kw.update(type=read, metavar=f"{values}[,...]")
    else:
        kw.update(type=parse, metavar=option.metavar, choices=option.choices or None)
        kw["default"] = option.value
    if option.nargs is not None:
        kw["nargs"] = option.nargs
    if option.const is not None:
        kw["const"] = option.const
    if option.positional and option.metavar is None:
        kw.pop("metavar", None)
    return group.add_argument(*filter(None, (option.short, option.flag)), **kw)


# -- docs -----------------------------------------------------------------------------------------------------
def markdown() -> str:
    """The docs' option list (``docs/options.md``), rendered from the table (:mod:`online_slam.options_page`)."""
    from online_slam.options_page import markdown as page

    return page()
