"""Joint speed limits: no optimising solver moves a joint faster than its limit between frames."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import ROBOTS, solve_problem
from hlik import load_robot
from hlik.human.demo import demo_motion
from hlik.problem.problem import build_problem
from hlik.robot.state import robot_state
from hlik.solvers import jv, qp, slsqp
from hlik.solvers.frames import joint_box

SOLVES = {"qp": qp.solve, "jv": jv.solve, "slsqp": slsqp.solve}


@pytest.mark.parametrize("solver", SOLVES)
@pytest.mark.parametrize("name", ROBOTS)
def test_a_target_jump_of_one_metre_gives_steps_within_the_speed_limits(name, solver):
    r = load_robot(name)
    motion = demo_motion().crop(1.0, 1.25).resample(100.0)
    problem = build_problem(motion, r)
    jump = problem.targets.pos.copy()
    jump[10:] += np.array([0.0, 0.3, 0.95])  # 1 m up and forward from frame 10 on
    targets = replace(problem.targets, pos=jump)
    q, result = solve_problem(SOLVES[solver], r, motion, targets, problem.placement)
    assert np.all(np.isfinite(q))
    speed = np.abs(np.diff(q, axis=0)) / problem.dt / r.velocity_limit
    assert speed.max() <= 1.0 + 1e-9, (name, solver, speed.max())
    # it lags, and the lag shows: the hands are still far from the jumped targets right after it
    fpos = np.linalg.norm(robot_state(r, q).tcp - jump, axis=-1).mean(axis=-1)
    assert fpos[11] > 0.1
    assert np.all(q >= r.lower - 1e-9) and np.all(q <= r.upper + 1e-9)


def test_the_joint_box_is_the_limits_intersected_with_the_speed_reach():
    r = load_robot("armar3")
    q = np.clip(r.home, r.lower, r.upper)
    free = joint_box(r, None, 0.01)
    np.testing.assert_array_equal(free.lower, r.lower)
    box = joint_box(r, q, 0.01)
    np.testing.assert_allclose(
        box.upper - box.lower, np.minimum(r.upper, q + 0.01) - np.maximum(r.lower, q - 0.01)
    )
    assert np.all(box.lower <= q) and np.all(q <= box.upper)
