"""Self-collision avoidance in the QP, SLSQP and JV: a target inside the torso is refused, pairs apart."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from conftest import ROBOTS, solve_problem
from hlik import load_robot
from hlik.human.demo import demo_motion
from hlik.human.kinematics import forward_kinematics
from hlik.problem.placement import shoulder_placement
from hlik.problem.problem import build_problem
from hlik.robot.collision import DistanceBounds, collision_pairs, pair_distances
from hlik.robot.model import self_contacts
from hlik.robot.state import robot_state
from hlik.solvers import jv, qp, slsqp

SOLVERS = {
    "qp": (qp.solve, qp.QPSettings),
    "slsqp": (slsqp.solve, slsqp.SLSQPSettings),
    "jv": (jv.solve, jv.JVSettings),
}


def _min_distance(robot, q):
    data, pairs = mujoco.MjData(robot.model), collision_pairs(robot)
    out = []
    for qk in q:
        data.qpos[:] = qk
        mujoco.mj_kinematics(robot.model, data)
        mujoco.mj_comPos(robot.model, data)
        d, _ = pair_distances(robot, data, pairs, 1.0)
        out.append(d.min(initial=1.0))
    return np.array(out)


def test_collision_pairs_are_exactly_the_pairs_mujoco_lets_collide(robot):
    """Where MuJoCo's collision reports a contact, some candidate pair overlaps, and vice versa."""
    pairs, data = collision_pairs(robot), mujoco.MjData(robot.model)
    rng = np.random.default_rng(0)
    lower = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    for _ in range(100):
        q = rng.uniform(lower, upper)
        contact = bool(self_contacts(robot, q, data))
        mujoco.mj_kinematics(robot.model, data)
        mujoco.mj_comPos(robot.model, data)
        d, grad = pair_distances(robot, data, pairs, 0.05)
        assert contact == bool(np.any(d < 0))
        assert np.all(np.isfinite(grad))


def test_distance_bounds_skip_only_pairs_that_are_far(robot):
    """With the carried bounds the distances and gradients are the same, bit for bit, along a path
    of small steps (the solvers' case) with jumps (a line search's)."""
    pairs, data = collision_pairs(robot), mujoco.MjData(robot.model)
    bounds = DistanceBounds(pairs)
    rng = np.random.default_rng(1)
    lower = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    q, rows = rng.uniform(lower, upper), 0
    for k in range(400):
        q = np.clip(q + rng.normal(scale=0.3 if k % 50 == 0 else 0.005, size=q.shape), lower, upper)
        data.qpos[:] = q
        mujoco.mj_kinematics(robot.model, data)
        mujoco.mj_comPos(robot.model, data)
        d, grad = pair_distances(robot, data, pairs, 0.1)
        d_bounded, grad_bounded = pair_distances(robot, data, pairs, 0.1, bounds)
        np.testing.assert_array_equal(d_bounded, d)
        np.testing.assert_array_equal(grad_bounded, grad)
        rows += len(d)
    assert rows > 100  # the path comes close often enough to test something


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("name", ROBOTS)
def test_a_target_inside_the_torso_is_refused(name, solver):
    r = load_robot(name)
    motion = demo_motion().crop(1.0, 1.3).resample(100.0)
    problem = build_problem(motion, r, shoulder_placement(r, forward_kinematics(motion)))  # human-near torso
    inside = problem.targets.pos.copy()
    # the right hand's target moves into the chest (base frame): 25 cm below the shoulders' midpoint
    chest = robot_state(r, r.home).shoulder[0].mean(axis=0) + np.array([0.0, 0.0, -0.25])
    inside[5:, 1] = chest
    targets = replace(problem.targets, pos=inside)
    solve, settings = SOLVERS[solver]
    q_free, _ = solve_problem(solve, r, motion, targets, problem.placement, settings(self_collision=False))
    q, result = solve_problem(solve, r, motion, targets, problem.placement, settings())
    assert np.all(np.isfinite(q)) and result.diagnostics.n_failed == 0
    assert np.min(_min_distance(r, q_free)) < 0.0  # without the limit, the arm goes in
    assert np.min(_min_distance(r, q)) >= -1e-3  # with it, every pair stays apart
    assert not any(self_contacts(r, qk) for qk in q)


def test_jv_avoiding_step_is_the_weighted_least_norm_step_unless_a_row_binds():
    """JV's constrained task step: the weighted least-norm solution where no row binds; else the
    rows and the bounds hold, and it tracks no worse than any other step that keeps them."""
    rng = np.random.default_rng(3)
    jac, xdot = rng.normal(size=(6, 9)), rng.normal(size=6)
    weights, damping = 1.0 + rng.uniform(0.0, 3.0, 9), 0.1
    lower, upper = np.full(9, -10.0), np.full(9, 10.0)
    free = jv.weighted_least_norm(jac, xdot, weights, damping)
    loose = jv.avoiding_least_norm(jac, xdot, weights, damping, -free[None], np.array([1.0]), lower, upper)
    np.testing.assert_allclose(loose, free, atol=1e-9)
    rows, rhs = rng.normal(size=(3, 9)), np.array([0.0, -0.01, 0.02])
    rows[0] = free / np.linalg.norm(free)  # the free step breaks this one
    x = jv.avoiding_least_norm(jac, xdot, weights, damping, rows, rhs, lower, upper)
    assert np.all(rows @ x <= rhs + 1e-9) and rows[0] @ free > rhs[0]

    def cost(v):
        return np.sum((jac @ v - xdot) ** 2) + damping**2 * v @ (weights * v)

    for _ in range(200):  # feasible neighbours cost no less
        other = x + 0.05 * rng.normal(size=9)
        if np.all(rows @ other <= rhs):
            assert cost(other) >= cost(x) - 1e-12


@pytest.mark.parametrize("scenario", ["pose", "relative"])
def test_jv_keeps_the_arms_out_of_the_body_on_a_kit_take(takes, scenario):
    """ARMAR-III on the Close take puts its forearm into its hip without the cut (JV's table row
    before it); with it, no frame touches, and the relative pose is still tracked."""
    from hlik import load_motion, retarget
    from hlik.criteria.functional import position_error, relative_errors
    from hlik.metrics import collision_frames

    r = load_robot("armar3")
    motion = load_motion(takes[0], rate=100.0).crop(1.0, 1.6)
    placement = shoulder_placement(r, forward_kinematics(motion))
    settings = jv.JVSettings(scenario=scenario)
    # the margin from the stops and the acceleration limits alone keep this forearm out of the hip
    unlimited = replace(settings, self_collision=False, stop_margin=0.0, acceleration_limits=False)
    free = retarget(motion, r, jv.jv_solver(unlimited), placement)
    traj = retarget(motion, r, jv.jv_solver(settings), placement)
    # 46 % of frames (pose); relative 15-46 %, by the machine's rounding (the free arm drifts)
    assert np.mean(collision_frames(free, r)) > 0.1
    assert not np.any(collision_frames(traj, r)) and np.all(np.isfinite(traj.q))
    # within the acceleration limits the hands take a few tenths of a second to reach the pose
    assert np.mean(traj.diagnostics.converged) > 0.9
    if scenario == "pose":
        assert np.median(position_error(traj.tcp_pos, traj.targets.pos)) < 0.02
    else:
        off = relative_errors(traj.tcp_pos, traj.tcp_rot, traj.targets.pos, traj.targets.rot)[0]
        assert np.median(off) < 0.01
