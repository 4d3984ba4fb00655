"""The first frame's start (``hlik.solvers.frames``): where the solver's first frame, started from
the clipped mapped pose, leaves a hand off, the frame is solved again from the hands' own IK and
kept where it lands them half as far; else solved once more from the first start, so that nothing
the solver carries on differs. 2-Panda on the bundled demo at its whole take's ``mapped``
placement is the reported fault: from the mapped pose the left arm ended on its stops, 7.5 cm and
50 deg off for the whole take."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hlik
from hlik.criteria.functional import rotation_angle
from hlik.problem.placement import mapped_placement
from hlik.problem.problem import build_problem
from hlik.problem.targets import HandTargets
from hlik.robot.model import tcp_poses
from hlik.solvers import frames, jv, qp, slsqp
from hlik.solvers.frames import JointBox
from hlik.solvers.settings import STOP_MARGIN
from hlik.solvers.stack_file import load_stack
from hlik.util.paths import demo_motion_path

SOLVERS = {"qp": qp.solve, "jv": jv.solve, "slsqp": slsqp.solve}


@pytest.fixture(scope="module")
def demo():
    """2-Panda on the first 1.5 s of the demo, placed where ``mapped`` stands it for the whole take."""
    robot = hlik.load_robot("dual_panda")
    motion = hlik.load_motion(demo_motion_path(), rate=100.0)
    placement = mapped_placement(robot, motion)
    return build_problem(motion.crop(0.0, 1.5), robot, placement)


def _errors(problem, q):
    pos, rot = tcp_poses(problem.robot, q)
    dp = np.linalg.norm(pos - problem.targets.pos, axis=-1)
    return dp, np.degrees(rotation_angle(rot, problem.targets.rot))


def _on(problem, q: np.ndarray):
    """The problem with its first frame's targets where ``q`` (n,) puts the TCPs."""
    pos, rot = tcp_poses(problem.robot, q[None])
    targets = problem.targets
    return replace(
        problem,
        targets=HandTargets(np.concatenate([pos, targets.pos[1:]]), np.concatenate([rot, targets.rot[1:]])),
    )


def _box(robot, margin: float = STOP_MARGIN) -> JointBox:
    return JointBox(robot.lower + margin, robot.upper - margin)


def test_hand_miss_is_the_larger_hand_error_in_tolerances(demo):
    q = demo.robot.home
    on = _on(demo, q)
    assert frames.hand_miss(on, q) == pytest.approx(0.0, abs=1e-9)
    tol_p, tol_a = frames.FIRST_FRAME_TOLERANCE
    moved = on.targets.pos.copy()
    moved[0, 1, 2] += tol_p  # the right hand's target 2 cm up: 1, the larger of its two shares
    assert frames.hand_miss(replace(on, targets=replace(on.targets, pos=moved)), q) == pytest.approx(1.0)
    moved[0, 1, 2] -= tol_p / 2  # 1 cm off: a half, not the sum with the angle
    assert frames.hand_miss(replace(on, targets=replace(on.targets, pos=moved)), q) == pytest.approx(0.5)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_hands_ik_puts_both_hands_on_reachable_targets(demo, seed):
    """Targets where a configuration near home, inside the frame's box (the stops less their
    margin), puts the TCPs: from home, the hands' IK lands both within 1 mm and 0.5 deg, inside the
    box. (A goal on the box's face is reached too, but slowly: each step's clip into the box
    crawls along it, 1.3 mm off after 300 steps where 1000 reach 0.2 mm.)"""
    robot = demo.robot
    rng = np.random.default_rng(seed)
    box = _box(robot)
    goal = _box(robot, STOP_MARGIN + 0.05).clip(robot.home + rng.uniform(-0.4, 0.4, robot.dof))
    problem = _on(demo, goal)
    q = frames.hands_ik(problem, robot.home, box)
    assert np.all(q >= box.lower - 1e-9) and np.all(q <= box.upper + 1e-9)
    dp, da = _errors(problem, q[None])
    assert dp[0].max() < 1e-3 and da[0].max() < 0.5, (dp[0], da[0])


def test_hands_ik_keeps_a_narrow_joint_inside_its_box(demo):
    """A joint whose box is narrower than the stop margin twice (a user's robot, or a box the
    speed limits narrowed): the IK stays inside it, joint by joint, and does not fail."""
    robot = demo.robot
    box = _box(robot)
    lower, upper = box.lower.copy(), box.upper.copy()
    lower[3], upper[3] = robot.home[3] - 0.005, robot.home[3] + 0.005
    narrow = JointBox(lower, upper)
    q = frames.hands_ik(demo, robot.home, narrow)
    assert np.all(q >= lower - 1e-9) and np.all(q <= upper + 1e-9)


@pytest.mark.parametrize("solver", ["qp", "jv", "slsqp"])
def test_a_second_start_not_taken_leaves_the_motion_as_it_was(cut_take, solver, monkeypatch):
    """ARMAR-III's first frame on the Cut take is 10-20 deg off, its forearm's range: solved again,
    and the second start not kept, the motion is the one solved without the second start, to the
    bit (JV's null-space memory included), with the iterations of every solve counted."""
    robot = hlik.load_robot("armar3")
    problem = build_problem(hlik.load_motion(cut_take, rate=100.0).crop(0.0, 0.3), robot)
    solve, settings = SOLVERS[solver], load_stack("ee_pose").with_criteria([]).settings(solver, "armar3")
    assert frames.hand_miss(problem, solve(problem, settings).q[0]) > 1.0
    again = solve(problem, settings)
    monkeypatch.setattr(frames, "FIRST_FRAME_TOLERANCE", (1e3, 1e3))  # never solved again
    once = solve(problem, settings)
    np.testing.assert_array_equal(again.q, once.q)
    assert again.diagnostics.iterations[0] > once.diagnostics.iterations[0]
    np.testing.assert_array_equal(again.diagnostics.iterations[1:], once.diagnostics.iterations[1:])


@pytest.mark.parametrize("solver", list(SOLVERS))
def test_a_first_frame_off_its_targets_starts_again_from_the_hands_ik(demo, solver, monkeypatch):
    """Without the second start (a switch share of 0 never switches) the left hand stays off for
    the whole stretch; with it, both hands are on target from the first frame on, every solver
    (each with its ee_pose settings for 2-Panda)."""
    solve, settings = SOLVERS[solver], load_stack("ee_pose").with_criteria([]).settings(solver, "dual_panda")
    monkeypatch.setattr(frames, "FIRST_FRAME_SWITCH", 0.0)
    dp, da = _errors(demo, solve(demo, settings).q)
    assert np.median(dp[:, 0]) > 0.02 or np.median(da[:, 0]) > 20.0, (np.median(dp, 0), np.median(da, 0))
    monkeypatch.undo()
    dp, da = _errors(demo, solve(demo, settings).q)
    assert np.all(np.median(dp, axis=0) < 0.01) and np.all(np.median(da, axis=0) < 5.0), (
        np.median(dp, 0),
        np.median(da, 0),
    )
