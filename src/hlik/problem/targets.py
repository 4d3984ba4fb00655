"""Hand targets: the human TCP poses, expressed in the robot's base frame through a placement.

The human TCP and the robot TCPs share one frame convention (z = approach, x = palm normal; see
``robots/README.md``), so a human hand pose is a robot TCP target as it is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hlik.human.kinematics import HumanKinematics
from hlik.problem.placement import Placement
from hlik.robot.reach import ArmReach


@dataclass(frozen=True, eq=False)
class HandTargets:
    """TCP targets of both arms (index 0 = left, 1 = right) in the robot base frame.

    Attributes:
        pos: (T, 2, 3) positions, metres.
        rot: (T, 2, 3, 3) orientations.
    """

    pos: np.ndarray
    rot: np.ndarray

    @property
    def n_frames(self) -> int:
        return len(self.pos)


def hand_targets(human: HumanKinematics, placement: Placement) -> HandTargets:
    """The human's TCP trajectories as robot TCP targets."""
    pos, rot = placement.to_base(human.tcp_pos, human.tcp_rot)
    return HandTargets(pos, rot)


def within_reach(targets: HandTargets, reach: ArmReach) -> HandTargets:
    """``targets`` with each position beyond its arm's reach sphere moved onto it, along the line
    from the sphere's centre (the nearest point of the sphere); orientations and the positions
    inside kept. What the solvers track (:attr:`hlik.problem.problem.Problem.tracked`); the
    trajectory and its scores keep ``targets``."""
    offset = targets.pos - reach.centre
    distance = np.linalg.norm(offset, axis=-1, keepdims=True)
    radius = reach.radius[:, None]
    onto = reach.centre + offset * (radius / np.maximum(distance, 1e-12))
    return HandTargets(np.where(distance > radius, onto, targets.pos), targets.rot)  # inside: as given
