"""The human's velocity manipulability: what MAN^r compares the robot's to (paper Sec. III-C,
:mod:`hlik.criteria.manipulability`), from the MMM model normalised to 1 m.
"""

from __future__ import annotations

import mujoco
import numpy as np

from hlik.human.kinematics import human_model, qpos_trajectory
from hlik.human.motion import ARM_JOINTS, HumanMotion

SIDES = ("left", "right")


def velocity_manipulability(jac_pos: np.ndarray) -> np.ndarray:
    """(..., 3, 3) velocity manipulability ``J J^T`` of a (..., 3, k) position Jacobian."""
    return jac_pos @ np.swapaxes(jac_pos, -1, -2)


def human_tcp_jacobians(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """(T, 2, 3, 7) TCP position Jacobians of the MMM model over each arm's :data:`ARM_JOINTS`."""
    data = mujoco.MjData(model)
    sites = [model.site(f"{s}_tcp").id for s in SIDES]
    dofs = [model.jnt_dofadr[[model.joint(j).id for j in ARM_JOINTS[s]]] for s in SIDES]
    jac = np.empty((len(qpos), 2, 3, 7))
    jac_pos = np.empty((3, model.nv))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        for i, site in enumerate(sites):
            mujoco.mj_jacSite(model, data, jac_pos, None, site)
            jac[t, i] = jac_pos[:, dofs[i]]
    return jac


def human_manipulability(motion: HumanMotion) -> np.ndarray:
    """(T, 2, 3, 3) TCP velocity manipulability of the normalised (1 m) MMM model, world frame, m².

    Only each arm's 7 :data:`~hlik.motion.ARM_JOINTS` count. In the robot base frame with
    rotation R (world <- robot) it is ``R^T M R``.
    """
    model = human_model(1.0)
    return velocity_manipulability(human_tcp_jacobians(model, qpos_trajectory(model, motion)))
