"""JM: the naive joint mapping baseline (paper Sec. III-A), blind to the hand targets."""

from __future__ import annotations

import numpy as np

from hlik.errors import MotionFormatError
from hlik.motion import HumanMotion
from hlik.placement import Placement
from hlik.robot import Robot
from hlik.targets import HandTargets


def mapped_configuration(robot: Robot, motion: HumanMotion) -> np.ndarray:
    """(T, n) the MMM joint angles mapped through the robot's Table I mapping, not clipped.

    Joints the mapping does not cover (ARMAR-III's hip) stay at home.
    """
    missing = [j for j in robot.mapping.mmm_joints if j not in motion.joint_names]
    if missing:
        raise MotionFormatError(motion.source, f"motion lacks MMM joint(s) {', '.join(missing)}")
    q = np.tile(robot.home, (motion.n_frames, 1))
    for name, angles in robot.mapping.apply(motion.joint_names, motion.joints).items():
        q[:, robot.index(name)] = angles
    return q


def joint_mapping(
    robot: Robot, motion: HumanMotion, targets: HandTargets | None = None, placement: Placement | None = None
) -> np.ndarray:
    """JM: :func:`mapped_configuration` clipped into the joint limits, as a robot controller would.

    Returns:
        (T, n) joint angles in ``robot.joint_names`` order.
    """
    return np.clip(mapped_configuration(robot, motion), robot.lower, robot.upper)
