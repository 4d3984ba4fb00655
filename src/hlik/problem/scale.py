"""How tall a subject the robot retargets from: the recorded one, or one scaled to the robot's arms.

The paper retargets hand poses as recorded, to robots about a person's size (``subject_scale = 1``,
the default). A robot much smaller or larger than the subject cannot reach the recorded hand poses
with any posture; ``auto`` scales the subject (:meth:`HumanMotion.scaled`: height, root and hand
positions; the joint angles stay) by the robot's arm length over the subject's, the usual
human-to-robot scaling of retargeting tools.
"""

from __future__ import annotations

import math
from dataclasses import replace

import mujoco
import numpy as np

from hlik.errors import SettingsError
from hlik.human.kinematics import human_model
from hlik.human.motion import HumanMotion
from hlik.robot.model import SIDES, Robot

ARM = ("shoulder", "elbow", "wrist", "tcp")
SCALE_RANGE = (0.1, 10.0)  # a factor outside it is a typo, not a robot
# m: a scaled subject whose shoulders stand farther than this above or below the robot's puts the
# hand targets out of the robot's reach (ARMAR-6's arms are 1.5x the KIT subject's at about its
# height: ``auto`` makes the subject 2.54 m tall, the hands 0.7 m above the robot's shoulders)
SHOULDER_GAP = 0.15


def arm_length(model: mujoco.MjModel, qpos: np.ndarray) -> float:
    """Mean over both arms of shoulder -> elbow -> wrist -> TCP, m, at configuration ``qpos``."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    lengths = []
    for side in SIDES:
        points = np.array([data.site_xpos[model.site(f"{side}_{site}").id] for site in ARM])
        lengths.append(float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum()))
    return float(np.mean(lengths))


def auto_scale(robot: Robot, motion: HumanMotion) -> float:
    """The robot's arm length (shoulder to TCP, at home) over the subject's (MMM model at its height)."""
    human = human_model(motion.height)
    return arm_length(robot.model, robot.home) / arm_length(human, human.qpos0)


def shoulder_gap(robot: Robot, motion: HumanMotion) -> float:
    """How far the subject's shoulders (midpoint, first frame) stand above the robot's at home, both
    on their floors, m."""
    from hlik.fk import site_poses
    from hlik.human.kinematics import forward_kinematics
    from hlik.robot.floor import floor_height

    ids = np.array([robot.site_id(side, "shoulder") for side in SIDES])
    robot_z = float(np.mean(site_poses(robot.model, robot.home[None], ids)[0][0, :, 2])) + floor_height(robot)
    human_z = float(np.mean(forward_kinematics(motion.frames(slice(0, 1))).shoulder[0, :, 2]))
    return human_z - robot_z


def scale_subject(motion: HumanMotion, robot: Robot, rule: float | str | None = None) -> HumanMotion:
    """``motion`` by a subject scaled by ``rule``: a factor, ``"auto"`` (:func:`auto_scale`), or None
    for the robot's own (``Robot.subject_scale``).

    Raises:
        SettingsError: a rule that is neither ``auto`` nor a positive number.
    """
    rule = robot.subject_scale if rule is None else rule
    if rule == "auto":
        factor = auto_scale(robot, motion)
        scaled = motion.scaled(factor, f" to {robot.title}'s arms (subject_scale auto)")
        gap = shoulder_gap(robot, scaled)
        if abs(gap) > SHOULDER_GAP:
            where = motion.source or motion.name
            side = "above" if gap > 0 else "below"
            note = (
                f"{where}: the subject scaled to {robot.title}'s arms has its shoulders {abs(gap):.2f} m "
                f"{side} the robot's, and the hand targets with them: {robot.title}'s arms are "
                f"{'long' if gap > 0 else 'short'} for its height (--scale or subject_scale: 1, or a factor)"
            )
            scaled = replace(scaled, notes=(*scaled.notes, note))
        return scaled
    try:
        factor = float(rule)
    except (TypeError, ValueError):
        factor = math.nan
    if not SCALE_RANGE[0] <= factor <= SCALE_RANGE[1]:
        low, high = SCALE_RANGE
        raise SettingsError(
            f"subject scale (--scale, subject_scale) must be auto or {low:g}-{high:g}, got {rule!r}"
        )
    return motion.scaled(factor, "")
