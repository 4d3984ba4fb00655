"""The human reference of each frame in the robot's terms: what the reference criteria compare to.

HJA^r and SYN^r read the mapped human pose, EEA^r the human's elbow elevation, MAN^r the
normalised human's manipulability (rotated into the robot base frame through the placement).
It is built once per retarget (:class:`~hlik.problem.problem.Problem`) and stored in the
trajectory, where the metrics and the recording read it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hlik.criteria.base import Sample
from hlik.human.kinematics import HumanKinematics, forward_kinematics
from hlik.human.manipulability import human_manipulability
from hlik.human.motion import HumanMotion
from hlik.human.swivel import forward_fill, swivel_angle
from hlik.problem.placement import Placement
from hlik.problem.targets import HandTargets
from hlik.robot.model import Robot, mapped_configuration


@dataclass(frozen=True, eq=False)
class HumanReference:
    """Attributes:
    q_map: (T, n) the human pose mapped to the robot (unclipped; non-arm joints at home).
    psi: (T, 2) the human's elbow elevation angles (last valid value where undefined).
    manip: (T, 2, 3, 3) the normalised human's manipulability, robot base frame.
    """

    q_map: np.ndarray
    psi: np.ndarray
    manip: np.ndarray


def human_reference(
    robot: Robot, motion: HumanMotion, placement: Placement, human: HumanKinematics | None = None
) -> HumanReference:
    """The reference of every frame of ``motion`` for ``robot`` placed at ``placement``; ``human``
    is the motion's forward kinematics, computed here if not given."""
    human = forward_kinematics(motion) if human is None else human
    rot = placement.rotation
    return HumanReference(
        q_map=mapped_configuration(robot, motion),
        psi=forward_fill(swivel_angle(human.shoulder, human.elbow, human.wrist)),  # invariant to yaw
        manip=rot.T @ human_manipulability(motion) @ rot,
    )


def reference_sample(
    reference: HumanReference, targets: HandTargets, rows: slice, history: np.ndarray, dt: float
) -> Sample:
    """The :class:`~hlik.criteria.base.Sample` of the frames ``rows``: their hand targets and human
    reference, with ``history`` (F, 3, n), the three configurations before each, newest first."""
    return Sample(
        targets.pos[rows],
        targets.rot[rows],
        reference.q_map[rows],
        reference.psi[rows],
        reference.manip[rows],
        history,
        dt,
    )
