"""How far each arm reaches: a sphere about its shoulder that holds every pose its TCP can take.

A hand target beyond it cannot be reached by any configuration; the solvers then track the nearest
point on it instead (:func:`hlik.problem.targets.within_reach`), so that the hands' pull toward a
point out of reach does not turn the hand, pin the clavicles on their stops or chatter at the
stretched arm's singularity for millimetres of reach (README "Targets out of reach"). The sphere
is the arm's own: its centre the anchor of the arm's first joint at home, its radius the farthest
the TCP gets from there with the arm's and the extra (trunk) joints anywhere in their ranges
(unlimited joints over a turn), found by L-BFGS-B from the farthest of :data:`SAMPLES` random
configurations and home. Where a joint range keeps the arm from stretching in some direction, the
sphere is larger than the reach there: a target it holds may still be out of reach.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import minimize

from hlik.robot.model import SIDES, Robot, tcp_poses

SAMPLES = 2000  # random configurations, the farthest STARTS of which are refined
STARTS = 8
SEED = 0


@dataclass(frozen=True, eq=False)
class ArmReach:
    """Each arm's reach sphere, robot base frame, arms in :data:`~hlik.robot.model.SIDES` order.

    Attributes:
        centre: (2, 3) the anchor of the arm's first joint at home, m.
        radius: (2,) the farthest its TCP gets from the centre, m.
        farthest: (2, n) a configuration that puts each TCP there (the other joints at home), rad.
    """

    centre: np.ndarray
    radius: np.ndarray
    farthest: np.ndarray

    def beyond(self, pos: np.ndarray) -> np.ndarray:
        """(..., 2) how far each of the positions (..., 2, 3) lies beyond its arm's sphere, m (0
        inside)."""
        return np.maximum(np.linalg.norm(pos - self.centre, axis=-1) - self.radius, 0.0)


@functools.lru_cache(maxsize=32)  # per robot, as floor_height: every problem and summary of a run asks
def arm_reach(robot: Robot) -> ArmReach:
    """The :class:`ArmReach` of ``robot`` (module docstring; deterministic, 0.1-0.2 s on the
    bundled robots, once per robot)."""
    model = robot.model
    data = mujoco.MjData(model)
    data.qpos[:] = robot.home
    mujoco.mj_kinematics(model, data)
    centre = np.array([data.xanchor[model.joint(robot.arm_joints[side][0]).id] for side in SIDES])
    farthest = np.array([_farthest(robot, data, i, side, centre[i]) for i, side in enumerate(SIDES)])
    pos, _ = tcp_poses(robot, farthest)
    radius = np.linalg.norm(pos[np.arange(len(SIDES)), np.arange(len(SIDES))] - centre, axis=-1)
    return ArmReach(centre, radius, farthest)


def _farthest(robot: Robot, data: mujoco.MjData, arm: int, side: str, centre: np.ndarray) -> np.ndarray:
    model = robot.model
    joints = np.atleast_1d(robot.index((*robot.arm_joints[side], *robot.extra_joints)))
    lower = np.maximum(robot.lower[joints], -np.pi)  # an unlimited joint: one turn
    upper = np.minimum(robot.upper[joints], np.pi)
    site = robot.site_id(side, "tcp")
    jac = np.zeros((3, model.nv))

    def negative_square(x: np.ndarray) -> tuple[float, np.ndarray]:
        data.qpos[:] = robot.home
        data.qpos[joints] = x
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jac, None, site)
        offset = data.site_xpos[site] - centre
        return -float(offset @ offset), -2.0 * (offset @ jac[:, joints])

    rng = np.random.default_rng(SEED + arm)
    samples = rng.uniform(lower, upper, (SAMPLES, len(joints)))
    far = np.array([-negative_square(x)[0] for x in samples])
    starts = [np.clip(robot.home[joints], lower, upper), *samples[np.argsort(far)[-STARTS:]]]
    found = [
        minimize(negative_square, x, jac=True, method="L-BFGS-B", bounds=list(zip(lower, upper)))
        for x in starts
    ]
    best = min(found, key=lambda r: r.fun)
    q = robot.home.copy()
    q[joints] = np.clip(best.x, lower, upper) if -best.fun >= far.max() else samples[np.argmax(far)]
    return q
