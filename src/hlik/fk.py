"""Forward kinematics over whole trajectories, with MuJoCo.

Every stage that needs poses of many frames (human targets, robot TCPs, the recording) calls these
two functions instead of looping over ``mj_kinematics`` itself.
"""

from __future__ import annotations

import mujoco
import numpy as np


def site_poses(model: mujoco.MjModel, qpos: np.ndarray, sites: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World poses of ``sites`` for every configuration.

    Args:
        model: A MuJoCo model.
        qpos: (T, nq) configurations.
        sites: (...,) integer site ids; any shape.

    Returns:
        (T, ..., 3) positions and (T, ..., 3, 3) rotation matrices.
    """
    sites = np.asarray(sites, dtype=int)
    data = mujoco.MjData(model)
    pos = np.empty((len(qpos), sites.size, 3))
    rot = np.empty((len(qpos), sites.size, 9))
    flat = sites.ravel()
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        pos[k] = data.site_xpos[flat]
        rot[k] = data.site_xmat[flat]
    shape = (len(qpos), *sites.shape)
    return pos.reshape(*shape, 3), rot.reshape(*shape, 3, 3)


def body_poses(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World poses of all bodies for every configuration.

    Args:
        model: A MuJoCo model.
        qpos: (T, nq) configurations.

    Returns:
        (T, nbody, 3) positions and (T, nbody, 4) quaternions, scalar first (MuJoCo's wxyz).
    """
    data = mujoco.MjData(model)
    pos = np.empty((len(qpos), model.nbody, 3))
    quat = np.empty((len(qpos), model.nbody, 4))
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        pos[k] = data.xpos
        quat[k] = data.xquat
    return pos, quat
