"""The smoother's state groups that belong to no single part, and every group's packing for checkpoints.

The checkpoint's content (its keys, their order, the arrays' layout) is the one earlier versions wrote: a
checkpoint's bytes depend on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.history import PoseHistory
from online_slam.estimators.landmark_book import LandmarkBook
from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.smoother.covariance import Solved
from online_slam.estimators.smoother.global_solve import GlobalJob, Relinearization
from online_slam.estimators.smoother.prior import Prior
from online_slam.estimators.smoother.window import Window
from online_slam.frontend.steps import Step
from online_slam.solvers.least_squares import SolveResult

Array = NDArray[np.float64]
Index = NDArray[np.int64]

KEYS = (
    "window",
    "poses",
    "final_poses",
    "landmark_ids",
    "landmarks",
    "odometry",
    "observations",
    "start",
    "prior",
    "pose_cov",
    "since_solve",
    "unsolved",
    "solves",
    "marginalized",
    "released",
    "step_report",
    "step_marginalized",
    "decision_poses",
    "decision_sizes",
    "decisions",
    "log",
    "steps",
    "global_job",
    "since_global",
    "global_solves",
    "global_rejections",
    "book",
    "resolved",
    "solved",
)
"""The checkpoint's keys, in the order it holds them."""


@dataclass
class Progress:
    """How far the smoother got: counts, and what the newest step did."""

    steps: int = 0
    """Steps consumed."""
    solves: int = 0
    """Window solves."""
    marginalized: int = 0
    """Poses marginalized."""
    released: int = 0
    """Landmarks let go from the prior because the window's sightings contradicted it (consensus)."""
    step_report: dict[str, float] = field(default_factory=dict)
    """The newest step's last solve and global relinearization figures."""
    step_marginalized: list[int] = field(default_factory=list)
    """The poses the newest step marginalized."""


@dataclass
class AssociationState:
    """Association's state, and the last solve's information it reads."""

    book: LandmarkBook
    """Tentative landmarks and each sighting's label."""
    resolved: Step | None = None
    """The newest step with associated ids, when association changed it."""
    solved: Solved | None = None
    """The last solve's factored information, while the state has not moved."""


def _floats(a: Any) -> Array:
    return np.array(a, dtype=float)


def pack_odometry(factors: dict[int, tuple[Array, Array, Array]]) -> dict[str, Any]:
    """Window odometry factors (delta, cov, sqrt-information) as stacked arrays (for checkpoints)."""
    rows = list(factors.values())
    return {
        "poses": np.array(list(factors), dtype=np.int64),
        "delta": np.array([r[0] for r in rows]).reshape(-1, 3),
        "cov": np.array([r[1] for r in rows]).reshape(-1, 3, 3),
        "sqrt_info": np.array([r[2] for r in rows]).reshape(-1, 3, 3),
    }


def unpack_odometry(state: dict[str, Any]) -> dict[int, tuple[Array, Array, Array]]:
    """The window odometry factors from :func:`pack_odometry`'s arrays (copies), keyed by pose."""
    parts = [np.array(state[k], dtype=float) for k in ("delta", "cov", "sqrt_info")]
    return {int(i): (parts[0][k].copy(), parts[1][k].copy(), parts[2][k].copy()) for k, i in enumerate(state["poses"])}


def pack_observations(factors: dict[int, tuple[Index, Array, Array, Array]]) -> dict[str, Any]:
    """Window observation factors (landmarks, z, cov, sqrt-information) concatenated (for checkpoints)."""
    rows = list(factors.values())

    def cat(k: int, shape: tuple[int, ...], dtype: type) -> np.ndarray:
        return np.concatenate([r[k] for r in rows]) if rows else np.zeros((0, *shape), dtype=dtype)

    return {
        "poses": np.array(list(factors), dtype=np.int64),
        "sizes": np.array([len(r[0]) for r in rows], dtype=np.int64),
        "landmarks": cat(0, (), np.int64),
        "z": cat(1, (2,), float),
        "cov": cat(2, (2, 2), float),
        "sqrt_info": cat(3, (2, 2), float),
    }


