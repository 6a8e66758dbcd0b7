"""Factors and the sparse solver: whole-graph Jacobian vs numerical, fixed vs prior, convergence, edge cases."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import numerical_jacobian

from online_slam import Slam
from online_slam.estimators import BatchEstimator
from online_slam.factors import FactorGraph, evaluate, layout, linearize
from online_slam.factors.graph import DenseAssembler, JacobianPoint
from online_slam.factors.information import FLOOR, floored, sqrt_information
from online_slam.frontend import FrontEnd
from online_slam.geometry import between, wrap
from online_slam.solvers import SolverConfig, solve
from online_slam.sources import GridConfig, grid_world, square_world


def small_graph(rng: np.random.Generator, prior: bool) -> tuple[FactorGraph, np.ndarray, np.ndarray]:
    n, m = 6, 4
    poses = rng.normal(size=(n, 3)) * [3, 3, 2]
    landmarks = rng.normal(size=(m, 2)) * 4
    A = rng.normal(size=(n - 1, 3, 3)) * 0.1
    odo_cov = A @ np.swapaxes(A, 1, 2) + 0.01 * np.eye(3)
    B = rng.normal(size=(10, 2, 2)) * 0.1
    obs_cov = B @ np.swapaxes(B, 1, 2) + 0.001 * np.eye(2)
    kwargs = {"prior_pose": [0], "prior_mean": [[0.1, 0.2, 0.3]], "prior_cov": [np.diag([0.1, 0.2, 0.05])]}
    graph = FactorGraph.build(
        n,
        m,
        fixed_poses=[] if prior else [0],
        **(kwargs if prior else {}),
        odo_from=np.arange(n - 1),
        odo_to=np.arange(1, n),
        odo_delta=rng.normal(size=(n - 1, 3)),
        odo_cov=odo_cov,
        obs_pose=rng.integers(0, n, 10),
        obs_landmark=np.r_[np.arange(m), rng.integers(0, m, 6)],
        obs_z=np.c_[rng.uniform(1, 5, 10), rng.uniform(-3, 3, 10)],
        obs_cov=obs_cov,
    )
    return graph, poses, landmarks


@pytest.mark.parametrize("prior", [True, False])
def test_graph_jacobian_matches_numerical(rng: np.random.Generator, prior: bool) -> None:
    graph, poses, landmarks = small_graph(rng, prior)
    sparse = layout(graph)
    r, J = linearize(graph, sparse, poses, landmarks)
    assert np.allclose(r, evaluate(graph, poses, landmarks))
    free = sparse.pose_column >= 0

    def f(x: np.ndarray) -> np.ndarray:
        p = poses.copy()
        p[free] = x[: 3 * free.sum()].reshape(-1, 3)
        return evaluate(graph, p, x[3 * free.sum() :].reshape(-1, 2))

    x0 = np.r_[poses[free].ravel(), landmarks.ravel()]
    # Residual differences pass through wrap inside evaluate; use small steps away from the branch cut.
    assert np.allclose(J.toarray(), numerical_jacobian(f, x0, eps=1e-7), atol=1e-5)
    assert J.shape == (graph.n_residuals, sparse.n_columns)


def test_jacobian_point_moves_the_jacobians_and_keeps_the_residuals(rng: np.random.Generator) -> None:
    """First-Estimates Jacobians: the rows of the fixed variables' Jacobians are those at their fixed values, the
    residuals those at the current values; the sparse and dense assemblies agree."""
    graph, poses, landmarks = small_graph(rng, True)
    sparse = layout(graph)
    at = JacobianPoint(np.array([1, 3]), poses[[1, 3]] + 0.3, np.array([2]), landmarks[[2]] - 0.5)
    r, J = linearize(graph, sparse, poses, landmarks, at=at)
    _, J_at = linearize(graph, sparse, *at.apply(poses, landmarks))
    _, J_now = linearize(graph, sparse, poses, landmarks)
    np.testing.assert_allclose(r, evaluate(graph, poses, landmarks))
    np.testing.assert_allclose(J.toarray(), J_at.toarray())
    assert np.abs(J.toarray() - J_now.toarray()).max() > 0.01
    H, g, _ = DenseAssembler(graph, layout(graph, entries=False))(poses, landmarks, None, at)
    np.testing.assert_allclose(H, (J.T @ J).toarray(), atol=1e-9)
    np.testing.assert_allclose(g, J.T @ r, atol=1e-9)


def test_solver_recovers_noise_free_problem(rng: np.random.Generator) -> None:
    poses = np.c_[np.arange(10.0), np.zeros(10), wrap(np.linspace(0, 6, 10))]
    landmarks = rng.uniform(-5, 15, size=(5, 2))
    pi, li = np.repeat(np.arange(10), 5), np.tile(np.arange(5), 10)
    d = landmarks[li] - poses[pi, :2]
    z = np.c_[np.hypot(d[:, 0], d[:, 1]), wrap(np.arctan2(d[:, 1], d[:, 0]) - poses[pi, 2])]
    graph = FactorGraph.build(
        10,
        5,
        fixed_poses=[0],
        odo_from=np.arange(9),
        odo_to=np.arange(1, 10),
        odo_delta=between(poses[:-1], poses[1:]),
        odo_cov=np.tile(np.eye(3) * 0.01, (9, 1, 1)),
        obs_pose=pi,
        obs_landmark=li,
        obs_z=z,
        obs_cov=np.tile(np.eye(2) * 0.01, (50, 1, 1)),
    )
    start_poses = poses + rng.normal(size=poses.shape) * [0.3, 0.3, 0.1]
    start_poses[0] = poses[0]
    result = solve(graph, start_poses, landmarks + rng.normal(size=landmarks.shape) * 0.5)
    assert result.converged and result.final_cost < 1e-16
    assert np.allclose(result.poses[:, :2], poses[:, :2], atol=1e-8)
    assert np.allclose(wrap(result.poses[:, 2] - poses[:, 2]), 0, atol=1e-9)
    assert np.all((result.poses[:, 2] >= -np.pi) & (result.poses[:, 2] < np.pi))


def test_fixed_pose_stays_put_and_gradient_vanishes_at_solution() -> None:
    fe, batch = FrontEnd(), BatchEstimator()
    for step in fe.steps(square_world()):
        batch.step(step)
    estimate = batch.finish()
    assert np.array_equal(estimate.poses[0], np.zeros(3))
    graph = batch.log.graph()
    r, J = linearize(graph, layout(graph), estimate.poses, estimate.landmarks)
    H = (J.T @ J).toarray()
    newton_step = np.linalg.solve(H, -(J.T @ r))
    assert np.max(np.abs(newton_step)) < 1e-8  # one more Gauss-Newton step would move nothing


def test_levenberg_marquardt_and_gauss_newton_agree() -> None:
    fe, batch = FrontEnd(), BatchEstimator()
    for step in fe.steps(grid_world(GridConfig(poses=300, seed=3))):
        batch.step(step)
    graph, p0, l0 = batch.log.graph(), np.array(batch.log.poses), batch.log.landmarks
    lm = solve(graph, p0, l0, SolverConfig(initial_lambda=1e-3))
    gn = solve(graph, p0, l0, SolverConfig(initial_lambda=0.0))
    assert lm.converged and gn.converged
    assert np.max(np.abs(lm.poses[:, :2] - gn.poses[:, :2])) < 1e-7


def test_solver_reports_non_convergence() -> None:
    fe, batch = FrontEnd(), BatchEstimator()
    for step in fe.steps(square_world()):
        batch.step(step)
    result = solve(batch.log.graph(), np.array(batch.log.poses), batch.log.landmarks, SolverConfig(max_iterations=1))
    assert not result.converged and result.iterations == 1 and result.message == "maximum iterations reached"
    assert result.final_cost < result.initial_cost


def test_a_solve_that_puts_a_landmark_on_its_sighting_pose_stays_finite_and_quiet() -> None:
    # Gauss-Newton's first step puts the landmark exactly on the pose that sights it (a zero range measured), where
    # the bearing is undefined: no NaN may reach the normal equations, and no warning is printed.
    graph = FactorGraph.build(
        1, 1, fixed_poses=[0], obs_pose=[0], obs_landmark=[0], obs_z=[[0.0, 0.0]], obs_cov=[np.eye(2)]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = solve(graph, np.zeros((1, 3)), np.array([[1.0, 0.0]]), SolverConfig(initial_lambda=0.0))
    assert result.landmarks.tolist() == [[0.0, 0.0]] and result.final_cost == 0.0
    assert result.converged


def test_no_free_variables() -> None:
    graph = FactorGraph.build(1, 0, fixed_poses=[0])
    result = solve(graph, np.zeros((1, 3)), np.zeros((0, 2)))
    assert result.converged and result.iterations == 0


@pytest.mark.parametrize("kind", ["huber", "cauchy"])
def test_robust_loss_weight_is_the_derivative_of_rho(kind: str) -> None:
    from online_slam.factors import RobustLoss

    loss = RobustLoss(kind, 1.5)
    s = np.linspace(0.01, 100.0, 500)
    numeric = (loss.rho(s + 1e-6) - loss.rho(s - 1e-6)) / 2e-6
    assert np.allclose(loss.weight(s), numeric, atol=1e-6)
    assert np.allclose(loss.rho(s[:5] * 1e-4), s[:5] * 1e-4, rtol=1e-3)  # quadratic near zero
    with pytest.raises(ValueError):
        RobustLoss("tukey")


def test_robust_gradient_matches_numerical_cost_gradient(rng: np.random.Generator) -> None:
    """J^T r from the reweighted linearization is the gradient of the robust cost."""
    from online_slam.factors import RobustLoss, cost

    graph, poses, landmarks = small_graph(rng, prior=False)
    loss = RobustLoss("cauchy", 1.0)
    sparse = layout(graph)
    r, J = linearize(graph, sparse, poses, landmarks, loss)
    free = sparse.pose_column >= 0
    x0 = np.r_[poses[free].ravel(), landmarks.ravel()]

    def f(x: np.ndarray) -> np.ndarray:
        p = poses.copy()
        p[free] = x[: 3 * free.sum()].reshape(-1, 3)
        return np.array([cost(graph, evaluate(graph, p, x[3 * free.sum() :].reshape(-1, 2)), loss)])

    assert np.allclose(J.T @ r, numerical_jacobian(f, x0, eps=1e-7)[0], rtol=1e-5, atol=1e-5)


def test_a_covariance_cholesky_refuses_is_factored_with_its_eigenvalues_floored() -> None:
    R = np.array([[np.cos(0.3), -np.sin(0.3), 0.0], [np.sin(0.3), np.cos(0.3), 0.0], [0.0, 0.0, 1.0]])
    cov = R @ np.diag([1e16, 1e-16, 1e-16]) @ R.T  # positive definite, but not in floating point
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(cov)
    W = sqrt_information(cov)
    assert np.isfinite(W).all() and np.allclose(np.triu(W, 1), 0.0)
    assert np.allclose(np.linalg.inv(W.T @ W), floored(cov), rtol=1e-4)  # condition 1e12: 1e-4 is what is left
    assert np.linalg.eigvalsh(floored(cov)).min() == pytest.approx(1e16 * FLOOR, rel=1e-3)
    good = np.diag([4.0, 1.0, 0.25])  # what Cholesky takes is factored as it is
    assert sqrt_information(good).tolist() == np.linalg.inv(np.linalg.cholesky(good)).tolist()


def test_the_smoother_takes_odometry_sigmas_sixteen_orders_apart_across_a_turn() -> None:
    # Found by the fuzzer: each sigma within the validator's bounds, their composition not positive definite in
    # floating point; the smoother's window raised numpy's LinAlgError through Slam.estimate.
    slam = Slam("smoother")
    for k in range(4):
        slam.add_odometry(0.5 * (k + 1), [0.5, 0.0, 0.1], sigma=[1e8, 1e-8, 1e-8])
    slam.add_observation(2.5, 1, 2.0, 0.3, [0.1, 0.01])
    slam.add_odometry(3.0, [0.5, 0.0, 0.1], sigma=[1e8, 1e-8, 1e-8])
    assert all(np.isfinite(slam.estimate().pose))
