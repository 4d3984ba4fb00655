"""MAN^r: manipulability, its exact derivatives, the SPD distance and the scale factor."""

from __future__ import annotations

import numpy as np
import pytest

import hlik
from conftest import ROBOTS
from hlik.criteria.manipulability import (
    arm_manipulability,
    man_cost,
    man_jacobian,
    man_residual,
    mandel,
    manipulability_derivative,
    scale_factor,
    spd_distance,
)
from hlik.human.demo import demo_motion
from hlik.human.manipulability import human_manipulability
from hlik.robot.state import robot_state

STEP = 1e-6


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return hlik.load_robot(request.param)


def random_q(robot, n: int, seed: int) -> np.ndarray:
    lower = np.where(np.isinf(robot.lower), -np.pi, robot.lower)
    upper = np.where(np.isinf(robot.upper), np.pi, robot.upper)
    return np.random.default_rng(seed).uniform(lower, upper, size=(n, robot.dof))


def random_spd(rng: np.random.Generator, shape: tuple[int, ...], scale: float = 1.0) -> np.ndarray:
    g = rng.normal(size=(*shape, 3, 3))
    return scale * (g @ np.swapaxes(g, -1, -2) + 0.1 * np.eye(3))


def central_difference(fun, robot, q: np.ndarray) -> np.ndarray:
    """(F, ..., n) central differences of fun(state) (F, ...) at configurations q (F, n)."""
    f, n = q.shape
    steps = STEP * np.eye(n)
    qs = np.concatenate([q[:, None] + steps, q[:, None] - steps], axis=1).reshape(-1, n)
    values = fun(robot_state(robot, qs, jacobians=True), np.repeat(np.arange(f), 2 * n))
    values = values.reshape(f, 2, n, *values.shape[1:])
    return np.moveaxis((values[:, 0] - values[:, 1]) / (2 * STEP), 1, -1)


def test_manipulability_derivative_matches_finite_differences(robot):
    q = random_q(robot, 3, seed=1)
    analytic = manipulability_derivative(robot, robot_state(robot, q, jacobians=True))
    numeric = central_difference(lambda s, _: arm_manipulability(robot, s), robot, q)
    np.testing.assert_allclose(np.moveaxis(analytic, 2, -1), numeric, atol=1e-7 * np.abs(numeric).max())


def test_man_jacobian_matches_finite_differences(robot):
    q = random_q(robot, 3, seed=2)
    target = random_spd(np.random.default_rng(3), (3, 2), scale=0.01)
    lam = 5.0
    analytic = man_jacobian(robot, robot_state(robot, q, jacobians=True), target, lam)
    numeric = central_difference(lambda s, i: man_residual(robot, s, target[i], lam), robot, q)
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-5 * np.abs(numeric).max())


def test_man_jacobian_at_the_target(robot):
    """All eigenvalues of X equal 1 at the target: the divided differences take their limit."""
    q = random_q(robot, 2, seed=4)
    lam = 3.0
    state = robot_state(robot, q, jacobians=True)
    target = arm_manipulability(robot, state) / lam
    np.testing.assert_allclose(man_residual(robot, state, target, lam), 0.0, atol=1e-10)
    analytic = man_jacobian(robot, state, target, lam)
    numeric = central_difference(lambda s, i: man_residual(robot, s, target[i], lam), robot, q)
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-5 * np.abs(numeric).max())


def test_residual_norm_is_the_spd_distance(robot):
    q = random_q(robot, 4, seed=5)
    state = robot_state(robot, q, jacobians=True)
    target = random_spd(np.random.default_rng(6), (4, 2), scale=0.01)
    residual = man_residual(robot, state, target, 4.0)
    distance = spd_distance(arm_manipulability(robot, state) / 4.0, target)
    np.testing.assert_allclose(np.linalg.norm(residual, axis=-1), distance, rtol=1e-9)
    np.testing.assert_allclose(man_cost(residual), distance.mean(axis=-1), rtol=1e-9)


def test_spd_distance_properties():
    rng = np.random.default_rng(7)
    a, b = random_spd(rng, (20,)), random_spd(rng, (20,))
    g = rng.normal(size=(20, 3, 3))
    d = spd_distance(a, b)
    assert np.all(d > 0)
    np.testing.assert_allclose(spd_distance(b, a), d, rtol=1e-9)
    np.testing.assert_allclose(spd_distance(a, a), 0.0, atol=1e-7)
    ga, gb = g @ a @ np.swapaxes(g, -1, -2), g @ b @ np.swapaxes(g, -1, -2)
    np.testing.assert_allclose(spd_distance(ga, gb), d, rtol=1e-7)
    np.testing.assert_allclose(spd_distance(a, 2.0 * a), np.sqrt(3) * np.log(2.0), rtol=1e-9)


def test_mandel_preserves_the_norm():
    m = random_spd(np.random.default_rng(8), (5,))
    np.testing.assert_allclose(np.linalg.norm(mandel(m), axis=-1), np.linalg.norm(m, axis=(-2, -1)))
    np.testing.assert_allclose(mandel(np.diag([1.0, 2.0, 3.0])), [1, 2, 3, 0, 0, 0])


def test_human_manipulability_is_spd():
    m = human_manipulability(demo_motion().crop(0, 1))
    assert m.shape[1:] == (2, 3, 3) and len(m) > 1
    np.testing.assert_allclose(m, np.swapaxes(m, -1, -2), atol=1e-15)
    assert np.all(np.linalg.eigvalsh(m) > 0)


def test_scale_factor_positive_and_deterministic():
    robot = hlik.load_robot("dual_panda")
    lam = scale_factor(robot, n=1000, seed=3)
    assert np.isfinite(lam) and lam > 0
    assert scale_factor(robot, n=1000, seed=3) == lam
