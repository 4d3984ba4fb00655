"""Robot kinematics at many configurations, the input every criterion reads.

Positions and Jacobians are in the robot base frame (the MuJoCo world of the robot model).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from hlik.robot.model import SITES, Robot


@dataclass(frozen=True, eq=False)
class RobotState:
    """Kinematics at F configurations; arm index 0 = left, 1 = right; site order :data:`SITES`.

    Attributes:
        q: (F, n) joint angles, rad.
        sites: (F, 2, 5, 3) shoulder, elbow, wrist, TCP and manipulability-frame positions, metres.
        tcp_rot: (F, 2, 3, 3) TCP orientations.
        jac: (F, 2, 5, 6, n) site Jacobians, linear rows first (d position / dq, angular velocity
            / dq), or None if not computed.
    """

    q: np.ndarray
    sites: np.ndarray
    tcp_rot: np.ndarray
    jac: np.ndarray | None = None

    @property
    def shoulder(self) -> np.ndarray:
        return self.sites[:, :, 0]

    @property
    def elbow(self) -> np.ndarray:
        return self.sites[:, :, 1]

    @property
    def wrist(self) -> np.ndarray:
        return self.sites[:, :, 2]

    @property
    def tcp(self) -> np.ndarray:
        return self.sites[:, :, 3]


def robot_state(
    robot: Robot,
    q: np.ndarray,
    jacobians: bool = False,
    data: mujoco.MjData | None = None,
    jacobian_sites: tuple[int, ...] = tuple(range(len(SITES))),
) -> RobotState:
    """Forward kinematics (and site Jacobians) of ``robot`` at configurations ``q`` (F, n) or (n,).

    Pass ``data`` (an ``MjData`` of ``robot.model``) when calling per step: making one costs more
    than the kinematics. ``jacobian_sites`` (indices into :data:`SITES`) limits which site
    Jacobians are computed; the others are left zero.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    model = robot.model
    data = mujoco.MjData(model) if data is None else data
    ids = robot.site_ids
    flat = ids.ravel()
    sites = np.empty((len(q), 2, len(SITES), 3))
    rot = np.empty((len(q), 2, 3, 3))
    jac = None
    if jacobians:
        shape = (len(q), 2, len(SITES), 6, model.nv)
        jac = np.empty(shape) if len(jacobian_sites) == len(SITES) else np.zeros(shape)
    for k, qk in enumerate(q):
        data.qpos[:] = qk
        mujoco.mj_kinematics(model, data)
        sites[k] = data.site_xpos[flat].reshape(2, len(SITES), 3)
        rot[k] = data.site_xmat[ids[:, 3]].reshape(2, 3, 3)
        if jac is not None:
            mujoco.mj_comPos(model, data)
            for i, side_ids in enumerate(ids):
                for j in jacobian_sites:
                    mujoco.mj_jacSite(model, data, jac[k, i, j, :3], jac[k, i, j, 3:], side_ids[j])
    return RobotState(q, sites, rot, jac)


def arm_lengths(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """(2,) upper-arm (shoulder -> elbow) and (2,) forearm (elbow -> wrist) lengths at home, metres."""
    s = robot_state(robot, robot.home).sites[0]
    return np.linalg.norm(s[:, 1] - s[:, 0], axis=-1), np.linalg.norm(s[:, 2] - s[:, 1], axis=-1)
