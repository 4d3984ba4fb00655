"""The arms' reach spheres, and targets beyond them tracked at the reach (hlik.robot.reach)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import ROBOTS
from hlik import load_robot
from hlik.human.demo import demo_motion
from hlik.problem.problem import build_problem
from hlik.problem.targets import HandTargets, within_reach
from hlik.robot.model import SIDES, tcp_poses
from hlik.robot.reach import ArmReach, arm_reach
from hlik.solvers import jv, qp, slsqp
from hlik.util.spatial import rotation_angle


@pytest.mark.parametrize("name", ROBOTS)
def test_the_reach_sphere_holds_every_pose_of_the_tcp_and_no_more(name):
    """No configuration in the ranges puts a TCP outside its sphere (3000 random ones, the trunk's
    joints moving too), and one does put it on the sphere."""
    robot = load_robot(name)
    reach = arm_reach(robot)
    rng = np.random.default_rng(1)
    q = np.tile(robot.home, (3000, 1))
    for side in SIDES:
        joints = robot.index((*robot.arm_joints[side], *robot.extra_joints))
        lo, hi = np.maximum(robot.lower[joints], -np.pi), np.minimum(robot.upper[joints], np.pi)
        q[:, joints] = rng.uniform(lo, hi, (len(q), len(joints)))
    pos, _ = tcp_poses(robot, q)
    distance = np.linalg.norm(pos - reach.centre, axis=-1)
    assert np.all(distance <= reach.radius + 1e-9)
    # attained: its configuration, inside the ranges, puts the TCP on the sphere
    assert np.all((reach.farthest >= robot.lower) & (reach.farthest <= robot.upper))
    far, _ = tcp_poses(robot, reach.farthest)
    assert np.allclose(np.linalg.norm(far[[0, 1], [0, 1]] - reach.centre, axis=-1), reach.radius, atol=1e-12)
    assert np.array_equal(reach.radius, arm_reach.__wrapped__(robot).radius)  # deterministic, not cached


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-3.0, 3.0), min_size=12, max_size=12),
    st.floats(0.3, 1.5),
)
def test_targets_beyond_reach_move_onto_the_sphere_and_no_others(coordinates, radius):
    reach = ArmReach(
        np.array([[-0.2, 0.0, 1.4], [0.2, 0.0, 1.4]]), np.array([radius, 0.9 * radius]), np.zeros((2, 1))
    )
    pos = np.reshape(coordinates, (2, 2, 3))
    rot = np.tile(np.eye(3), (2, 2, 1, 1))
    moved = within_reach(HandTargets(pos, rot), reach)
    distance = np.linalg.norm(pos - reach.centre, axis=-1)
    inside = distance <= reach.radius
    assert np.array_equal(moved.pos[inside], pos[inside])
    out = ~inside
    assert np.allclose(
        np.linalg.norm(moved.pos[out] - reach.centre[np.nonzero(out)[1]], axis=-1),
        reach.radius[np.nonzero(out)[1]],
    )
    # along the line from the centre: the same direction
    before = (pos - reach.centre)[out]
    after = (moved.pos - reach.centre)[out]
    assert np.allclose(np.cross(before, after), 0.0, atol=1e-9) and np.all(
        np.sum(before * after, axis=-1) > 0
    )
    assert np.array_equal(moved.rot, rot)
    assert np.allclose(within_reach(moved, reach).pos, moved.pos)  # idempotent
    assert np.all(reach.beyond(moved.pos) < 1e-9) and np.allclose(
        reach.beyond(pos)[out], (distance - reach.radius)[out]
    )


@pytest.mark.parametrize(
    ("name", "solver"),
    [("dual_panda", qp), ("dual_panda", slsqp), ("dual_panda", jv), ("armar6", qp), ("armar3", qp)],
)
def test_a_target_out_of_reach_no_longer_turns_the_hand_for_its_position(name, solver):
    """The left hand's target carried 0.3 m beyond its arm's reach for a second: tracking the point
    of the sphere, the solver keeps the hand turned nearer its target than it does pulled toward
    the point out of reach (median over that second; 4-13 degrees nearer, measured), and the
    trajectory's targets are the ones given."""
    robot = load_robot(name)
    motion = demo_motion().crop(2.0, 3.5).resample(100.0)
    problem = build_problem(motion, robot)
    reach = arm_reach(robot)
    pos = problem.targets.pos.copy()
    far = slice(20, 120)
    away = pos[far, 0] - reach.centre[0]
    pos[far, 0] = reach.centre[0] + away / np.linalg.norm(away, axis=-1, keepdims=True) * (
        reach.radius[0] + 0.3
    )
    beyond = replace(problem, targets=replace(problem.targets, pos=pos))
    assert np.all(beyond.tracked.pos[far, 0] != pos[far, 0]) and np.array_equal(
        beyond.tracked.pos[:20], pos[:20]
    )
    pulled = replace(beyond)
    pulled.__dict__["tracked"] = pulled.targets  # the point out of reach itself, as before
    turned = []
    for p in (beyond, pulled):
        _, rot = tcp_poses(robot, solver.solve(p).q)
        turned.append(np.median(np.degrees(rotation_angle(rot[far, 0], p.targets.rot[far, 0]))))
    assert turned[0] < turned[1] - 2.0, turned


def test_the_summary_says_how_often_and_how_far_a_target_lay_beyond_the_reach():
    """Whether a hand lagged or not: the lagging row counts the frames with a target beyond its
    arm's reach and the largest distance past it."""
    from rich.console import Console

    from hlik.cli.summary import run_summary
    from hlik.pipeline import RunSpec, run

    result = run(RunSpec(robot="dual_panda", solver="qp", span=(2.0, 2.5), whole_take=False))
    traj, ev = result.trajectory, result.evaluation
    beyond = np.zeros((traj.n_frames, 2))
    beyond[10:17, 0] = np.linspace(0.01, 0.034, 7)

    def lagging(b):
        console = Console(width=400, record=True)
        console.print(run_summary(traj, result.motion, 1.0, ev, "", b))
        return next(line for line in console.export_text().splitlines() if "lagging" in line)

    assert "a target beyond its arm's reach in 7 frames, up to 3.4 cm (tracked at the reach)" in lagging(
        beyond
    )
    assert "beyond its arm's reach" not in lagging(np.zeros_like(beyond))
