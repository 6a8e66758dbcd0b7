"""The sliding-window smoother: drives the window, its prior, covariance recovery and the global relinearization
(see :mod:`online_slam.estimators.smoother`). Its state is one dataclass (:class:`~.state.SmootherState`): the window
(:class:`~.window.Window`), the marginal prior (:class:`~.prior.Prior`), progress (:class:`~.state.Progress`), the
global relinearization (:class:`~.global_solve.Relinearization`) and association (:class:`~.state.AssociationState`);
a checkpoint is its tree (:func:`~online_slam.checkpoint.to_tree`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from online_slam.checkpoint import from_tree, to_tree
from online_slam.estimators.adaptation import adapted_info, entering, fold_sightings
from online_slam.estimators.blas import OneThreadBlas
from online_slam.estimators.landmark_book import LandmarkBook
from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.protocol import Estimate, Snapshot
from online_slam.estimators.smoother.config import SmootherConfig
from online_slam.estimators.smoother.covariance import (
    factored,
    is_unknown,
    landmark_joint,
    landmark_marginals,
    pose_marginals,
    propagated_covariance,
    window_covariance,
)
from online_slam.estimators.smoother.final_pairing import paired_again
from online_slam.estimators.smoother.fixes import fix_counts, gated
from online_slam.estimators.smoother.global_solve import (
    Relinearization,
    Revision,
    finish_job,
    followed,
    global_inputs,
    global_solver,
    is_due,
    jumped,
    rejudged_solve,
    revise,
    solve_now,
    start_job,
)
from online_slam.estimators.smoother.prior import (
    Prior,
    Sightings,
    carried,
    fold_map,
    initial_prior,
    marginalize,
    release,
)
from online_slam.estimators.smoother.robots import SeveralRobots
from online_slam.estimators.smoother.state import AssociationState, Progress, SmootherState
from online_slam.estimators.smoother.window import (
    Linearized,
    Window,
    active,
    consensus,
    judge,
    linearize,
    sightings_outside,
    solve_window,
)
from online_slam.factors.graph import FactorGraph
from online_slam.factors.robust import outlier_threshold
from online_slam.frontend.pose import SIGHTING_ARRAYS
from online_slam.frontend.steps import Step
from online_slam.geometry.angles import wrap
from online_slam.geometry.pose_moments import reported
from online_slam.solvers.least_squares import SolveResult
from online_slam.sources.events import LandmarkId
from online_slam.sources.landmark_map import LandmarkMap

Array = NDArray[np.float64]
Index = NDArray[np.int64]


class SlidingWindowSmoother(SeveralRobots):
    """Fixed-lag smoother over poses, keeping all landmarks, of one robot or several; follows the estimator
    protocol."""

    name = "smoother"
    online = True

    def __init__(self, config: SmootherConfig | None = None, name: str = "smoother") -> None:
        self.config = config or SmootherConfig()
        self.name = name
        keep_factors = self.config.global_solve.every > 0  # every factor, for global solves
        self.state = SmootherState(
            Window(),
            Relinearization(ProblemLog(keep_factors=keep_factors)),
            AssociationState(LandmarkBook(self.config.association, inside=False), stream=self._stream_log()),
        )
        self._reject_bound = (
            outlier_threshold(self.config.robust.reject_false_alarm)
            if self.config.robust.reject_false_alarm > 0
            else np.inf
        )
        self._blas = OneThreadBlas()
        self.preview = False
        """True in a copy a query makes (:meth:`online_slam.Slam.estimate`): no global relinearization starts or
        is handed over, so that it costs a window's solve and never waits for the background."""

    def _stream_log(self) -> ProblemLog | None:
        """Every step as it comes, ids ignored, when association pairs every sighting: the final pairs them all
        again from it (:func:`~.final_pairing.paired_again`); None otherwise."""
        return ProblemLog(use_ids=False) if self.config.association.ignores_ids else None

    @property
    def landmarks(self) -> Array:
        """Current landmark estimates, shape (M, 2)."""
        return self.window.landmarks

    # the state's groups
    @property
    def window(self) -> Window:
        """The window's poses and factors, the poses that left it, every landmark."""
        return self.state.window

    @property
    def prior(self) -> Prior | None:
        """The marginal prior, once a pose left the window."""
        return self.state.prior

    @prior.setter
    def prior(self, value: Prior | None) -> None:
        self.state.prior = value

    @property
    def progress(self) -> Progress:
        """Counts, and what the newest step did."""
        return self.state.progress

    @property
    def relinearization(self) -> Relinearization:
        """Every factor seen so far and the global relinearizations."""
        return self.state.relinearization

    @property
    def association(self) -> AssociationState:
        """Association's state, and the last solve's information it reads."""
        return self.state.association

    def load_map(self, landmark_map: LandmarkMap, fixed: bool = False) -> None:
        """Start from a map (before the first step): its landmarks come first, each with a prior of its covariance
        (at least :data:`~online_slam.sources.landmark_map.FIXED_STD` squared; exactly that with ``fixed``), in
        the window's graph while the marginal prior does not hold it, and in the global solves' graphs. A map with
        a joint covariance is one prior over all its landmarks: the marginal prior holds them all from its start."""
        w, log = self.window, self.relinearization.log
        if w.indices or w.landmark_ids:
            raise ValueError("a map is loaded before the first step")
        log.load_map(landmark_map, fixed)
        if self.association.stream is not None:
            self.association.stream.load_map(landmark_map, fixed)
        w.landmark_ids = list(landmark_map.ids)
        w.index = {lid: j for j, lid in enumerate(w.landmark_ids)}
        w.landmarks = landmark_map.xy.copy()
        w.map_size, w.map_xy, w.map_cov = len(landmark_map), log.map_xy.copy(), log.map_cov.copy()
        w.map_joint = log.map_joint.copy()

    # -- protocol --------------------------------------------------------------------------------
    def step(self, step: Step) -> Snapshot:
        """Add the step; solve every K steps; marginalize beyond the window; relinearize globally on schedule."""
        with self._blas.limit():
            w = self.window
            if self.association.stream is not None:
                self.association.stream.add(step)
            step = entering(step, self.state.adaptation)
            w.add_pose(step)
            step = gated(step, self.progress.fixes, w.poses[step.index], w.pose_cov)
            step, _ = self._resolve(step, 0)
            self._adapt(step, 0)
            w.add_sightings(step, 0)
            w.add_fixes(step)
            self.relinearization.log.add(step)
            if w.sightings_waiting or len(self.relinearization.log.seen.pose) > w.sightings_read:
                self._link_robot_sightings()
            self._add_retro()
            w.since_solve += 1
            report: dict[str, float] = {}
            jump = False
            if w.since_solve >= self.config.relinearize_every:
                oldest = float(w.poses[w.indices[0]][2])
                report = self.solve()
                jump = jumped(self.config, float(wrap(w.poses[w.indices[0]][2] - oldest)))
            marginalized: list[int] = []
            while w.several and w.is_full(self.config.window) and self._marginalize_several(marginalized):
                pass
            while not w.several and w.is_full(self.config.window):
                if w.indices[0] in w.unsolved:  # never marginalize a pose before it was optimized
                    report = self.solve()
                marginalized.append(w.indices[0])
                self.marginalize_oldest()
            report = self._global_schedule(report, jump)
            self.progress.step_report, self.progress.step_marginalized = report, marginalized
            return self.snapshot(step)

    def extend(self, step: Step, start: int) -> Snapshot:
        """The newest step grew: add its observations ``start:``; solve again if this step was a solve step."""
        with self._blas.limit():
            if self.association.stream is not None:
                self.association.stream.extend(step, start)
            step = gated(entering(step, self.state.adaptation), self.progress.fixes, self.window.poses[step.index],
                         self.window.pose_cov)  # fmt: skip
            step, start = self._resolve(step, start)
            self._adapt(step, start)
            self.window.add_sightings(step, start)
            self.window.add_fixes(step)
            self.relinearization.log.extend(step, start)
            self._add_retro()
            if self.window.since_solve == 0:  # this step solved: its new sightings are used at once
                self.progress.step_report = self.solve()
            return self.snapshot(step)

    def trajectory(self) -> Array:
        """Current estimate of every pose so far (window poses as now, older ones as they left), shape (N, 3)."""
        return np.concatenate(self.trajectory_parts())

    def trajectory_parts(self) -> tuple[Array, Array]:
        """(poses that left the window, read-only (N - W, 3) view; the window's poses now, a copy (W, 3)); with
        several robots (nothing; every pose in step order)."""
        if self.window.several:
            return np.zeros((0, 3)), self.window.all_poses()
        return self.window.history.view(), self.window.values().reshape(-1, 3)

    def state_dict(self) -> Any:
        """Everything needed to continue exactly where the smoother is: the tree of :class:`~.state.SmootherState`
        (a pending global solve is finished first: its result is part of the state)."""
        finish_job(self.relinearization.job)
        return to_tree(self.state)

    def load_state(self, state: Any) -> None:
        """Restore a :meth:`state_dict` (this smoother's config is kept)."""
        self.state = from_tree(SmootherState, state)

    def snapshot(self, step: Step) -> Snapshot:
        """The current estimate as an immutable snapshot."""
        w, report = self.window, self.progress.step_report
        return Snapshot(
            estimator=self.name,
            index=step.index,
            t=step.t,
            pose=w.poses[w.indices[-1]].copy(),
            pose_cov=reported(w.pose_cov, self.config.pose_covariance),
            landmark_ids=tuple(w.landmark_ids),
            landmarks=w.landmarks.copy(),
            info={
                "window": tuple(w.indices),
                "window_poses": w.values(),
                "relinearized": bool(report),
                "marginalized": tuple(self.progress.step_marginalized),
                **report,
            },
        )

    def finish(self) -> Estimate:
        """Solve once more if anything arrived since the last solve, then (with global relinearization on) re-solve
        every factor from there once, as a scheduled global relinearization does (:meth:`relinearize_globally`, its
        few iterations), so that the poses after the last scheduled one are revised too (why, and why not to
        convergence: benchmarks/RESULTS.md, "The smoother ends on a global solve"). Each pose's last estimate is
        final (with every landmark's marginal covariance there).

        A global relinearization still running in the background is waited for and dropped: its hand-over
        step never came (the final estimate is what the regular schedule gave).
        """
        started = time.perf_counter()
        w, r, p = self.window, self.relinearization, self.progress
        finish_job(r.job)
        r.job = None
        if w.sightings_waiting:
            self._link_robot_sightings(final=True)
        if w.indices:
            with self._blas.limit():
                self.solve(final=True)
                if self.config.global_solve.every:  # end on every factor re-solved: a diverged window recovers
                    self.relinearize_globally(final=True)
        decisions = r.decisions + [(g, judge(w, g, self._reject_bound)) for g in w.indices if g in w.observations]
        if w.several:  # poses left the window out of step order
            decisions.sort(key=lambda d: d[0])
        rejected = np.concatenate([d[1] for d in decisions]) if decisions else np.zeros(0, dtype=bool)
        estimate = Estimate(
            self.name,
            self.trajectory(),
            tuple(w.landmark_ids),
            w.landmarks.copy(),
            {
                "rejected": rejected,
                "solves": p.solves,
                "marginalized_poses": p.marginalized,
                "global_solves": r.solves,
                "global_rejections": r.rejections,
                "global_failures": list(r.failures),
                "landmarks_released": p.released,
                **adapted_info(self.state.adaptation, self.config.adaptation),
                **self._robot_info(),
                **fix_counts(self.progress.fixes),
                "window": self.config.window.size,
                "relinearize_every": self.config.relinearize_every,
                "linearization": self.config.linearization,
                "pose_covariance": self.config.pose_covariance,
                "final_solve_s": time.perf_counter() - started,
                **self.association.book.info(),
            },
            landmark_covs=self.landmark_marginals(),
            landmark_joint=self.landmark_joint(),
        )
        if self.association.stream is None:
            return estimate
        with self._blas.limit():
            return paired_again(estimate, self.association.stream, self.config)

    # -- covariances -----------------------------------------------------------------------------
    def association_covariance(self, indices: Index, exact: bool = True) -> Array:
        """Joint covariance of the newest pose and landmarks ``indices`` (c,), shape (3 + 2c, 3 + 2c): usually the
        last solve's information carried through the newest odometry (:func:`~.covariance.propagated_covariance`,
        which says when, ``exact`` or not); else the window (without the newest pose's sightings, being associated)
        linearized at the current estimate (:func:`~.covariance.window_covariance`)."""
        propagated = propagated_covariance(self.association.solved, self.window, self.prior, indices, exact)
        if propagated is not None:
            return propagated
        linearized = linearize(self.window, self.prior, self.config.robust.loss, self.config.fej)
        return window_covariance(linearized, self.prior, indices, self.window.map_covariance)

    def landmark_joint(self) -> Array:
        """Joint covariance of every landmark, shape (2M, 2M), as :meth:`landmark_marginals` gives the blocks."""
        return self._at_estimate(landmark_joint, lambda m: (2 * m, 2 * m))

    def landmark_marginals(self) -> Array:
        """2x2 marginal covariance of every landmark at the current estimate, shape (M, 2, 2): the window's factors and
        the reduced prior linearized once (no iteration, no state change); NaN where the system is singular."""
        return self._at_estimate(landmark_marginals, lambda m: (m, 2, 2))

    def _at_estimate(
        self, covariance: Callable[[Linearized, Prior | None, int], Array], empty: Callable[[int], tuple[int, ...]]
    ) -> Array:
        """``covariance`` of the window linearized at the current estimate (NaN, shape ``empty(M)``, before a pose)."""
        count = len(self.window.landmark_ids)
        if not self.window.indices:
            return np.full(empty(count), np.nan)
        with self._blas.limit():
            linearized = linearize(self.window, self.prior, self.config.robust.loss, self.config.fej)
            return covariance(linearized, self.prior, count)

    # -- association -----------------------------------------------------------------------------
    def _resolve(self, step: Step, start: int) -> tuple[Step, int]:
        """The step with the sightings ``start:`` associated (those not used left out, those kept judged as declared
        by noise adaptation), and where they begin. Without association (every sighting has an id) the step itself."""
        a, w = self.association, self.window
        ids: tuple[LandmarkId | None, ...] | list[LandmarkId | None] = step.landmarks[start:]  # or as associated
        needed = a.book.needs(ids)
        if start == 0:
            a.resolved = None
        if not needed and a.resolved is None:
            return step, start
        base = a.resolved if a.resolved is not None else step
        cut = len(base.landmarks) if a.resolved is not None else start
        if needed:
            a.book.expire(step.index)
            ids = a.book.assign_ids(
                step.index,
                ids,
                step.z[start:],
                step.z_cov[start:],
                step.z_model[start:],
                w.poses[w.indices[-1]].copy(),
                w.pose_cov,
                w.landmarks,
                w.landmark_ids,
                self.association_covariance,
            )
        keep = np.array([lid is not None for lid in ids], dtype=bool)
        arrays: dict[str, Any] = {
            f: np.concatenate([getattr(base, f)[:cut], getattr(step, f)[start:][keep]]) for f in SIGHTING_ARRAYS
        }
        if needed:
            arrays["z_widening"][cut:] = 1.0
        landmarks = base.landmarks[:cut] + tuple(lid for lid, ok in zip(ids, keep) if ok)
        a.resolved = replace(step, landmarks=landmarks, **arrays)
        return a.resolved, cut

    def _adapt(self, step: Step, start: int) -> None:
        """Fold the newest pose's sightings ``start:`` of landmarks already mapped into the noise adaptation."""
        w, ids = self.window, step.landmarks[start:]
        rows = [k for k, lid in enumerate(ids) if lid in w.index] if self.config.adaptation.enabled else []
        if not rows:
            return
        indices = np.array([w.index[cast(LandmarkId, ids[k])] for k in rows], dtype=np.int64)
        unique, inverse = np.unique(indices, return_inverse=True)
        columns = np.r_[np.arange(3), 3 + (2 * inverse[:, None] + np.arange(2)).reshape(-1)]
        if is_unknown(joint := self.association_covariance(unique, exact=False)):  # no information: nothing to read
            return
        joint = joint[np.ix_(columns, columns)]
        at = start + np.array(rows)
        pose, z, R, model = w.poses[w.indices[-1]], step.z[at], step.z_cov[at], step.z_model[at]
        own, state = step.z_own_cov()[at], self.state.adaptation
        rise = fold_sightings(state, pose, w.landmarks[indices], z, R, own, model, joint, self.config.adaptation)
        if rise > 1.0 and self.prior is not None:
            self.prior.Sigma *= rise  # its fold-ins took the odometry too sure, as the EKF's covariance did

    def _add_retro(self) -> None:
        """Earlier sightings of the landmarks association confirmed just now, at poses still in the window."""
        book = self.association.book
        for lid, g, z, R, model in book.retro:
            if self.window.add_earlier_sighting(lid, g, z, R, model):
                self.relinearization.log.add_sightings(g, (lid,), z[None], R[None], model)
        book.retro = []

    # -- solving ---------------------------------------------------------------------------------
    def solve(self, final: bool = False) -> dict[str, float]:
        """Relinearize the window and solve (``final``: with the final solver settings, at the end of the stream);
        solve again (at most twice) when consensus moved landmarks. The last solve's report (iterations, costs)."""
        for depth in range(3):
            report, graph, observed = self._solve_once(final)
            if depth == 2 or not self._consensus(graph, observed):
                break
        return report

    def _solve_once(self, final: bool) -> tuple[dict[str, float], FactorGraph, Index]:
        """One window solve written into the state; (its report, its graph, the landmarks it solved)."""
        w = self.window
        observed = active(w)
        solver = self.config.final_solver if final else self.config.window_solver
        s, result = solve_window(w, self.prior, observed, solver, self.config.robust.loss, self.config.fej)
        for k, g in enumerate(w.indices):
            w.poses[g] = result.poses[k]
        w.landmarks[observed] = result.landmarks
        if s.recover is not None:
            passive, positions = s.recover(result.poses[s.prior_poses], result.landmarks)
            w.landmarks[passive] = positions
        layout, info, p = s.layout, result.information, self.prior
        invariant = self.config.linearization == "invariant"
        turned = carried(p, w.landmarks, w.poses[p.pose]) if invariant and p is not None else None
        if turned is not None:  # the information read with the prior carried to the solution (the solve's own kept)
            lin = linearize(w, turned, self.config.robust.loss)
            layout, info = lin.layout, lin.information
        information = factored(info, w.indices, layout, observed)
        self.association.solved = None
        if information is not None:
            w.pose_cov, self.association.solved = information
            if w.robot_cov and self.association.solved is not None:  # the other robots' newest poses, now
                w.robot_cov.update(pose_marginals(self.association.solved, list(w.robot_cov)))
        w.since_solve = 0
        w.unsolved.clear()
        self.progress.solves += 1
        report = {"iterations": result.iterations, "cost_before": result.initial_cost, "cost_after": result.final_cost}
        return report, s.graph, observed

    def _consensus(self, graph: FactorGraph, observed: Index) -> bool:
        """Move landmarks the window's sightings place elsewhere (:func:`~.window.consensus`), releasing those the
        prior holds; True when something moved."""
        if not (self.config.robust.consensus and np.isfinite(self._reject_bound)) or len(graph.obs_pose) == 0:
            return False
        held = self.prior.landmarks if self.prior is not None else np.zeros(0, dtype=np.int64)
        w = self.window
        outside = None if w.several else sightings_outside(self.relinearization.log, w)
        moves, stale = consensus(graph, observed, w.values(), w.landmarks, held, self._reject_bound, outside)
        for j, position in moves:
            w.landmarks[j] = position
        if stale:
            assert self.prior is not None
            self.prior, count = release(self.prior, stale)
            self.progress.released += count
            self.association.solved = None
        return bool(moves)

    # -- marginalization -------------------------------------------------------------------------
    def marginalize_oldest(self) -> None:
        """Fold the oldest window pose's factors into the prior (:func:`~.prior.marginalize`) and drop the pose.

        Its sightings judged outliers at the current estimate are recorded and never folded in.
        """
        w = self.window
        o, n1 = w.indices[0], w.indices[1]
        if self.prior is None:
            assert w.start is not None
            p = initial_prior(w.start, w.poses[w.start[0]], w.joint_map())
        else:
            p = self.prior
        assert p.pose == o
        sightings = self._sightings_to_fold(o)
        delta, _, W = w.odometry[n1]
        held = p.landmarks
        self.prior = marginalize(
            p,
            w.poses[o],
            w.landmarks,
            sightings,
            (delta, W),
            (n1, w.poses[n1]),
            self.config.robust.loss,
            self.config.linearization,
            fixes=w.fixes.get(o),
        )
        come = self.prior.landmarks[(self.prior.landmarks < w.map_size) & ~np.isin(self.prior.landmarks, held)]
        if len(come):  # a map's landmarks the prior holds from now on: it carries their priors
            fold_map(self.prior, come, w.map_xy[come], w.map_cov[come])
        w.drop_oldest()
        self.progress.marginalized += 1

    def _sightings_to_fold(self, o: int) -> Sightings | None:
        """Window pose o's sightings to fold into the prior: those judged outliers at the current estimate are
        recorded and left out (None: none left)."""
        w = self.window
        sightings = w.observations.get(o)
        if sightings is not None:
            keep = ~judge(w, o, self._reject_bound)
            self.relinearization.decisions.append((o, ~keep))
            if not keep.all():  # judged outliers are never folded into the prior; the solved information holds them
                if self.association.solved is not None:
                    self.association.solved = replace(self.association.solved, exact=False)
                # Cast: the same five columns, without the outliers.
                sightings = cast(Sightings, tuple(a[keep] for a in sightings)) if keep.any() else None
        return sightings

    # -- global relinearization ------------------------------------------------------------------
    def _global_schedule(self, report: dict[str, float], jump: bool = False) -> dict[str, float]:
        """After a step: hand a finished background solve over, start the next one when due, or after a ``jump``
        (:func:`~.global_solve.jumped`) solve at once, a pending job's older result dropped; the step's report
        with theirs."""
        r, p = self.relinearization, self.progress
        r.since += 1
        p.steps += 1
        job = r.job
        if job is not None and (jump or p.steps >= job.handover) and not self.preview:
            started = time.perf_counter()
            finish_job(job)
            r.job = None
            if job.error is not None:  # told in this step's report and in the estimate's details
                r.failures.append(job.error)
                report = {**report, "global_failed": 1.0}
            if job.result is not None and not jump:  # after a jump its older result is dropped: solved below
                if job.released != p.released:  # consensus corrected the map since it started
                    report = {**report, **self.relinearize_globally(), "global_stale": 1.0}
                else:
                    report = {**report, **self._apply_global(job.result, job.n_poses, at_once=False)}
                    report["global_s"] = time.perf_counter() - started
        if jump and len(self.window.history) and not self.preview:
            r.since = 0
            return {**report, **self.relinearize_globally(), "global_jump": 1.0}
        if is_due(self.config, r, p.steps, self.window) and not self.preview:
            if self.config.global_solve.delay:
                inputs = global_inputs(r, self.window)
                r.since = 0
                if inputs is not None:
                    r.job = start_job(inputs, self.config, p.steps, self.name, p.released)
            else:
                r.since = 0
                report = {**report, **self.relinearize_globally()}
        return report

    def relinearize_globally(self, final: bool = False) -> dict[str, float]:
        """Re-solve every factor from the current estimate now; revise the history; re-anchor the prior there
        (``final``: at the end of the stream, see :meth:`_apply_global`)."""
        started = time.perf_counter()
        inputs = global_inputs(self.relinearization, self.window)
        if inputs is None:
            return {}
        result = solve_now(inputs, global_solver(self.config), self.config.robust.loss)
        report = self._apply_global(result, len(inputs.poses), at_once=True, final=final)
        report["global_s"] = time.perf_counter() - started
        return report

    def _apply_global(self, result: SolveResult, n_poses: int, at_once: bool, final: bool = False) -> dict[str, float]:
        """Write a global solution's revision (:func:`~.global_solve.revise`) into the state; its report.

        ``final`` (the end of the stream, one robot): a solution whose prior would be refused is still taken when
        it lowered the cost, the prior left where it was (no step follows that it would carry)."""
        r, w = self.relinearization, self.window
        revision = revise(result, n_poses, at_once, w, self.prior, r, self.config)
        if revision is None:
            retried = rejudged_solve(result, n_poses, at_once, w, self.prior, r, self.config, self._reject_bound)
            if retried is None and final and not w.several and result.final_cost < result.initial_cost:
                history, _, landmarks = followed(result, n_poses, at_once, w)
                retried = (result, Revision(history, landmarks, None), r.decisions)
            if retried is None:
                r.rejections += 1
                return {"global_rejected": 1.0}
            result, revision, r.decisions = retried
            at_once = True
        w.history.replace(revision.history)
        self.association.solved = None
        if at_once:
            for g in w.indices:
                w.poses[g] = result.poses[g].copy()
            w.landmarks = revision.landmarks
        if revision.prior is not None:
            self.prior = revision.prior
        r.solves += 1
        return {
            "global_iterations": result.iterations,
            "global_cost_before": result.initial_cost,
            "global_cost_after": result.final_cost,
        }
