"""The robot's left-right mirror map in joint space, where its model has one.

A reflection M = I - 2 n nᵀ of the base frame (n the unit normal of the sagittal plane, from the
left arm's first joint to the right's, horizontal) maps a rotation by θ about an axis a to one by
-θ about M a. So a model is mirror-symmetric when each left arm joint has a right partner (the
same place in ``[arms]``) at the reflected anchor with the axis ±M a, each extra (trunk) joint is
its own partner, and the partners' ranges, speed, acceleration and effort limits and home angles
are each other's under the sign: then q' = sign · q[source] poses the mirror image of the robot
posed by q. Checked on the model (anchors and axes at q = 0) and by forward kinematics (the TCPs
at random configurations).

Used by the mirror-symmetry property (a take and its mirror image retarget to mirror images) on the
robots this holds for: ARMAR-6 and the G1; ARMAR-III's published ranges differ between its arms
(elbow, wrists), and the Panda's joints 4 and 6 have one-sided ranges that a mirrored Panda would
reverse.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from hlik.robot.model import COLLISION_GROUP, Robot, tcp_poses
from hlik.robot.reachability import UNLIMITED_RANGE
from hlik.util.errors import HlikError

#: Tolerances of the check: anchors and TCPs, m; axes (|cos|), limits, rad or the limit's unit.
POSITION_TOL = 1e-6
AXIS_TOL = 1e-6
LIMIT_TOL = 1e-4
GEOM_TOL = 1e-3  # m: meshes exported per side differ by a fraction of a millimetre


class NotMirrorSymmetric(HlikError):
    """The robot's model has no left-right mirror map; the message names the first joint that breaks it."""


@dataclass(frozen=True)
class JointMirror:
    """q' = sign · q[source] poses the mirror image of the robot posed by q.

    Attributes:
        source: (n,) index of the joint each joint takes its angle from (its partner).
        sign: (n,) ±1: -1 where the partner's axis is the reflected axis (the sense reverses).
        normal: (3,) unit normal of the mirror plane, base frame.
        point: (3,) a point of the mirror plane, base frame, m.
    """

    source: np.ndarray
    sign: np.ndarray
    normal: np.ndarray
    point: np.ndarray

    def apply(self, q: np.ndarray) -> np.ndarray:
        """Joint angles (..., n) of the mirror image, rad."""
        return np.asarray(q)[..., self.source] * self.sign

    def reflect(self, points: np.ndarray) -> np.ndarray:
        """Points (..., 3) in the base frame reflected in the mirror plane, m."""
        p = np.asarray(points, dtype=float)
        return p - 2.0 * ((p - self.point) @ self.normal)[..., None] * self.normal


def joint_mirror(robot: Robot, collision: bool = True, samples: int = 20, seed: int = 0) -> JointMirror:
    """The robot's mirror map, checked (see the module); ``collision``: its collision geoms too
    (each the mirror image of one of the same type and size, within :data:`GEOM_TOL`).

    Raises:
        NotMirrorSymmetric: the first joint whose partner is not its mirror image (place, axis,
            range or limits), TCPs that do not mirror, or the collision geom furthest from any
            mirror image.
    """
    model, data = robot.model, mujoco.MjData(robot.model)
    mujoco.mj_kinematics(model, data)
    left, right = robot.arm_joints["left"], robot.arm_joints["right"]
    if len(left) != len(right):
        raise NotMirrorSymmetric(f"{robot.name}: the arms have {len(left)} and {len(right)} joints")
    anchor = {n: data.xanchor[model.joint(n).id].copy() for n in robot.joint_names}
    axis = {n: data.xaxis[model.joint(n).id].copy() for n in robot.joint_names}
    normal = anchor[right[0]] - anchor[left[0]]
    normal[2] = 0.0
    normal /= np.linalg.norm(normal)
    point = (anchor[left[0]] + anchor[right[0]]) / 2
    reflect = np.eye(3) - 2.0 * np.outer(normal, normal)
    partners = [*zip(left, right), *zip(right, left), *((e, e) for e in robot.extra_joints)]
    source, sign = np.arange(robot.dof), np.ones(robot.dof)
    for a, b in partners:
        i, k = int(robot.index(a)), int(robot.index(b))
        cos = float(axis[b] @ (reflect @ axis[a]))
        moved = np.linalg.norm(point + (anchor[a] - point) @ reflect - anchor[b])
        if moved > POSITION_TOL or abs(abs(cos) - 1) > AXIS_TOL:
            raise NotMirrorSymmetric(f"{robot.name}: joint {b} is not the mirror image of {a} (place, axis)")
        source[k], sign[k] = i, (-1.0 if cos > 0 else 1.0)
        _check_limits(robot, a, b, i, k, sign[k])
    mirror = JointMirror(source, sign, normal, point)
    odd = np.flatnonzero(np.abs(mirror.apply(robot.home) - robot.home) > LIMIT_TOL)
    if len(odd):  # the first frame starts from home: an asymmetric one seeds asymmetric postures
        raise NotMirrorSymmetric(
            f"{robot.name}: its home pose is not mirror-symmetric at {robot.joint_names[odd[0]]}"
        )
    _check_tcps(robot, mirror, reflect, samples, seed)
    if collision:
        _check_collision_geoms(robot, mirror, seed)
    return mirror


