"""Placement by reachability inversion (paper Sec. IV-A): where the hand poses are reachable, and
covariant with the motion."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import ROBOTS, kit_takes, solve_problem
from hlik.criteria.learned import learn
from hlik.human.demo import demo_motion
from hlik.human.kinematics import HumanKinematics, forward_kinematics
from hlik.human.load import load_motion
from hlik.placement_search import optimize_placement
from hlik.problem.placement import (
    Placement,
    mapped_placement,
    placement_from_spec,
    reach_placement,
    shoulder_placement,
    working_distances,
    working_placement,
    yaw_rotation,
)
from hlik.problem.problem import build_problem
from hlik.problem.scale import scale_subject
from hlik.problem.targets import HandTargets
from hlik.robot.floor import floor_height
from hlik.robot.model import SIDES, joint_mapping, load_robot
from hlik.robot.reachability import reachability_map
from hlik.robot.state import robot_state
from hlik.solvers import qp
from hlik.util.errors import SettingsError
from hlik.util.spatial import site_poses


def test_reach_placement_moves_and_turns_with_the_motion(takes):
    robot = load_robot("armar6")
    motion = load_motion(takes[1])
    turn, shift = yaw_rotation(2.3), np.array([1.7, -3.1, 0.0])
    moved = replace(
        motion,
        root_position=motion.root_position @ turn.T + shift,
        root_rotation=turn @ motion.root_rotation,
    )
    here = reach_placement(robot, forward_kinematics(motion))
    there = reach_placement(robot, forward_kinematics(moved))
    assert here.method == there.method == "reach"
    np.testing.assert_allclose(there.rotation, turn @ here.rotation, atol=1e-9)
    np.testing.assert_allclose(there.translation, turn @ here.translation + shift, atol=1e-9)


@pytest.mark.parametrize("name", ROBOTS)
def test_reach_placement_finds_a_base_where_every_hand_pose_is_reachable(name):
    """Hand poses the robot itself makes from a base pose far from the human's shoulders: the search
    finds a base from which the QP reaches all of them, and the map has an entry for each."""
    robot = load_robot(name)
    motion = demo_motion().crop(1.0, 3.0).resample(10.0)
    state = robot_state(robot, joint_mapping(robot, motion))
    truth = Placement(yaw_rotation(-0.8), np.array([0.9, 0.6, 0.0]))
    world = [truth.to_world(p) for p in (state.shoulder, state.elbow, state.wrist, state.tcp)]
    hands = HumanKinematics(*world, truth.rotation @ state.tcp_rot)
    found = reach_placement(robot, hands)
    targets = HandTargets(*found.to_base(hands.tcp_pos, hands.tcp_rot))
    reach = reachability_map(robot)
    for side in range(2):
        assert np.all(reach.lookup(side, targets.pos[:, side], targets.rot[:, side]) > 0)
    q, _ = solve_problem(qp.solve, robot, motion, targets, found, qp.QPSettings(max_iter=50))
    tcp = robot_state(robot, q).tcp
    assert np.median(np.linalg.norm(tcp - targets.pos, axis=-1)) < 0.01


@pytest.mark.parametrize("name", ROBOTS)
def test_mapped_placement_recovers_the_base_that_put_the_mapped_hands_there(name):
    robot = load_robot(name)
    motion = demo_motion().crop(1.0, 3.0).resample(20.0)
    state = robot_state(robot, joint_mapping(robot, motion))
    truth = Placement(yaw_rotation(2.5), np.array([-0.4, 1.3, 0.0]))
    world = [truth.to_world(p) for p in (state.shoulder, state.elbow, state.wrist, state.tcp)]
    found = mapped_placement(robot, motion, HumanKinematics(*world, truth.rotation @ state.tcp_rot))
    np.testing.assert_allclose(found.rotation, truth.rotation, atol=1e-9)
    np.testing.assert_allclose(found.translation[:2], truth.translation[:2], atol=1e-9)


def test_mapped_placement_ignores_a_stretch_of_targets_carried_away():
    """A fifth of the frames' hand targets carried 2 m forward (field case unreachable_forward_2m)
    leave the fit on the rest."""
    robot = load_robot("armar6")
    motion = demo_motion().crop(1.0, 3.0).resample(20.0)
    state = robot_state(robot, joint_mapping(robot, motion))
    truth = Placement(yaw_rotation(0.7), np.array([0.2, -0.5, 0.0]))
    world = [truth.to_world(p) for p in (state.shoulder, state.elbow, state.wrist, state.tcp)]
    away = slice(10, 18)
    world[3][away] += np.array([0.0, 2.0, 0.0])
    found = mapped_placement(robot, motion, HumanKinematics(*world, truth.rotation @ state.tcp_rot))
    np.testing.assert_allclose(found.translation[:2], truth.translation[:2], atol=1e-6)
    assert found.yaw == pytest.approx(truth.yaw, abs=1e-6)


@pytest.mark.parametrize("name", ["armar6", "dual_panda"])  # mapped is their default
@pytest.mark.parametrize(("away", "start"), [(0.6, 1.0), (0.3, 0.5), (0.45, 2.5)])
def test_mapped_placement_stands_where_a_take_carried_away_starts(name, away, start):
    """The whole subject carried 2 m away for a share ``away`` of a recorded take (ramps of 0.5 s
    in and out included; the field case unreachable_forward_2m: 60 %, which stood ARMAR-6 1.5 m
    off, between the two places): the robot stands where the frames left in place alone would
    stand it."""
    robot = load_robot(name)
    motion = load_motion(kit_takes()[5]).crop(0.0, 5.0).resample(50.0)  # the Stir take, as the field cases
    t = motion.times - motion.times[0]
    stop = start + away * 5.0
    ramp = np.clip((t - start) / 0.5, 0, 1) - np.clip((t - stop + 0.5) / 0.5, 0, 1)
    carried = replace(motion, root_position=motion.root_position + ramp[:, None] * [2.0, 0.0, 0.0])
    scaled = scale_subject(motion, robot)  # about the first frame, in place in both
    clean = mapped_placement(robot, scaled.frames(ramp == 0))
    found = mapped_placement(robot, scale_subject(carried, robot))
    np.testing.assert_allclose(found.translation[:2], clean.translation[:2], atol=0.03)
    assert np.degrees(found.yaw) == pytest.approx(np.degrees(clean.yaw), abs=2.0)


@pytest.mark.parametrize(("away", "start"), [(0.6, 1.0), (0.3, 0.5), (0.45, 2.5)])
def test_reach_placement_stands_where_a_take_carried_away_is(away, start):
    """As the mapped rule above, for reach (ARMAR-III's default): the subject carried 2 m away for a
    share of the Stir take. Scored on every frame, the robot stood 0.5 m forward of where the frames
    left in place stand it, between the two places, turned 10-20 deg; now it stands for the frames
    whose shoulders agree with the take's start (those of the ramps within the agreement's 0.4 m
    included, which reach stands for too: 12-13 cm and up to one yaw step away)."""
    robot = load_robot("armar3")
    motion = load_motion(kit_takes()[5]).crop(0.0, 5.0).resample(50.0)
    t = motion.times - motion.times[0]
    stop = start + away * 5.0
    ramp = np.clip((t - start) / 0.5, 0, 1) - np.clip((t - stop + 0.5) / 0.5, 0, 1)
    carried = replace(motion, root_position=motion.root_position + ramp[:, None] * [2.0, 0.0, 0.0])
    clean = reach_placement(robot, forward_kinematics(scale_subject(motion, robot).frames(ramp == 0)))
    found = reach_placement(robot, forward_kinematics(scale_subject(carried, robot)))
    assert np.linalg.norm(found.translation[:2] - clean.translation[:2]) < 0.2
    assert np.degrees(found.yaw) == pytest.approx(np.degrees(clean.yaw), abs=10.5)


@pytest.mark.parametrize("name", ROBOTS)
def test_shoulder_placement_matches_shoulder_midpoints_and_heading(name, takes):
    r = load_robot(name)
    human = forward_kinematics(load_motion(takes[1]))
    placement = shoulder_placement(r, human)
    ids = np.array([r.site_id(s, "shoulder") for s in SIDES])
    shoulders, _ = site_poses(r.model, r.home[None], ids)
    world = placement.to_world(shoulders[0])
    np.testing.assert_allclose(world.mean(0)[:2], human.shoulder[0].mean(0)[:2], atol=1e-9)
    assert placement.translation[2] == floor_height(r)  # on the floor, not at the human's shoulders
    lateral = lambda p: (p[1] - p[0])[:2] / np.linalg.norm((p[1] - p[0])[:2])  # noqa: E731
    np.testing.assert_allclose(lateral(world), lateral(human.shoulder[0]), atol=1e-9)
    np.testing.assert_allclose(placement.rotation[:, 2], [0, 0, 1], atol=1e-12)  # stays upright


def test_placement_spec():
    robot = load_robot("dual_panda")
    motion = demo_motion().crop(0.0, 1.0)
    human = forward_kinematics(motion)
    given = placement_from_spec("0.5,-1,90", robot, motion)
    np.testing.assert_allclose(given.translation[:2], [0.5, -1.0])
    assert given.yaw == pytest.approx(np.pi / 2)
    assert given.translation[2] == floor_height(robot) == shoulder_placement(robot, human).translation[2]
    assert placement_from_spec("shoulders", robot, motion).method == "shoulders"
    with pytest.raises(SettingsError, match="X,Y,YAW"):
        placement_from_spec("0.5,1", robot, motion)


def test_optimize_keeps_the_candidate_with_the_best_unified_metric():
    robot = load_robot("armar3")
    motion = demo_motion().crop(1.0, 2.0)
    learned = learn(robot)
    solver = qp.qp_solver(qp.QPSettings(max_iter=5))
    best, tried = optimize_placement(motion, robot, solver, learned, frames=10)
    human = forward_kinematics(motion)
    assert [c.name for c in tried] == ["reach", "reach+1/3", "reach+2/3", "mapped", "shoulders"]
    np.testing.assert_allclose(tried[0].placement.matrix, reach_placement(robot, human).matrix)
    np.testing.assert_allclose(tried[3].placement.matrix, mapped_placement(robot, motion, human).matrix)
    winner = max(tried, key=lambda c: c.m_hl_f)
    assert best.method == "optimize"
    np.testing.assert_allclose(best.matrix, winner.placement.matrix)
    assert all(np.isfinite(c.m_hl_f) for c in tried)


@pytest.mark.parametrize("name", ROBOTS)
def test_the_reachability_map_leaves_out_hands_behind_the_back(name):
    """Hand poses the robot reaches 20 cm or more behind its shoulders' frontal plane have no entry,
    ones in front do (the map is of the workspace a person works in)."""
    robot = load_robot(name)
    reach = reachability_map(robot)
    rng = np.random.default_rng(5)
    moving = np.concatenate([robot.index(robot.extra_joints + robot.arm_joints[s]) for s in SIDES])
    lower = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    q = np.tile(robot.home, (3000, 1))
    q[:, moving] = rng.uniform(lower[moving], upper[moving], (3000, len(moving)))
    state = robot_state(robot, q)
    shoulder_y = robot_state(robot, robot.home).shoulder[0, :, 1]
    for side in range(2):
        entries = reach.lookup(side, state.tcp[:, side], state.tcp_rot[:, side])
        behind = state.tcp[:, side, 1] < shoulder_y[side] - 0.2
        ahead = state.tcp[:, side, 1] > shoulder_y[side] + 0.2
        assert behind.sum() > 10 and np.all(entries[behind] == 0)
        assert np.mean(entries[ahead] > 0) > 0.9


@pytest.mark.parametrize("name", ROBOTS)
def test_a_problem_is_placed_by_the_robots_own_rule(name):
    robot = load_robot(name)
    problem = build_problem(demo_motion().crop(1.0, 1.5), robot)
    assert problem.placement.method == robot.placement == ("reach" if name == "armar3" else "mapped")


def _working_miss(robot, human, placement) -> float:
    """How far the robot's hands at its home shoulders, placed so, are from the subject's working
    distances (ahead and beside, per arm length)."""
    ids = robot.site_ids
    home, _ = site_poses(robot.model, robot.home[None], ids[:, :3])
    shoulder, elbow, wrist = (np.broadcast_to(home[:, :, i], (len(human.tcp_pos), 2, 3)) for i in range(3))
    tcp = placement.to_base(human.tcp_pos.reshape(-1, 3)).reshape(-1, 2, 3)
    robot_side = working_distances(shoulder, elbow, wrist, tcp)
    subject = working_distances(human.shoulder, human.elbow, human.wrist, human.tcp_pos)
    return float(np.sum(np.abs(robot_side - subject)))


@pytest.mark.parametrize("name", ROBOTS)
def test_working_placement_puts_the_hands_at_the_subjects_distance_inside_the_maps(name, takes):
    """Among the well-reachable base poses, ``working`` is at least as close to the subject's working
    distances as ``reach``, stands on the floor, and moves and turns with the motion."""
    robot = load_robot(name)
    motion = load_motion(takes[1]).crop(1.0, 4.0)
    human = forward_kinematics(motion)
    work, reach = working_placement(robot, human), reach_placement(robot, human)
    assert work.method == "working" and work.translation[2] == floor_height(robot)
    # 0.02: the rule looks at 100 of the frames, the check at all
    assert _working_miss(robot, human, work) <= _working_miss(robot, human, reach) + 0.02, (
        _working_miss(robot, human, work),
        _working_miss(robot, human, reach),
    )
    turn, shift = yaw_rotation(1.1), np.array([-0.8, 2.0, 0.0])
    moved = replace(
        motion, root_position=motion.root_position @ turn.T + shift, root_rotation=turn @ motion.root_rotation
    )
    there = working_placement(robot, forward_kinematics(moved))
    np.testing.assert_allclose(there.translation, turn @ work.translation + shift, atol=1e-9)
