"""Self-collision distances of a robot's collision geometry, with their Jacobians.

The candidate pairs are the collision geoms (group :data:`~hlik.robot.model.COLLISION_GROUP`) that
MuJoCo's own filter lets touch: different rigid bodies, compatible ``contype``/``conaffinity``, not
an ``<exclude>`` pair, not parent and child (unless the parent is welded to the world). Solvers turn
the distances into constraints that keep every pair at least a margin apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from hlik.robot.model import COLLISION_GROUP, Robot


@dataclass(frozen=True, eq=False)
class CollisionPairs:
    """Geom pairs (p, 2) that may collide, and their bodies (p, 2)."""

    geoms: np.ndarray
    bodies: np.ndarray

    def __len__(self) -> int:
        return len(self.geoms)


def collision_pairs(robot: Robot) -> CollisionPairs:
    """Every pair of collision geoms MuJoCo's contact filter would let collide."""
    m = robot.model
    geoms = np.flatnonzero((m.geom_group == COLLISION_GROUP) & ((m.geom_contype | m.geom_conaffinity) > 0))
    excluded = {int(s) for s in m.exclude_signature}
    pairs = []
    for i, g1 in enumerate(geoms):
        for g2 in geoms[i + 1 :]:
            b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
            w1, w2 = int(m.body_weldid[b1]), int(m.body_weldid[b2])
            if w1 == w2:
                continue
            if not (
                m.geom_contype[g1] & m.geom_conaffinity[g2] or m.geom_contype[g2] & m.geom_conaffinity[g1]
            ):
                continue
            lo, hi = min(b1, b2), max(b1, b2)
            if (lo << 16) + hi in excluded:
                continue
            p1, p2 = int(m.body_weldid[m.body_parentid[w1]]), int(m.body_weldid[m.body_parentid[w2]])
            if (p2 == w1 != 0) or (p1 == w2 != 0):
                continue  # MuJoCo's parent filter (a parent welded to the world does not count)
            pairs.append((g1, g2, b1, b2))
    arr = np.array(pairs, dtype=int).reshape(-1, 4)
    return CollisionPairs(arr[:, :2], arr[:, 2:])


def pair_distances(
    robot: Robot, data: mujoco.MjData, pairs: CollisionPairs, distmax: float
) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances (k,) of the pairs closer than ``distmax`` (m), and their gradients (k, n).

    ``data`` must hold the configuration's kinematics (``mj_kinematics`` and ``mj_comPos``). The
    gradient of the distance between the nearest points p1 (on geom 1) and p2 is
    ``n . (J_p2 - J_p1)`` with n the unit vector from p1 to p2 (reversed when they overlap).
    """
    m = robot.model
    g = pairs.geoms
    if len(g) == 0:
        return np.zeros(0), np.zeros((0, robot.dof))
    centre = data.geom_xpos[g]  # (p, 2, 3)
    near = np.linalg.norm(centre[:, 0] - centre[:, 1], axis=-1) - m.geom_rbound[g].sum(axis=1) < distmax
    dists, rows = [], []
    fromto = np.zeros(6)
    jac1, jac2 = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    for (g1, g2), (b1, b2) in zip(g[near], pairs.bodies[near]):
        d = mujoco.mj_geomDistance(m, data, g1, g2, distmax, fromto)
        if d >= distmax:
            continue
        p1, p2 = fromto[:3].copy(), fromto[3:].copy()
        v = p2 - p1
        length = np.linalg.norm(v)
        if length < 1e-12:
            continue  # touching at a point: no direction to push along
        normal = v / length * (1.0 if d >= 0 else -1.0)
        mujoco.mj_jac(m, data, jac1, None, p1, b1)
        mujoco.mj_jac(m, data, jac2, None, p2, b2)
        dists.append(d)
        rows.append(normal @ (jac2 - jac1))
    if not dists:
        return np.zeros(0), np.zeros((0, robot.dof))
    return np.array(dists), np.array(rows)


def velocity_damper(
    robot: Robot, data: mujoco.MjData, pairs: CollisionPairs, margin: float, detect: float, gain: float
) -> tuple[np.ndarray, np.ndarray]:
    """Rows (k, n) and bounds (k,) a step dq must meet, ``rows @ dq <= rhs``, to keep the pairs
    closer than ``detect`` at least ``margin`` apart (m): each may approach by at most ``gain`` of
    its distance to the margin, ``d + grad dq >= margin - (1 - gain)(d - margin)`` (mink's velocity
    damper). ``data`` must hold the kinematics of the configuration (``mj_kinematics``)."""
    mujoco.mj_comPos(robot.model, data)
    dist, grad = pair_distances(robot, data, pairs, detect)
    return -grad, gain * (dist - margin)