def _configurations(robot: Robot, n: int, seed: int) -> np.ndarray:
    """(n, dof) joint angles drawn uniformly within the ranges (unlimited joints within ±π), rad."""
    lo = np.where(np.isfinite(robot.lower), robot.lower, -UNLIMITED_RANGE)
    hi = np.where(np.isfinite(robot.upper), robot.upper, UNLIMITED_RANGE)
    return np.random.default_rng(seed).uniform(lo, hi, (n, robot.dof))


def _check_limits(robot: Robot, a: str, b: str, i: int, k: int, sign: float) -> None:
    lo, hi = sorted((sign * robot.lower[i], sign * robot.upper[i]))
    if not np.allclose([lo, hi], [robot.lower[k], robot.upper[k]], atol=LIMIT_TOL):
        raise NotMirrorSymmetric(
            f"{robot.name}: joint {b}'s range [{robot.lower[k]:.6g}, {robot.upper[k]:.6g}] rad is not "
            f"{a}'s mirrored, [{lo:.6g}, {hi:.6g}]"
        )
    for what in ("velocity_limit", "acceleration_limit", "effort_limit"):
        limit = getattr(robot, what)
        if limit is not None and not np.isclose(limit[i], limit[k], rtol=LIMIT_TOL):
            kind = what.replace("_", " ")
            raise NotMirrorSymmetric(f"{robot.name}: joints {a} and {b} have different {kind}s")


def _check_tcps(robot: Robot, mirror: JointMirror, reflect: np.ndarray, samples: int, seed: int) -> None:
    frame = None  # the constant turn between a TCP frame and its partner's reflected frame
    for q in _configurations(robot, samples, seed):
        (pos,), (rot,) = tcp_poses(robot, q[None])
        (pos_m,), (rot_m,) = tcp_poses(robot, mirror.apply(q)[None])
        if np.abs(mirror.reflect(pos[::-1]) - pos_m).max() > POSITION_TOL:
            raise NotMirrorSymmetric(f"{robot.name}: the TCPs of mirrored joint angles do not mirror")
        turn = np.einsum("ij,sjk,kl->sil", reflect, rot[::-1], reflect).transpose(0, 2, 1) @ rot_m
        frame = turn if frame is None else frame
        if np.abs(turn - frame).max() > 1e-6:
            raise NotMirrorSymmetric(f"{robot.name}: the TCP frames of mirrored joint angles do not mirror")


def _check_collision_geoms(robot: Robot, mirror: JointMirror, seed: int) -> None:
    model, data = robot.model, mujoco.MjData(robot.model)
    colliding = (model.geom_contype | model.geom_conaffinity) > 0
    geoms = np.flatnonzero((model.geom_group == COLLISION_GROUP) & colliding)
    (q,) = _configurations(robot, 1, seed)
    centres = []
    for pose in (q, mirror.apply(q)):
        data.qpos[: robot.dof] = pose
        mujoco.mj_kinematics(model, data)
        centres.append(data.geom_xpos[geoms].copy())
    shape = np.column_stack([model.geom_type[geoms], model.geom_size[geoms]])
    same = np.all(np.abs(shape[:, None] - shape[None]) <= GEOM_TOL, axis=2)  # (g, g) alike
    gap = np.linalg.norm(mirror.reflect(centres[0])[:, None] - centres[1][None], axis=2)
    off = np.where(same, gap, np.inf).min(axis=1)
    worst = int(np.argmax(off))
    if off[worst] > GEOM_TOL:
        geom = geoms[worst]
        name = model.geom(geom).name or f"#{geom}"
        body = model.body(model.geom_bodyid[geom]).name
        raise NotMirrorSymmetric(
            f"{robot.name}: collision geom {name} of {body} lies {off[worst] * 1e3:.1f} mm "
            "from any mirror image"
        )
