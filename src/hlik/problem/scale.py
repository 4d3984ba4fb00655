"""How tall a subject the robot retargets from: the recorded one, or one scaled to the robot's arms.

The paper retargets hand poses as recorded, to robots about a person's size (``subject_scale = 1``,
the default). A robot much smaller or larger than the subject cannot reach the recorded hand poses
with any posture; ``auto`` scales the subject (:meth:`HumanMotion.scaled`: height, root and hand
positions; the joint angles stay) by the robot's arm length over the subject's, the usual
human-to-robot scaling of retargeting tools, about the shoulders.
"""

from __future__ import annotations

import mujoco
import numpy as np

from hlik.human.kinematics import human_model
from hlik.human.limits import scale_factor
from hlik.human.motion import HumanMotion
from hlik.robot.model import SIDES, Robot

ARM = ("shoulder", "elbow", "wrist", "tcp")


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


def shoulder_heights(robot: Robot, motion: HumanMotion) -> tuple[np.ndarray, float]:
    """The subject's shoulder midpoint at the first frame (3,), world, m, and the height of the
    robot's at home standing on the floor, m."""
    from hlik.human.kinematics import forward_kinematics
    from hlik.robot.floor import floor_height
    from hlik.util.spatial import site_poses

    ids = np.array([robot.site_id(side, "shoulder") for side in SIDES])
    robot_z = float(np.mean(site_poses(robot.model, robot.home[None], ids)[0][0, :, 2])) + floor_height(robot)
    human = np.mean(forward_kinematics(motion.frames(slice(0, 1))).shoulder[0], axis=0)
    return human, robot_z


def scale_subject(motion: HumanMotion, robot: Robot, rule: float | str | None = None) -> HumanMotion:
    """``motion`` by a subject scaled by ``rule``: a factor (about the origin, the floor stays),
    ``"auto"``, or None for the robot's own (``Robot.subject_scale``).

    ``auto`` scales by :func:`auto_scale` about the subject's shoulders (first frame), which then
    stand at the height of the robot's: the hand targets keep the subject's reach in arm lengths
    about the shoulders. Scaled about the floor, a robot whose arms are long for its height would
    get targets above its head (ARMAR-6: x1.51, the scaled subject's shoulders 0.73 m above the
    robot's); the subject's feet leave the floor instead, by :func:`shoulder_heights`' gap.

    Raises:
        SettingsError: a rule that is neither ``auto`` nor a positive number.
    """
    rule = robot.subject_scale if rule is None else rule
    factor = scale_factor(rule)
    if factor is None:
        factor = auto_scale(robot, motion)
        shoulders, robot_z = shoulder_heights(robot, motion)
        lift = robot_z - factor * shoulders[2]
        feet = f"{abs(lift):.2f} m {'above' if lift > 0 else 'below'} the floor"
        height = lambda z: robot_z + factor * (z - shoulders[2])  # noqa: E731
        heights = [o.position[:, 2] for o in motion.objects.values() if np.any(np.isfinite(o.position))]
        if heights:  # the scene moves with the subject: the robot works at the scaled objects
            z = float(np.nanmedian(np.concatenate(heights)))
            scene = f"the objects with it, their median height {z:.2f} m -> {height(z):.2f} m"
        else:
            scene = f"the hand targets with it: a table 0.90 m high would stand at {height(0.9):.2f} m"
        why = f" to {robot.title}'s arms about its shoulders (subject_scale auto; its feet {feet}; {scene})"
        return motion.scaled(factor, why, about=shoulders, to=np.array([*shoulders[:2], robot_z]))
    return motion.scaled(factor, "")
