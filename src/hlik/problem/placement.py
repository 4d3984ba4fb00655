"""Where the robot stands in the human's world: a rigid transform ``world <- robot base``.

Until reachability-based placement exists, the robot is put so that the midpoint of its shoulders
coincides with the human's at the first frame, facing the same way (heading from the shoulder line,
so a slouch or a turned pelvis does not tilt the robot).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hlik.fk import site_poses
from hlik.human.kinematics import HumanKinematics, shoulder_frame
from hlik.robot.model import SIDES, Robot


@dataclass(frozen=True, eq=False)
class Placement:
    """The pose of the robot base in the world.

    Attributes:
        rotation: (3, 3) world <- base rotation.
        translation: (3,) base origin in the world, metres.
    """

    rotation: np.ndarray
    translation: np.ndarray

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) homogeneous world <- base transform."""
        m = np.eye(4)
        m[:3, :3] = self.rotation
        m[:3, 3] = self.translation
        return m

    @classmethod
    def from_matrix(cls, matrix: np.ndarray) -> Placement:
        matrix = np.asarray(matrix, dtype=float)
        return cls(matrix[:3, :3].copy(), matrix[:3, 3].copy())

    def to_world(self, pos: np.ndarray, rot: np.ndarray | None = None):
        """Base-frame positions (..., 3) (and rotations (..., 3, 3)) expressed in the world."""
        p = pos @ self.rotation.T + self.translation
        return p if rot is None else (p, self.rotation @ rot)

    def to_base(self, pos: np.ndarray, rot: np.ndarray | None = None):
        """World positions (..., 3) (and rotations (..., 3, 3)) expressed in the robot base frame."""
        p = (pos - self.translation) @ self.rotation
        return p if rot is None else (p, self.rotation.T @ rot)


def shoulder_placement(robot: Robot, human: HumanKinematics) -> Placement:
    """Shoulder midpoints coincide at the first frame, both facing the same way; robot at home."""
    ids = np.array([robot.site_id(s, "shoulder") for s in SIDES])
    pos, _ = site_poses(robot.model, robot.home[None], ids)
    r_rob, o_rob = shoulder_frame(pos[0, 0], pos[0, 1])
    r_hum, o_hum = shoulder_frame(human.shoulder[0, 0], human.shoulder[0, 1])
    rotation = r_hum @ r_rob.T
    return Placement(rotation, o_hum - rotation @ o_rob)
