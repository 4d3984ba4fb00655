"""How low a robot reaches: the lowest point of its geometry, in its base frame, per configuration.

The floor is z = 0 of the base frame (robots/README.md), so a robot placed upright at world height
``z`` stands on the world floor when ``z + lowest_points(robot, q)`` is 0 for its standing parts.
Exact for MuJoCo's primitives (sphere, capsule, cylinder, box, ellipsoid) and meshes (their
vertices); planes and height fields are skipped.
"""

from __future__ import annotations

import mujoco
import numpy as np

from hlik.robot.model import Robot

_T = mujoco.mjtGeom


def lowest_point(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """The lowest z (m, base frame) of any geom for the kinematics ``data`` holds."""
    lowest = np.inf
    for g in range(model.ngeom):
        kind, size = model.geom_type[g], model.geom_size[g]
        z, up = data.geom_xpos[g, 2], data.geom_xmat[g].reshape(3, 3)[2]  # world z of the geom axes
        if kind == _T.mjGEOM_SPHERE:
            low = z - size[0]
        elif kind == _T.mjGEOM_CAPSULE:
            low = z - abs(up[2]) * size[1] - size[0]
        elif kind == _T.mjGEOM_CYLINDER:
            low = z - abs(up[2]) * size[1] - size[0] * np.sqrt(max(1.0 - up[2] ** 2, 0.0))
        elif kind == _T.mjGEOM_BOX:
            low = z - np.abs(up) @ size
        elif kind == _T.mjGEOM_ELLIPSOID:
            low = z - np.linalg.norm(up * size)
        elif kind == _T.mjGEOM_MESH:
            mesh = model.geom_dataid[g]
            start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
            low = z + float(np.min(model.mesh_vert[start : start + count] @ up))
        else:
            continue
        lowest = min(lowest, float(low))
    return lowest


def lowest_points(robot: Robot, q: np.ndarray) -> np.ndarray:
    """(T,) the lowest point (m, base frame) of the robot at each configuration of ``q`` (T, n)."""
    data = mujoco.MjData(robot.model)
    out = np.empty(len(q))
    for k, qk in enumerate(np.atleast_2d(q)):
        data.qpos[:] = qk
        mujoco.mj_kinematics(robot.model, data)
        out[k] = lowest_point(robot.model, data)
    return out
