"""MIS over the joints the mapping moves: a held joint neither enters the first-order synergies
nor saturates the misalignment."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import ROBOTS
from hlik import load_robot
from hlik.criteria.base import Sample
from hlik.criteria.learned import learn
from hlik.criteria.synergy import MIS
from hlik.robot.state import robot_state

HELD = {"armar3": (), "armar6": ("ArmL1_Cla1", "ArmR1_Cla1"), "dual_panda": ("left_joint7", "right_joint7")}


@pytest.mark.parametrize("name", ROBOTS)
def test_mis_leaves_out_the_joints_the_mapping_holds(name):
    robot = load_robot(name)
    assert set(robot.mapping.held_joints) == set(HELD[name])
    syn = learn(robot).synergies
    spanned = {robot.joint_names[i] for i in syn.vel_idx}
    assert spanned.isdisjoint(HELD[name]) and len(spanned) == len(syn.idx) - len(HELD[name])
    assert syn.vel_basis.shape[1] == len(spanned) and syn.vel_scale.shape == (len(spanned),)

    mis = MIS(robot, learn(robot).synergies)
    q0 = np.clip(robot.home, robot.lower, robot.upper)
    eye = np.tile(np.eye(3), (2, 1, 1))

    def h(q: np.ndarray) -> float:
        sample = Sample.one(np.zeros((2, 3)), eye, q0, np.zeros(2), eye, np.tile(q0, (3, 1)), 0.01)
        return float(mis.cost(mis.residual(robot_state(robot, q), sample))[0])

    for joint in HELD[name]:  # a held joint moving alone is no misaligned motion (was h = 1)
        q = q0.copy()
        q[robot.index(joint)] += 0.01
        assert h(q) == 0.0
    # a synergy direction is aligned, and adding a held joint's motion leaves it aligned
    along = q0.copy()
    along[syn.vel_idx] += 0.01 * syn.vel_basis[0] * syn.vel_scale
    assert h(along) == pytest.approx(0.0, abs=1e-9)
    for joint in HELD[name]:
        along[robot.index(joint)] += 0.05
    assert h(along) == pytest.approx(0.0, abs=1e-9)
