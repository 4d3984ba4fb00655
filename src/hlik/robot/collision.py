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
    """Geom pairs that may collide, and what the distance queries need of their geoms.

    Attributes:
        geoms, bodies: (p, 2) the pairs' geom ids and body ids.
        unique: (g,) the geoms of any pair, sorted; ``index`` (p, 2) the pairs' positions in it.
        aabb: (g, 6) each geom's bounding box in its own frame (centre, half sizes; m).
        rbound: (g,) each geom's bounding-sphere radius about its frame's origin (m).
    """

    geoms: np.ndarray
    bodies: np.ndarray
    unique: np.ndarray
    index: np.ndarray
    aabb: np.ndarray
    rbound: np.ndarray

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
    unique = np.unique(arr[:, :2])
    index = np.searchsorted(unique, arr[:, :2])
    return CollisionPairs(arr[:, :2], arr[:, 2:], unique, index, m.geom_aabb[unique], m.geom_rbound[unique])


class DistanceBounds:
    """Lower bounds (p,) on the pairs' distances, carried from one configuration to the next.

    A pair whose distance was d at the last evaluation is at least ``d - s1 - s2`` apart now, with
    s the farthest any point of each geom has moved since (its centre's displacement plus its
    bounding radius times the change of its rotation matrix, a bound on the spectral norm), so
    it needs no new distance query until that reaches ``distmax``. Exact for any path; one per
    solver run, since it mutates.
    """

    def __init__(self, pairs: CollisionPairs, horizon: float = 0.05):
        self.horizon = horizon  # queries look this far beyond distmax, so that bounds last
        self.lower = np.full(len(pairs), -np.inf)
        self.pos: np.ndarray | None = None  # (g, 3) geom centres when the bounds were set
        self.mat: np.ndarray | None = None  # (g, 9) geom rotations then

    def update(self, pos: np.ndarray, mat: np.ndarray, pairs: CollisionPairs) -> np.ndarray:
        """The bounds (p,) moved to the geom poses ``pos`` (g, 3), ``mat`` (g, 9), now held."""
        if self.pos is not None and self.mat is not None:
            self.lower -= pair_shift(pairs, self.pos, self.mat, pos, mat)
        self.pos, self.mat = pos, mat
        return self.lower


def pair_shift(
    pairs: CollisionPairs, pos: np.ndarray, mat: np.ndarray, new_pos: np.ndarray, new_mat: np.ndarray
) -> np.ndarray:
    """(p,) a bound on how much each pair's distance changed, m, between the geom poses ``pos``,
    ``mat`` and ``new_pos``, ``new_mat`` ((g, 3), (g, 9), the pairs' geoms): the farthest any point
    of each geom moved, its centre's displacement plus its bounding radius times the change of its
    rotation matrix (a bound on the spectral norm), summed over the pair."""
    dx, dr = new_pos - pos, new_mat - mat
    shift = np.sqrt(np.einsum("gi,gi->g", dx, dx)) + pairs.rbound * np.sqrt(np.einsum("gi,gi->g", dr, dr))
    return shift[pairs.index[:, 0]] + shift[pairs.index[:, 1]]