def unpack_observations(state: dict[str, Any]) -> dict[int, tuple[Index, Array, Array, Array]]:
    """The window observation factors from :func:`pack_observations`'s arrays (copies), keyed by pose."""
    cuts = np.cumsum(np.array(state["sizes"], dtype=np.int64))[:-1]
    landmarks = np.split(np.array(state["landmarks"], dtype=np.int64), cuts)
    z, cov, w = (np.split(np.array(state[k], dtype=float), cuts) for k in ("z", "cov", "sqrt_info"))
    return {
        int(i): (landmarks[k].copy(), z[k].copy(), cov[k].copy(), w[k].copy()) for k, i in enumerate(state["poses"])
    }


def pack(
    window: Window,
    prior: Prior | None,
    progress: Progress,
    relinearization: Relinearization,
    association: AssociationState,
) -> dict[str, Any]:
    """Every group as a checkpoint's numbers and arrays (a pending global job must be finished)."""
    parts = {
        **_pack_window(window),
        "prior": _pack_prior(prior),
        **_pack_progress(progress),
        **_pack_relinearization(relinearization),
        **_pack_association(association),
    }
    return {key: parts[key] for key in KEYS}


def _pack_window(w: Window) -> dict[str, Any]:
    poses = w.values().reshape(-1, 3)
    return {
        "window": list(w.indices),
        "poses": poses,
        "final_poses": np.concatenate((w.history.view(), poses)),
        "landmark_ids": list(w.landmark_ids),
        "landmarks": w.landmarks.copy(),
        "odometry": pack_odometry(w.odometry),
        "observations": pack_observations(w.observations),
        "start": None if w.start is None else list(w.start),
        "pose_cov": w.pose_cov,
        "since_solve": w.since_solve,
        "unsolved": sorted(w.unsolved),
    }


def unpack_window(state: dict[str, Any]) -> Window:
    """The window of a :func:`pack`."""
    indices = [int(g) for g in state["window"]]
    landmark_ids = list(state["landmark_ids"])
    start = state["start"]
    return Window(
        indices=indices,
        poses={g: pose.copy() for g, pose in zip(indices, _floats(state["poses"]).reshape(-1, 3))},
        history=PoseHistory(_floats(state["final_poses"]).reshape(-1, 3)[: len(state["final_poses"]) - len(indices)]),
        landmark_ids=landmark_ids,
        index={lid: j for j, lid in enumerate(landmark_ids)},
        landmarks=_floats(state["landmarks"]).reshape(-1, 2),
        odometry=unpack_odometry(state["odometry"]),
        observations=unpack_observations(state["observations"]),
        start=None
        if start is None
        else (int(start[0]), _floats(start[1]), None if start[2] is None else _floats(start[2])),
        pose_cov=_floats(state["pose_cov"]),
        unsolved={int(g) for g in state["unsolved"]},
        since_solve=int(state["since_solve"]),
    )


def _pack_prior(p: Prior | None) -> dict[str, Any] | None:
    if p is None:
        return None
    return {
        "pose": p.pose,
        "landmarks": p.landmarks,
        "x_lin": p.x_lin,
        "mu": p.mu,
        "Sigma": p.Sigma.copy(),
        "capacity": len(p.Sigma),  # read by versions that kept a larger buffer
    }


def unpack_prior(state: dict[str, Any]) -> Prior | None:
    """The prior of a :func:`pack`."""
    prior = state["prior"]
    if prior is None:
        return None
    n = len(prior["mu"])
    return Prior(
        int(prior["pose"]),
        np.array(prior["landmarks"], dtype=np.int64),
        _floats(prior["x_lin"]),
        _floats(prior["mu"]),
        np.ascontiguousarray(_floats(prior["Sigma"]).reshape(n, n)),
    )


def _pack_progress(p: Progress) -> dict[str, Any]:
    return {
        "solves": p.solves,
        "marginalized": p.marginalized,
        "released": p.released,
        "step_report": dict(p.step_report),
        "step_marginalized": list(p.step_marginalized),
        "steps": p.steps,
    }


def unpack_progress(state: dict[str, Any]) -> Progress:
    """The progress of a :func:`pack`."""
    return Progress(
        steps=int(state["steps"]),
        solves=int(state["solves"]),
        marginalized=int(state["marginalized"]),
        released=int(state["released"]),
        step_report=dict(state["step_report"]),
        step_marginalized=[int(g) for g in state["step_marginalized"]],
    )


