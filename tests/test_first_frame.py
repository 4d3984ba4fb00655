"""The first frame's start (``hlik.solvers.frames``): where the solver's first frame, started from
the clipped mapped pose, leaves a hand off, the frame is solved again from the hands' own IK and
kept where it lands them nearer. 2-Panda on the bundled demo at its whole take's ``mapped``
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


def test_hand_miss_is_the_larger_hand_error_in_tolerances(demo):
    q = demo.robot.home
    on = _on(demo, q)
    assert frames.hand_miss(on, q) == pytest.approx(0.0, abs=1e-9)
    moved = on.targets.pos.copy()
    moved[0, 1, 2] += frames.FIRST_FRAME_TOLERANCE[0]  # the right hand's target 2 cm up
    assert frames.hand_miss(replace(on, targets=replace(on.targets, pos=moved)), q) == pytest.approx(1.0)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_hands_ik_puts_both_hands_on_reachable_targets(demo, seed):
    """Targets where a configuration near home puts the TCPs: from home, the hands' IK lands both
    within 1 mm and 0.5 deg (the limits' margin kept)."""
    robot = demo.robot
    rng = np.random.default_rng(seed)
    margin = STOP_MARGIN
    goal = np.clip(robot.home + rng.uniform(-0.4, 0.4, robot.dof), robot.lower + margin, robot.upper - margin)
    problem = _on(demo, goal)
    q = frames.hands_ik(problem, robot.home, margin)
    assert np.all(q >= robot.lower + margin - 1e-6) and np.all(q <= robot.upper - margin + 1e-6)
    dp, da = _errors(problem, q[None])
    assert dp[0].max() < 1e-3 and da[0].max() < 0.5, (dp[0], da[0])


@pytest.mark.parametrize("solver", list(SOLVERS))
def test_a_first_frame_off_its_targets_starts_again_from_the_hands_ik(demo, solver, monkeypatch):
    """Without the second start (a switch share of 0 never switches) the left hand stays off for
    the whole stretch; with it, both hands are on target from the first frame on, every solver
    (each with its ee_pose settings for 2-Panda)."""
    solve, settings = SOLVERS[solver], load_stack("ee_pose").settings(solver, "dual_panda")
    monkeypatch.setattr(frames, "FIRST_FRAME_SWITCH", 0.0)
    dp, da = _errors(demo, solve(demo, settings).q)
    assert np.median(dp[:, 0]) > 0.02 or np.median(da[:, 0]) > 20.0, (np.median(dp, 0), np.median(da, 0))
    monkeypatch.undo()
    dp, da = _errors(demo, solve(demo, settings).q)
    assert np.all(np.median(dp, axis=0) < 0.01) and np.all(np.median(da, axis=0) < 5.0), (
        np.median(dp, 0),
        np.median(da, 0),
    )
