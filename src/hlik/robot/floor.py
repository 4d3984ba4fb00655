"""How low a robot reaches, and the height at which it stands on its floor.

The floor is z = 0 of the base frame for every model that follows robots/README.md (tested), so a
robot placed upright at world height ``z`` stands on the world floor when ``z`` is
:func:`floor_height`. Exact for MuJoCo's primitives (sphere, capsule, cylinder, box, ellipsoid)
and meshes (a mesh's lowest point is a vertex of its convex hull); planes and height fields have no
bottom of their own and are skipped.
"""

from __future__ import annotations

import functools

import mujoco
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from hlik.robot.model import Robot

FLOOR_TOLERANCE = 1e-3  # m: a base this close to the robot's floor height stands on the floor


def floor_height(robot: Robot) -> float:
    """Height of the base origin above the floor when the robot stands on it, m: minus the lowest
    point of its geometry (visual and collision) at home, in the base frame. 0 for the bundled
    models and the G1 example (robots/README.md; tested). Rounded to 0.1 mm (a summary then reads
    0.00, not -0.00)."""
    return 0.0 - round(_home_lowest(robot), 4)  # 0.0 - x: never -0.0


@functools.lru_cache(maxsize=32)
def _home_lowest(robot: Robot) -> float:
    return float(lowest_points(robot, robot.home[None])[0])


def lowest_points(
    robot: Robot, q: np.ndarray, rotation: np.ndarray | None = None, height: float = 0.0
) -> np.ndarray:
    """(T,) the lowest world z of the robot's geometry (every geom, visual and collision) at each
    configuration of ``q`` (T, n), m, the base turned by ``rotation`` (3, 3) (world <- base; the
    identity if None) at world height ``height``."""
    model = robot.model
    q = np.atleast_2d(np.asarray(q, dtype=float))
    up = np.eye(3)[2] if rotation is None else np.asarray(rotation)[2]  # world z in the base frame
    data = mujoco.MjData(model)
    pos = np.empty((len(q), model.ngeom, 3))
    mat = np.empty((len(q), model.ngeom, 3, 3))
    for k, qk in enumerate(q):
        data.qpos[:] = qk
        mujoco.mj_kinematics(model, data)
        pos[k], mat[k] = data.geom_xpos, data.geom_xmat.reshape(-1, 3, 3)
    axis_z = np.einsum("i,tgij->tgj", up, mat)  # (T, g, 3): world z of each geom axis
    centre_z = pos @ up + height
    size = model.geom_size
    low = np.full((len(q), model.ngeom), np.inf)
    geom = mujoco.mjtGeom
    for g in range(model.ngeom):
        a, s, kind = axis_z[:, g], size[g], model.geom_type[g]
        if kind == geom.mjGEOM_MESH:
            depth = (a @ _hull_vertices(robot, int(model.geom_dataid[g])).T).min(axis=1)
        elif kind == geom.mjGEOM_SPHERE:
            depth = np.full(len(q), -s[0])
        elif kind == geom.mjGEOM_CAPSULE:
            depth = -np.abs(a[:, 2]) * s[1] - s[0]
        elif kind == geom.mjGEOM_CYLINDER:
            depth = -np.abs(a[:, 2]) * s[1] - s[0] * np.sqrt(np.clip(1.0 - a[:, 2] ** 2, 0.0, 1.0))
        elif kind == geom.mjGEOM_BOX:
            depth = -np.abs(a) @ s
        elif kind == geom.mjGEOM_ELLIPSOID:
            depth = -np.sqrt(((a * s) ** 2).sum(axis=1))
        else:  # planes, height fields: no bottom of their own
            continue
        low[:, g] = centre_z[:, g] + depth
    return low.min(axis=1)


@functools.lru_cache(maxsize=256)
def _hull_vertices(robot: Robot, mesh: int) -> np.ndarray:
    """(k, 3) the vertices of a mesh's convex hull, in the mesh (geom) frame."""
    m = robot.model
    start = int(m.mesh_vertadr[mesh])
    vert = np.array(m.mesh_vert[start : start + int(m.mesh_vertnum[mesh])], dtype=float)
    try:
        return vert[ConvexHull(vert).vertices]
    except (QhullError, ValueError):  # flat or tiny: every vertex
        return vert
