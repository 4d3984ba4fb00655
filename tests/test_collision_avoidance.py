"""Self-collision avoidance in the QP and SLSQP: a target inside the torso is refused, pairs stay apart."""

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
from hlik.robot.collision import collision_pairs, pair_distances
from hlik.robot.model import self_contacts
from hlik.robot.state import robot_state
from hlik.solvers import qp


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


@pytest.mark.parametrize("solver", ["qp", "slsqp"])
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
    q_free, _ = solve_problem(
        qp.solve, r, motion, targets, problem.placement, qp.QPSettings(self_collision=False)
    )
    q, result = solve_problem(qp.solve, r, motion, targets, problem.placement, qp.QPSettings())
    assert np.all(np.isfinite(q)) and result.diagnostics.n_failed == 0
    assert np.min(_min_distance(r, q_free)) < 0.0  # without the limit, the arm goes in
    assert np.min(_min_distance(r, q)) >= -1e-3  # with it, every pair stays apart
    assert not any(self_contacts(r, qk) for qk in q)
