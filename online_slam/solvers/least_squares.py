"""Levenberg-Marquardt (Gauss-Newton when undamped) on the normal equations, dense or sparse by size.

Each iteration linearizes every factor analytically (:func:`online_slam.factors.linearize`), forms
``H = J^T J`` and ``g = J^T r``, and solves ``(H + lambda diag(H)) dx = -g``. Problems with a dense prior (every
window solve of the smoother) or at most :data:`DENSE_LIMIT` free variables assemble H dense and solve it by
Cholesky; the others (the batch, global relinearizations) by a sparse LDL^T factorisation (QDLDL with an AMD
ordering; the symbolic analysis is done once and reused while the sparsity pattern holds). Damping follows
Nielsen's rule: shrink after a good step, grow after a rejected one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
import qdldl
import scipy.linalg as la
import scipy.sparse as sp
from numpy.typing import NDArray

from online_slam.factors.graph import (
    DenseAssembler,
    FactorGraph,
    JacobianPoint,
    SparseLayout,
    cost,
    evaluate,
    layout,
    linearize,
)
from online_slam.factors.robust import RobustLoss
from online_slam.geometry.angles import wrap
from online_slam.solvers.config import SolverConfig

Array = NDArray[np.float64]

DENSE_LIMIT = 600
"""Problems with at most this many free variables are solved with dense normal equations."""


@dataclass(frozen=True)
class SolveResult:
    """Outcome of a solve: the estimate and how the iterations went. Costs are ``0.5 * |r|^2``."""

    poses: Array
    """Estimated poses, shape (n_poses, 3)."""
    landmarks: Array
    """Estimated landmarks, shape (n_landmarks, 2)."""
    iterations: int
    """Iterations performed (accepted and rejected)."""
    converged: bool
    """True when a tolerance was met before ``max_iterations``."""
    initial_cost: float
    """Cost at the initial values."""
    final_cost: float
    """Cost at the returned values."""
    message: str
    """Why the solver stopped."""
    information: Array | sp.csr_matrix | None = None
    """``J^T J`` (plus the quadratic prior) at the solution, over the free columns; only when asked for."""


@dataclass(frozen=True)
class QuadraticPrior:
    """A dense Gaussian prior on some state columns: ``0.5 d^T A d + b^T d`` with ``d = x[columns] - x_lin``.

    Angle entries of d are wrapped. The linearization point ``x_lin`` stays fixed: the prior is a quadratic
    in d whatever the current estimate (a marginalization prior keeps its first-estimate Jacobians).
    """

    columns: NDArray[np.int64]
    """State columns (in the solver's layout) the prior is on, shape (c,)."""
    x_lin: Array
    """Linearization point of those columns, shape (c,)."""
    angle: NDArray[np.bool_]
    """Which of the columns are headings, shape (c,)."""
    information: Array
    """A, symmetric positive semi-definite, shape (c, c)."""
    gradient: Array
    """b, the gradient at d = 0, shape (c,)."""

    def delta(self, x: Array) -> Array:
        """d for a full free-state vector x, shape (n_columns,) -> (c,)."""
        d = x[self.columns] - self.x_lin
        d[self.angle] = wrap(d[self.angle])
        return d

    def cost(self, x: Array) -> float:
        """The prior's cost at x (up to a constant)."""
        d = self.delta(x)
        return 0.5 * float(d @ self.information @ d) + float(self.gradient @ d)


def flatten(graph_layout: SparseLayout, poses: Array, landmarks: Array) -> Array:
    """The free-state vector (free poses, then landmarks) in the layout's column order, shape (n_columns,)."""
    free = graph_layout.pose_column >= 0
    x = np.empty(graph_layout.n_columns)
    columns = graph_layout.pose_column[free]
    x[columns[:, None] + np.arange(3)] = poses[free]
    n_pose_cols = 3 * int(free.sum())
    x[n_pose_cols:] = landmarks.reshape(-1)
    return x


def retract(graph_layout: SparseLayout, poses: Array, landmarks: Array, dx: Array) -> tuple[Array, Array]:
    """Apply an update to the free variables (headings wrapped).

    Args:
        graph_layout: Column layout of the free variables.
        poses: Pose values, shape (n_poses, 3).
        landmarks: Landmark values, shape (n_landmarks, 2).
        dx: Update, shape (n_columns,).

    Returns:
        New (poses, landmarks); the inputs are not modified.
    """
    poses = poses.copy()
    free = graph_layout.pose_column >= 0
    columns = graph_layout.pose_column[free]
    poses[free] += dx[columns[:, None] + np.arange(3)]
    poses[:, 2] = wrap(poses[:, 2])
    n_pose_cols = 3 * int(free.sum())
    landmarks = landmarks + dx[n_pose_cols:].reshape(-1, 2)
    return poses, landmarks


class SparseLDL:
    """Solves ``A x = b`` for sparse symmetric positive definite A, reusing the symbolic factorisation."""

    def __init__(self) -> None:
        self._solver: qdldl.Solver | None = None
        self._pattern: tuple[NDArray[np.int32], NDArray[np.int32]] | None = None

    def solve(self, A: sp.spmatrix, b: Array) -> Array:
        """Factorise A (upper triangle used) and solve.

        Args:
            A: Symmetric positive definite matrix, shape (n, n).
            b: Right-hand side, shape (n,).

        Returns:
            x, shape (n,).

        Raises:
            ValueError: When the factorisation fails (A singular or indefinite).
        """
        upper = sp.triu(A, format="csc")
        upper.sort_indices()
        pattern = self._pattern
        if (
            self._solver is not None
            and pattern is not None
            and np.array_equal(pattern[0], upper.indptr)
            and np.array_equal(pattern[1], upper.indices)
        ):
            self._solver.update(upper)
        else:
            self._solver = qdldl.Solver(upper)
            self._pattern = (upper.indptr.copy(), upper.indices.copy())
        x = self._solver.solve(b)
        if not np.all(np.isfinite(x)):
            raise ValueError("singular or indefinite system")
        return x


@dataclass(frozen=True)
class _Problem:
    """What one solve minimises: the factors (in a column layout), the loss and the prior."""

    graph: FactorGraph
    sparse: SparseLayout
    loss: RobustLoss | None
    prior: QuadraticPrior | None
    assemble: DenseAssembler | None
    """Dense normal-equation assembler, or None for the sparse path."""
    at: JacobianPoint | None = None
    """Where some variables' Jacobians are evaluated (First-Estimates Jacobians), or None: at the current values."""

    def system(self, p: Array, l: Array) -> tuple[Array | sp.spmatrix, Array, float]:
        """Normal equations and cost at (p, l), in one pass over the factors."""
        if self.assemble is not None:
            H, g, value = self.assemble(p, l, self.loss, self.at)
        else:
            r, J = linearize(self.graph, self.sparse, p, l, self.loss, self.at)
            H, g = J.T @ J, J.T @ r
            value = 0.5 * float(r @ r) if self.loss is None else cost(self.graph, evaluate(self.graph, p, l), self.loss)
        prior = self.prior
        if prior is not None:
            x = flatten(self.sparse, p, l)
            H[np.ix_(prior.columns, prior.columns)] += prior.information
            g[prior.columns] += prior.information @ prior.delta(x) + prior.gradient
            value += prior.cost(x)
        return H, g, value

    def cost(self, p: Array, l: Array) -> float:
        """The cost alone at (p, l)."""
        value = cost(self.graph, evaluate(self.graph, p, l), self.loss)
        return value + self.prior.cost(flatten(self.sparse, p, l)) if self.prior is not None else value

    def damped_step(self, H: Array | sp.spmatrix, g: Array, lam: float, ldl: SparseLDL) -> Array:
        """Solve ``(H + lam diag(H)) dx = -g``; raises ValueError / LinAlgError when it is not positive definite."""
        diagonal = np.maximum(H.diagonal(), 1e-12)
        if self.assemble is None:
            sparse = cast("sp.spmatrix", H)  # without an assembler, H is sparse
            return ldl.solve(sparse.tocsc() + sp.diags(lam * diagonal, format="csc"), -g)
        return la.cho_solve(la.cho_factor(H + np.diag(lam * diagonal)), -g)


def solve(
    graph: FactorGraph,
    poses: Array,
    landmarks: Array,
    config: SolverConfig | None = None,
    *,
    loss: RobustLoss | None = None,
    prior: QuadraticPrior | None = None,
    return_information: bool = False,
    dense: bool | None = None,
    graph_layout: SparseLayout | None = None,
    jacobian_point: JacobianPoint | None = None,
) -> SolveResult:
    """Minimise ``0.5 * |r(x)|^2`` (robust on observations) plus an optional quadratic prior.

    Args:
        graph: The factor graph.
        poses: Initial poses, shape (n_poses, 3); fixed poses keep these values.
        landmarks: Initial landmarks, shape (n_landmarks, 2).
        config: Solver settings.
        loss: Robust loss on observation factors, or None for plain least squares.
        prior: A dense quadratic prior on some columns of ``layout(graph)``; the system is then solved densely.
        return_information: Also return ``J^T J`` (+ prior) at the last linearization point (the solution, or one
            converged step before it), for covariances.
        dense: Assemble and factor the normal equations densely; default: when a prior is given or the
            problem has at most ``DENSE_LIMIT`` free variables (a smoother's window), sparse otherwise.
        graph_layout: ``layout(graph)`` when the caller has it already.
        jacobian_point: Evaluate some variables' Jacobians at fixed values (First-Estimates Jacobians; the
            residuals and the cost stay at the iterate): the iterations then converge where ``J^T r`` with those
            Jacobians vanishes, and the information is that of the fixed linearization.

    Returns:
        The solution and convergence report.
    """
    cfg = config or SolverConfig()
    poses = np.array(poses, dtype=float).reshape(graph.n_poses, 3)
    landmarks = np.array(landmarks, dtype=float).reshape(graph.n_landmarks, 2)
    sparse = graph_layout if graph_layout is not None else layout(graph, entries=False)
    use_dense = dense if dense is not None else (prior is not None or sparse.n_columns <= DENSE_LIMIT)
    if not use_dense and len(sparse.keep) == 0 and graph.n_residuals:
        sparse = layout(graph)  # the sparse path needs every Jacobian entry's place
    assemble = DenseAssembler(graph, sparse) if use_dense else None
    problem = _Problem(graph, sparse, loss, prior, assemble, jacobian_point)
    H, g, current = problem.system(poses, landmarks)
    if sparse.n_columns == 0:
        return SolveResult(poses, landmarks, 0, True, current, current, "no free variables")
    return _iterate(problem, cfg, _Iterate(poses, landmarks, H, g, current), return_information)


@dataclass
class _Iterate:
    """The current point of Levenberg-Marquardt and its normal equations."""

    poses: Array
    landmarks: Array
    H: Array | sp.spmatrix
    g: Array
    cost: float


def _iterate(problem: _Problem, cfg: SolverConfig, it: _Iterate, return_information: bool) -> SolveResult:
    """Levenberg-Marquardt iterations from ``it`` until a tolerance or ``cfg.max_iterations``."""
    initial_cost = it.cost
    ldl = SparseLDL()
    lam, nu = cfg.initial_lambda, 2.0
    message = "maximum iterations reached"
    converged = False
    iterations = 0
    while iterations < cfg.max_iterations:
        iterations += 1
        if np.max(np.abs(it.g)) < cfg.gradient_tolerance:
            converged, message = True, "gradient below tolerance"
            break
        try:
            dx = problem.damped_step(it.H, it.g, lam, ldl)
        except (ValueError, la.LinAlgError):  # singular or indefinite: damp harder
            lam, nu = max(lam, 1e-9) * nu, 2 * nu
            continue
        predicted = -float(dx @ it.g) - 0.5 * float(dx @ (it.H @ dx))
        new_poses, new_landmarks = retract(problem.sparse, it.poses, it.landmarks, dx)
        new_cost = problem.cost(new_poses, new_landmarks)
        if lam <= cfg.initial_lambda and 0.0 <= predicted <= cfg.relative_cost_tolerance * max(it.cost, 1e-300):
            # The (barely damped) quadratic model promises no meaningful decrease: converged. Take this last,
            # tiny Newton step when it does not raise the cost (it costs one residual evaluation, no assembly).
            if new_cost <= it.cost:
                it.poses, it.landmarks, it.cost = new_poses, new_landmarks, new_cost
            converged, message = True, "predicted decrease below tolerance"
            break
        # The cost alone decides acceptance and convergence; the normal equations are assembled only at an
        # accepted point the iterations go on from (at convergence H stays the last one assembled, one small
        # step away: what the information matrix is used for does not see the difference).
        actual = it.cost - new_cost
        if actual >= 0.0 and np.isfinite(new_cost):
            rho = actual / predicted if predicted > 0 else 1.0
            undamped = lam <= cfg.initial_lambda
            it.poses, it.landmarks, it.cost = new_poses, new_landmarks, new_cost
            lam = lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3) if lam > 0 else 0.0
            nu = 2.0
            reason = _converged(cfg, dx, actual, predicted, it.cost, undamped)
            if reason:
                converged, message = True, reason
                break
            it.H, it.g, it.cost = problem.system(it.poses, it.landmarks)
        else:
            if np.max(np.abs(dx)) < cfg.step_tolerance:
                converged, message = True, "step below tolerance"
                break
            lam, nu = max(lam, 1e-9) * nu, 2 * nu
    information = it.H if return_information else None
    return SolveResult(it.poses, it.landmarks, iterations, converged, initial_cost, it.cost, message, information)


def _converged(cfg: SolverConfig, dx: Array, actual: float, predicted: float, cost: float, undamped: bool) -> str:
    """Why an accepted step ends the iterations, or "" when they go on."""
    if np.max(np.abs(dx)) < cfg.step_tolerance:
        return "step below tolerance"
    if actual <= cfg.relative_cost_tolerance * max(cost + actual, 1e-300):
        return "cost change below tolerance"
    if undamped and abs(actual - predicted) <= cfg.model_tolerance * cost:
        return "quadratic model held within tolerance"
    return ""