def _pack_relinearization(r: Relinearization) -> dict[str, Any]:
    decisions = r.decisions
    return {
        "decision_poses": np.array([d[0] for d in decisions], dtype=np.int64),
        "decision_sizes": np.array([len(d[1]) for d in decisions], dtype=np.int64),
        "decisions": np.concatenate([d[1] for d in decisions]) if decisions else np.zeros(0, bool),
        "log": r.log.state_dict(),
        "global_job": _pack_job(r.job),
        "since_global": r.since,
        "global_solves": r.solves,
        "global_rejections": r.rejections,
    }


def _pack_job(job: GlobalJob | None) -> dict[str, Any] | None:
    if job is None:
        return None
    r = job.result
    return {
        "handover": job.handover,
        "n_poses": job.n_poses,
        "error": job.error,
        "poses": None if r is None else r.poses,
        "landmarks": None if r is None else r.landmarks,
        "iterations": 0 if r is None else r.iterations,
        "converged": False if r is None else r.converged,
        "initial_cost": 0.0 if r is None else r.initial_cost,
        "final_cost": 0.0 if r is None else r.final_cost,
        "message": "" if r is None else r.message,
    }


def unpack_relinearization(state: dict[str, Any], log: ProblemLog) -> Relinearization:
    """The global relinearization's state of a :func:`pack`, around ``log`` (loaded in place)."""
    cuts = np.cumsum(np.array(state["decision_sizes"], dtype=np.int64))[:-1]
    masks = np.split(np.array(state["decisions"], dtype=bool), cuts) if len(state["decision_sizes"]) else []
    log.load_state(state["log"])
    return Relinearization(
        log=log,
        decisions=[(int(g), m.copy()) for g, m in zip(state["decision_poses"], masks)],
        since=int(state["since_global"]),
        job=_unpack_job(state["global_job"]),
        solves=int(state["global_solves"]),
        rejections=int(state["global_rejections"]),
    )


def _unpack_job(job: dict[str, Any] | None) -> GlobalJob | None:
    if job is None:
        return None
    restored = GlobalJob(int(job["handover"]), int(job["n_poses"]), error=job["error"])
    if job["poses"] is not None:
        restored.result = SolveResult(
            _floats(job["poses"]).reshape(-1, 3),
            _floats(job["landmarks"]).reshape(-1, 2),
            int(job["iterations"]),
            bool(job["converged"]),
            float(job["initial_cost"]),
            float(job["final_cost"]),
            str(job["message"]),
        )
    return restored


def _pack_association(a: AssociationState) -> dict[str, Any]:
    r, s = a.resolved, a.solved
    return {
        "book": a.book.state_dict(),
        "resolved": None if r is None else {"landmarks": list(r.landmarks), "z": r.z, "z_cov": r.z_cov},
        "solved": None
        if s is None
        else {
            "window": s.window,
            "pose_column": s.pose_column,
            "active": s.active,
            "landmark_column": s.landmark_column,
            "factor": s.factor,
            "size": len(s.factor),
        },
    }


def unpack_association(state: dict[str, Any], book: LandmarkBook, window: Window) -> AssociationState:
    """Association's state of a :func:`pack`, around ``book`` (loaded in place), for the unpacked ``window``."""
    book.load_state(state["book"])
    sightings = state["resolved"]
    resolved = (
        None
        if sightings is None
        else Step(  # only its sightings are read again (extend keeps them and appends)
            index=window.indices[-1],
            t=math.nan,
            odometry=None,
            odometry_cov=None,
            landmarks=tuple(sightings["landmarks"]),
            z=_floats(sightings["z"]).reshape(-1, 2),
            z_cov=_floats(sightings["z_cov"]).reshape(-1, 2, 2),
        )
    )
    factored = state.get("solved")  # absent from checkpoints of versions before it
    solved = (
        None
        if factored is None
        else Solved(
            np.array(factored["window"], dtype=np.int64),
            np.array(factored["pose_column"], dtype=np.int64),
            np.array(factored["active"], dtype=np.int64),
            np.array(factored["landmark_column"], dtype=np.int64),
            np.array(factored["factor"], dtype=float).reshape(int(factored["size"]), int(factored["size"])),
        )
    )
    return AssociationState(book, resolved, solved)
