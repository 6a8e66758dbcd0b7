"""Levenberg-Marquardt (Gauss-Newton when undamped) with a sparse factorisation of the normal equations.

Each iteration linearizes every factor analytically (:func:`online_slam.factors.linearize`), forms
``H = J^T J`` and ``g = J^T r``, and solves ``(H + lambda diag(H)) dx = -g`` by a sparse LDL^T factorisation
(QDLDL with an AMD ordering; the symbolic analysis is done once and reused while the sparsity pattern holds).
Damping follows Nielsen's rule: shrink after a good step, grow after a rejected one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import qdldl
import scipy.sparse as sp
from numpy.typing import NDArray

from online_slam.factors.graph import FactorGraph, SparseLayout, evaluate, layout, linearize
from online_slam.geometry.angles import wrap

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SolverConfig:
    """Settings of the sparse least-squares solver."""

    max_iterations: int = 100
    """Upper bound on accepted plus rejected iterations."""
    initial_lambda: float = 1e-6
    """Initial damping, relative to the diagonal of ``J^T J``; 0 gives pure Gauss-Newton."""
    relative_cost_tolerance: float = 1e-12
    """Stop when an accepted step lowers the cost by less than this fraction."""
    step_tolerance: float = 1e-10
    """Stop when the largest update component is below this (metres / radians)."""
    gradient_tolerance: float = 1e-10
    """Stop when the largest gradient component is below this."""


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


def solve(graph: FactorGraph, poses: Array, landmarks: Array, config: SolverConfig | None = None) -> SolveResult:
    """Minimise ``0.5 * |r(x)|^2`` over the free poses and all landmarks.

    Args:
        graph: The factor graph.
        poses: Initial poses, shape (n_poses, 3); fixed poses keep these values.
        landmarks: Initial landmarks, shape (n_landmarks, 2).
        config: Solver settings.

    Returns:
        The solution and convergence report.
    """
    cfg = config or SolverConfig()
    poses = np.array(poses, dtype=float).reshape(graph.n_poses, 3)
    landmarks = np.array(landmarks, dtype=float).reshape(graph.n_landmarks, 2)
    sparse = layout(graph)
    r, J = linearize(graph, sparse, poses, landmarks)
    cost = initial_cost = 0.5 * float(r @ r)
    if sparse.n_columns == 0:
        return SolveResult(poses, landmarks, 0, True, cost, cost, "no free variables")
    ldl = SparseLDL()
    lam, nu = cfg.initial_lambda, 2.0
    message = "maximum iterations reached"
    converged = False
    iterations = 0
    while iterations < cfg.max_iterations:
        iterations += 1
        H = (J.T @ J).tocsc()
        g = J.T @ r
        if np.max(np.abs(g)) < cfg.gradient_tolerance:
            converged, message = True, "gradient below tolerance"
            break
        diagonal = np.maximum(H.diagonal(), 1e-12)
        damped = H + sp.diags(lam * diagonal, format="csc")
        try:
            dx = ldl.solve(damped, -g)
        except ValueError:  # singular: damp harder
            lam, nu = max(lam, 1e-9) * nu, 2 * nu
            continue
        new_poses, new_landmarks = retract(sparse, poses, landmarks, dx)
        r_new = evaluate(graph, new_poses, new_landmarks)
        new_cost = 0.5 * float(r_new @ r_new)
        predicted = -float(dx @ g) - 0.5 * float(dx @ (H @ dx))
        actual = cost - new_cost
        if actual >= 0.0 and np.isfinite(new_cost):
            rho = actual / predicted if predicted > 0 else 1.0
            poses, landmarks, cost = new_poses, new_landmarks, new_cost
            lam = lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3) if lam > 0 else 0.0
            nu = 2.0
            small_step = np.max(np.abs(dx)) < cfg.step_tolerance
            small_gain = actual <= cfg.relative_cost_tolerance * max(cost + actual, 1e-300)
            r, J = linearize(graph, sparse, poses, landmarks)
            if small_step or small_gain:
                converged = True
                message = "step below tolerance" if small_step else "cost change below tolerance"
                break
        else:
            if np.max(np.abs(dx)) < cfg.step_tolerance:
                converged, message = True, "step below tolerance"
                break
            lam, nu = max(lam, 1e-9) * nu, 2 * nu
    return SolveResult(poses, landmarks, iterations, converged, initial_cost, cost, message)
