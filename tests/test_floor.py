"""Robots stand on their floor (world z = 0, the human's): every placement rule chooses x, y and yaw
only, and the base is at the robot's own height (README "Placement")."""

from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import G1, require_g1
from hlik.human.kinematics import forward_kinematics
from hlik.human.load import load_motion
from hlik.problem.placement import (
    mapped_placement,
    placement_from_spec,
    placement_notes,
    reach_placement,
    shoulder_placement,
    yaw_rotation,
)
from hlik.problem.scale import scale_subject
from hlik.robot.files import available_robots
from hlik.robot.floor import floor_height, lowest_points
from hlik.robot.model import joint_mapping, load_robot
from hlik.robot.reachability import reachability_map
from hlik.robot.state import robot_state

ROBOTS = (*available_robots(), str(G1))
TOLERANCE = 1e-3  # m
RULES = ("reach", "mapped", "shoulders", "X,Y,YAW")
FEW = settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@functools.cache
def _robot(name: str):
    if name == str(G1):
        require_g1()
    return load_robot(name)


@functools.cache
def _take(path, name: str):
    """Two seconds of the take at 10 Hz, the subject scaled as the robot wants, and its JM angles."""
    robot = _robot(name)
    motion = scale_subject(load_motion(path).crop(2.0, 4.0).resample(10.0), robot)
    return motion, joint_mapping(robot, motion)


@pytest.mark.parametrize("name", ROBOTS)
def test_every_model_stands_on_the_floor_of_its_base_frame(name):
    """The convention of robots/README.md, measured: the lowest point of all geometry (visual and
    collision) at home is z = 0 of the base frame, to 1 mm; so the base stands at its origin."""
    robot = _robot(name)
    low = float(lowest_points(robot, robot.home[None])[0])
    assert abs(low) < TOLERANCE, f"{robot.name}: lowest point at home {low * 1e3:.2f} mm"
    assert floor_height(robot) == pytest.approx(-low, abs=1e-4)


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("name", ROBOTS)
@FEW
@given(
    dx=st.floats(-2.0, 2.0),
    dy=st.floats(-2.0, 2.0),
    dz=st.floats(-0.3, 0.3),
    turn=st.floats(-np.pi, np.pi),
    given_pose=st.tuples(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), st.floats(-180.0, 180.0)),
)
def test_placement_stands_the_robot_on_the_floor_wherever_the_motion_is(
    name, rule, cut_take, dx, dy, dz, turn, given_pose
):
    """A real take moved and turned anywhere (and up or down by 0.3 m): the lowest point of the robot
    over all frames of its JM motion, placed by ``rule``, is on the floor (world z = 0) to 1 mm."""
    robot = _robot(name)
    motion, q = _take(cut_take, name)
    r, shift = yaw_rotation(turn), np.array([dx, dy, dz])
    moved = replace(
        motion, root_position=motion.root_position @ r.T + shift, root_rotation=r @ motion.root_rotation
    )
    human = forward_kinematics(moved)
    if rule == "reach":
        placement = reach_placement(robot, human, _reach_map(name))
    elif rule == "mapped":
        placement = mapped_placement(robot, moved, human)
    elif rule == "shoulders":
        placement = shoulder_placement(robot, human)
    else:
        placement = placement_from_spec(",".join(f"{v:.6f}" for v in given_pose), robot, moved, human)
    np.testing.assert_allclose(placement.rotation[:, 2], [0, 0, 1], atol=1e-12)  # upright
    low = float(lowest_points(robot, q, placement.rotation, placement.translation[2]).min())
    assert abs(low) < TOLERANCE, f"{robot.name} ({rule}): lowest point {low * 1e3:.1f} mm"
    assert not placement_notes(robot, placement)


@functools.cache
def _reach_map(name: str):
    return reachability_map(_robot(name))


def test_a_given_height_is_honoured_and_noted(cut_take):
    """X,Y,YAW,Z puts the base at Z, and the note says the robot does not stand on its floor."""
    robot = _robot("dual_panda")
    motion, _ = _take(cut_take, "dual_panda")
    placement = placement_from_spec("0.5,-1,90,0.25", robot, motion)
    np.testing.assert_allclose(placement.translation, [0.5, -1.0, 0.25])
    assert placement.yaw == pytest.approx(np.pi / 2)
    (note,) = placement_notes(robot, placement)
    assert "does not stand on its floor" in note and "0.250 m above" in note
    on_floor = placement_from_spec(f"0.5,-1,90,{floor_height(robot)}", robot, motion)
    assert not placement_notes(robot, on_floor)


def test_shoulders_stay_at_the_robots_own_height(cut_take):
    """2-Panda's shoulders are 9 cm above the subject's: the shoulder placement keeps them there (it
    used to sink the pedestal into the floor), matching the subject's shoulders seen from above."""
    robot = _robot("dual_panda")
    motion, _ = _take(cut_take, "dual_panda")
    human = forward_kinematics(motion)
    placement = shoulder_placement(robot, human)
    shoulders = placement.to_world(robot_state(robot, robot.home).shoulder[0])
    np.testing.assert_allclose(shoulders.mean(0)[:2], human.shoulder[0].mean(0)[:2], atol=1e-9)
    assert shoulders.mean(0)[2] - human.shoulder[0].mean(0)[2] > 0.05
    assert placement.translation[2] == floor_height(robot) == 0.0
