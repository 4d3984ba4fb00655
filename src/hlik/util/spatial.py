"""Rotations and frames: the helpers every stage shares (angles between rotations, rotation
vectors, cross products and their matrices, yaw about the vertical, quaternion orders) and forward
kinematics over whole trajectories with MuJoCo (every stage that needs poses of many frames calls
:func:`site_poses` or :func:`body_poses` instead of looping over ``mj_kinematics`` itself).
Matrices are (..., 3, 3), vectors (..., 3); MuJoCo's quaternions are w, x, y, z, SciPy's and
Rerun's x, y, z, w.
"""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation


def rotation_angle(rot_a: np.ndarray, rot_b: np.ndarray) -> np.ndarray:
    """fORI: (...,) angles of ``rot_a^T rot_b`` for (..., 3, 3) rotations, radians in [0, pi]."""
    rel = np.swapaxes(rot_a, -1, -2) @ rot_b
    # atan2 of sine and cosine stays exact near 0, where arccos of the trace loses half the digits
    axis = np.stack(
        [rel[..., 2, 1] - rel[..., 1, 2], rel[..., 0, 2] - rel[..., 2, 0], rel[..., 1, 0] - rel[..., 0, 1]],
        -1,
    )
    cos = (np.trace(rel, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.arctan2(np.linalg.norm(axis, axis=-1) / 2.0, cos)


def rotation_vector(rot: np.ndarray) -> np.ndarray:
    """(..., 3) axis * angle of rotations (..., 3, 3); closed form, SciPy only near pi."""
    axis = rot[..., _ROWS, _COLS] - rot[..., _COLS, _ROWS]  # 2 sin(angle) * unit axis
    sin2 = np.sqrt(np.sum(axis * axis, axis=-1))
    angle = np.arctan2(sin2, rot[..., 0, 0] + rot[..., 1, 1] + rot[..., 2, 2] - 1.0)
    if np.max(angle, initial=0.0) > np.pi - 1e-3:
        return Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_rotvec().reshape(rot.shape[:-1])
    return axis * np.where(sin2 > 1e-12, angle / np.maximum(sin2, 1e-300), 0.5)[..., None]


_ROWS, _COLS = (2, 0, 1), (1, 2, 0)


def skew(v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) cross-product matrices of vectors (..., 3)."""
    z = np.zeros(v.shape[:-1])
    return np.stack(
        [
            np.stack([z, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], z, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], z], -1),
        ],
        -2,
    )


def cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """u x v (..., 3) over the last axis, broadcast; np.cross costs ten times more on the criteria's
    small arrays."""
    return np.stack(
        [
            u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1],
            u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
            u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0],
        ],
        axis=-1,
    )


def yaw_rotation(angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` (rad) about the vertical z axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def xyzw(wxyz: np.ndarray) -> np.ndarray:
    """(..., 4) quaternions w, x, y, z (MuJoCo's order) as x, y, z, w (SciPy's, Rerun's)."""
    return np.roll(wxyz, -1, axis=-1)


def wxyz_from_rpy(rpy: np.ndarray) -> np.ndarray:
    """(4,) MuJoCo quaternion (w, x, y, z) of URDF roll, pitch, yaw (fixed axes x, y, z), rad."""
    return np.roll(Rotation.from_euler("xyz", rpy).as_quat(), 1)


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
