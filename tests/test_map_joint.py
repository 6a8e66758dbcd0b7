"""A map's joint covariance: saved by the EKF and the smoother, read back, and used as one prior by every estimator."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import numerical_graph_jacobian
from inprocess import run_cli

from online_slam.errors import InputError
from online_slam.estimators.smoother import SlidingWindowSmoother, SmootherConfig, WindowConfig
from online_slam.estimators.smoother.covariance import landmark_joint, landmark_marginals
from online_slam.estimators.smoother.prior import split
from online_slam.estimators.smoother.window import linearize as linearize_window
from online_slam.factors.graph import DenseAssembler, FactorGraph, layout, linearize
from online_slam.factors.information import sqrt_information
from online_slam.frontend.steps import FrontEnd
from online_slam.pipeline import MapConfig, ReplayConfig, replay
from online_slam.sources.landmark_map import LandmarkMap, map_from_json, read_map, write_map
from online_slam.sources.worlds import square_world

ROOT = Path(__file__).resolve().parents[1]


def spd(rng: np.random.Generator, n: int) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A @ A.T + 0.1 * np.eye(n)


def graph_with_priors(joint: np.ndarray | None, cov: np.ndarray) -> FactorGraph:
    graph = FactorGraph.build(2, 3, fixed_poses=[0], odo_from=[0], odo_to=[1], odo_delta=[[1.0, 0.0, 0.1]],
                              odo_cov=[np.eye(3)], obs_pose=[1], obs_landmark=[2], obs_z=[[2.0, 0.3]],
                              obs_cov=[np.eye(2)])  # fmt: skip
    lp = {"lp_landmark": np.array([2, 0]), "lp_mean": np.array([[1.5, 0.5], [0.2, -0.3]])}
    lp["lp_sqrt_info"] = sqrt_information(cov)
    if joint is not None:
        lp["lp_joint"] = sqrt_information(joint)
    return dataclasses.replace(graph, **lp)


def test_a_joint_map_file_round_trips_and_a_version_1_file_still_reads(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    joint = spd(rng, 6)
    original = LandmarkMap.of([3, "tree-7", 9], rng.normal(size=(3, 2)), None, "s", joint)
    assert np.array_equal(original.cov[1], joint[2:4, 2:4])
    write_map(tmp_path / "m.json", original)
    again = read_map(tmp_path / "m.json")
    assert again == original and again.joint is not None
    assert again != dataclasses.replace(original, joint=None)
    old = json.loads((tmp_path / "m.json").read_text())
    old["version"] = 1
    del old["joint_cov"]
    assert map_from_json(old).joint is None and np.array_equal(map_from_json(old).cov, original.cov)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t: t.update(version=1), "not in a version 1 map"),
        (lambda t: t.update(joint_cov=[[1.0, 0.0], [0.0, 1.0]]), "expected 4x4 numbers (2 per landmark), found 2 rows"),
        (lambda t: t["joint_cov"][2].pop(), "found rows of other lengths"),
        (lambda t: t.update(joint_cov=None), "found null"),
        (lambda t: t["joint_cov"][0].__setitem__(3, 0.9), "not symmetric (row 0, column 3)"),
        (lambda t: [t["joint_cov"][i].__setitem__(i, 5.0) for i in (2, 3)], "diagonal block 1 is not landmarks[1]"),
        (lambda t: t["joint_cov"][0].__setitem__(2, float("nan")), "expected a finite number"),
    ],
)
def test_a_bad_joint_covariance_is_one_error_naming_it(change, message: str) -> None:  # noqa: ANN001
    joint = np.array([[1.0, 0.0, 0.5, 0.1], [0.0, 1.0, 0.2, 0.5], [0.5, 0.2, 1.0, 0.0], [0.1, 0.5, 0.0, 1.0]])
    tree = LandmarkMap.of([1, 2], [[0.0, 0.0], [1.0, 1.0]], None, "", joint).to_json()
    change(tree)
    with pytest.raises(InputError) as caught:
        map_from_json(json.loads(json.dumps(tree)), "m.json")
    assert caught.value.field == "joint_cov" and message in str(caught.value)


def test_a_joint_covariance_that_is_not_positive_semi_definite_is_refused() -> None:
    joint = np.eye(4)
    joint[0, 2] = joint[2, 0] = joint[1, 3] = joint[3, 1] = 1.5  # blocks fine, the whole indefinite
    tree = LandmarkMap.of([1, 2], [[0.0, 0.0], [1.0, 1.0]], None, "", joint).to_json()
    with pytest.raises(InputError, match="joint_cov: not positive semi-definite"):
        map_from_json(tree, "m.json")


def test_the_joint_landmark_prior_has_the_numerical_jacobian_and_both_assemblers_agree() -> None:
    rng = np.random.default_rng(1)
    joint = spd(rng, 4)
    cov = np.array([joint[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] for k in range(2)])
    graph = graph_with_priors(joint, cov)
    poses, landmarks = np.array([[0.0, 0.0, 0.0], [1.0, 0.1, 0.2]]), rng.normal(size=(3, 2)) + 2.0
    r, J = linearize(graph, layout(graph), poses, landmarks)
    assert np.allclose(J.toarray(), numerical_graph_jacobian(graph, poses, landmarks), atol=1e-5)
    H, g, cost = DenseAssembler(graph, layout(graph, entries=False))(poses, landmarks)
    assert np.allclose(H, (J.T @ J).toarray()) and np.allclose(g, J.T @ r) and cost == pytest.approx(0.5 * r @ r)
    # the priors' part of the cost is the joint Gaussian's
    e = (landmarks[[2, 0]] - graph.lp_mean).reshape(-1)
    assert np.sum(r[-4:] ** 2) == pytest.approx(e @ np.linalg.solve(joint, e))


def test_a_block_diagonal_joint_prior_is_the_independent_priors() -> None:
    rng = np.random.default_rng(2)
    cov = np.array([spd(rng, 2), spd(rng, 2)])
    joint = np.zeros((4, 4))
    joint[:2, :2], joint[2:, 2:] = cov
    poses, landmarks = np.array([[0.0, 0.0, 0.0], [1.0, 0.1, 0.2]]), rng.normal(size=(3, 2)) + 2.0
    with_joint, independent = graph_with_priors(joint, cov), graph_with_priors(None, cov)
    r1, J1 = linearize(with_joint, layout(with_joint), poses, landmarks)
    r2, J2 = linearize(independent, layout(independent), poses, landmarks)
    assert np.allclose(r1, r2) and np.allclose((J1.T @ J1).toarray(), (J2.T @ J2).toarray())


def smoother_on_square(size: int) -> SlidingWindowSmoother:
    smoother = SlidingWindowSmoother(SmootherConfig(window=WindowConfig(size=size, distance=0.0)))
    for step in FrontEnd().steps(square_world()):
        smoother.step(step)
    return smoother


def test_the_smoothers_joint_covariance_is_the_window_and_prior_gaussian() -> None:
    smoother = smoother_on_square(4)
    w, prior = smoother.window, smoother.prior
    assert prior is not None
    linearized = linearize_window(w, prior, smoother.config.robust.loss, smoother.config.fej)
    count = len(w.landmark_ids)
    joint = landmark_joint(linearized, prior, count)
    s = split(prior, linearized.active)
    assert len(s.passive) > 0  # landmarks only the prior holds: the regression's part is tested
    blocks = joint.reshape(count, 2, count, 2)[np.arange(count), :, np.arange(count), :]
    marginals = landmark_marginals(linearized, prior, count)
    held = np.isfinite(marginals).all(axis=(1, 2))
    assert np.allclose(blocks[held], marginals[held], rtol=1e-9, atol=1e-14)
    # Independently: the window's factors (its information less the reduced prior's) plus the prior's whole
    # information over [window variables..., passive landmarks], inverted.
    quadratic, H = linearized.quadratic, linearized.information
    assert quadratic is not None and H is not None
    n, order = len(H), np.r_[s.order, s.passive]
    factors = H.copy()
    factors[np.ix_(quadratic.columns, quadratic.columns)] -= quadratic.information
    full = np.zeros((n + len(s.passive), n + len(s.passive)))
    full[:n, :n] = factors
    where = np.r_[quadratic.columns, n + np.arange(len(s.passive))]
    full[np.ix_(where, where)] += np.linalg.inv(prior.Sigma[np.ix_(order, order)])
    covariance = np.linalg.inv(full)
    columns = np.full(2 * count, -1)
    active_columns = linearized.layout.landmark_column[np.arange(len(linearized.active))]
    columns.reshape(-1, 2)[linearized.active] = active_columns[:, None] + np.arange(2)
    columns.reshape(-1, 2)[prior.landmarks[~s.is_active]] = n + np.arange(len(s.passive)).reshape(-1, 2)
    known = columns >= 0
    expected = covariance[np.ix_(columns[known], columns[known])]
    assert np.allclose(joint[np.ix_(known, known)], expected, rtol=1e-6, atol=1e-10)


def test_runs_save_the_joint_covariance_and_reuse_it_in_every_estimator(tmp_path: Path) -> None:
    first = replay(square_world(), name="square")
    assert first.map is not None and first.map.final is not None
    saved = first.map.final
    assert saved.joint is not None and np.all(np.linalg.eigvalsh(saved.joint) > 0)
    assert np.abs(saved.joint - dataclasses.replace(saved, joint=None).covariance).max() > 1e-4  # correlated
    path, independent = tmp_path / "joint.json", tmp_path / "independent.json"
    write_map(path, saved)
    write_map(independent, dataclasses.replace(saved, joint=None))
    errors: dict[str, dict[str, list[float]]] = {"joint": {}, "independent": {}}
    for label, file in (("joint", path), ("independent", independent)):
        config = dataclasses.replace(ReplayConfig(), map=MapConfig(str(file)))
        for seed in (1, 2, 3, 4):  # fresh noise on the same world
            results = replay(square_world(seed), config, name="square")
            assert results.map is not None and results.map.joint == (label == "joint") and results.map.loaded == 12
            for name, e in results.estimators.items():
                errors[label].setdefault(name, []).append(float(e.final_rmse_m or np.nan))
                if name != "batch":
                    errors[label].setdefault(name + " nees", []).append(float(e.nees_mean or np.nan))
    for name, values in errors["joint"].items():  # the map's shared error is corrected by the new run's data
        assert np.mean(values) < np.mean(errors["independent"][name]), name


def test_the_table_says_which_map_the_run_started_from(tmp_path: Path) -> None:
    path = tmp_path / "map.json"
    write_map(path, LandmarkMap.of([0, 1], [[-1.0, -1.0], [1.0, 1.0]], np.tile(0.01 * np.eye(2), (2, 1, 1))))
    run = run_cli("replay", "square", "--map", str(path), "--estimators", "ekf")
    assert run.returncode == 0, run.stderr
    assert f"started from a map of 2 landmarks ({path}): independent priors" in run.stdout