def pair_distances(
    robot: Robot,
    data: mujoco.MjData,
    pairs: CollisionPairs,
    distmax: float,
    bounds: DistanceBounds | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances (k,) of the pairs closer than ``distmax`` (m), and their gradients (k, n):
    :func:`near_pairs` without the pairs' indices."""
    _, dist, grad = near_pairs(robot, data, pairs, distmax, bounds)
    return dist, grad


def near_pairs(
    robot: Robot,
    data: mujoco.MjData,
    pairs: CollisionPairs,
    distmax: float | np.ndarray,
    bounds: DistanceBounds | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs closer than ``distmax`` (m; one for all, or (p,) one per pair): their indices (k,)
    into ``pairs``, signed distances (k,) and the distances' gradients (k, n).

    ``data`` must hold the configuration's kinematics (``mj_kinematics`` and ``mj_comPos``). The
    gradient of the distance between the nearest points p1 (on geom 1) and p2 is
    ``n . (J_p2 - J_p1)`` with n the unit vector from p1 to p2 (reversed when they overlap).
    ``bounds`` (updated) skips the pairs known to be farther than ``distmax``; same result.
    """
    m = robot.model
    if len(pairs) == 0:
        return np.zeros(0, dtype=int), np.zeros(0), np.zeros((0, robot.dof))
    pos, mat = data.geom_xpos[pairs.unique], data.geom_xmat[pairs.unique]
    distmax = np.broadcast_to(np.asarray(distmax, dtype=float), (len(pairs),))
    if bounds is not None:
        # the carried bounds are the broad phase: few pairs come closer than the last query said
        near = np.flatnonzero(bounds.update(pos, mat, pairs) < distmax)
        horizon = distmax + bounds.horizon
    else:
        # a lower bound on each pair's distance from the geoms' world-aligned bounding boxes
        rot = mat.reshape(-1, 3, 3)
        centre = pos + (rot @ pairs.aabb[:, :3, None])[..., 0]
        half = (np.abs(rot) @ pairs.aabb[:, 3:, None])[..., 0]
        i, j = pairs.index[:, 0], pairs.index[:, 1]
        gap = np.abs(centre[i] - centre[j]) - half[i] - half[j]  # (p, 3): separation along x, y, z
        near = np.flatnonzero(np.maximum(np.maximum(gap[:, 0], gap[:, 1]), gap[:, 2]) < distmax)
        horizon = distmax
    dist = np.empty(len(near))
    fromto = np.empty((len(near), 6))
    for k, (g1, g2) in enumerate(pairs.geoms[near].tolist()):
        dist[k] = mujoco.mj_geomDistance(m, data, g1, g2, horizon[near[k]], fromto[k])
    if bounds is not None:
        bounds.lower[near] = dist
    v = fromto[:, 3:] - fromto[:, :3]
    length = np.sqrt(np.einsum("ki,ki->k", v, v))
    hit = np.flatnonzero((dist < distmax[near]) & (length > 1e-12))  # touching at a point: no direction
    if len(hit) == 0:
        return np.zeros(0, dtype=int), np.zeros(0), np.zeros((0, robot.dof))
    normal = v[hit] * (np.where(dist[hit] >= 0, 1.0, -1.0) / length[hit])[:, None]
    jac = np.empty((len(hit), 2, 3, m.nv))
    points = fromto[hit].reshape(-1, 2, 3)
    for k, (b1, b2) in enumerate(pairs.bodies[near[hit]].tolist()):
        mujoco.mj_jac(m, data, jac[k, 0], None, points[k, 0], b1)
        mujoco.mj_jac(m, data, jac[k, 1], None, points[k, 1], b2)
    return near[hit], dist[hit], np.einsum("kj,kjn->kn", normal, jac[:, 1] - jac[:, 0])


def velocity_damper(
    robot: Robot,
    data: mujoco.MjData,
    pairs: CollisionPairs,
    margin: float,
    detect: float | np.ndarray,
    gain: float,
    bounds: DistanceBounds | None = None,
    floors: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Rows (k, n) and bounds (k,) a step dq must meet, ``rows @ dq <= rhs``, to keep the pairs
    closer than ``detect`` (m; or (p,), per pair) at least ``margin`` apart: each may approach
    by at most ``gain`` of its distance to the margin, ``d + grad dq >= margin - (1 - gain)(d -
    margin)`` (mink's velocity damper), and come no closer than its entry of ``floors`` (p,), m,
    if given (a frame's braking distances). ``data`` must hold the kinematics of the
    configuration (``mj_kinematics``); ``bounds`` as in :func:`pair_distances`."""
    mujoco.mj_comPos(robot.model, data)
    index, dist, grad = near_pairs(robot, data, pairs, detect, bounds)
    rhs = gain * (dist - margin)
    if floors is not None:
        rhs = np.minimum(rhs, dist - floors[index])
    return -grad, rhs
