"""Joint-space criteria: HJA^r (mapped human joint angles), HJL (human joint limits), JLA (robot limits);
and the trunk posture term the solvers add (:class:`TrunkUpright`, not one of the paper's criteria).

All three are linear in q: residual ``e = S (q - target) / scale`` with selection rows ``S``, and the
metric is the mean of squares.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hlik.criteria.angles import joint_difference
from hlik.criteria.base import Criterion, Term
from hlik.human.kinematics import human_model
from hlik.robot.model import Robot


@dataclass(frozen=True, eq=False)
class JointBand:
    """A target and half-width per selected joint: ``e = (q[idx] - centre) / half``.

    Attributes:
        idx: (k,) robot joint indices.
        centre: (k,) or (F, k) targets, rad.
        half: (k,) half-widths, rad (1 for plain differences).
        unlimited: (k,) joints compared by angular distance.
    """

    idx: np.ndarray
    centre: np.ndarray
    half: np.ndarray
    unlimited: np.ndarray

    def residual(self, q: np.ndarray) -> np.ndarray:
        """(F, k) residual for configurations (F, n)."""
        return joint_difference(q[..., self.idx], self.centre, self.unlimited) / self.half

    def jacobian(self, n: int) -> np.ndarray:
        """(k, n) constant Jacobian of :meth:`residual`."""
        jac = np.zeros((len(self.idx), n))
        jac[np.arange(len(self.idx)), self.idx] = 1.0 / self.half
        return jac


def mapped_pose(robot: Robot, q_map: np.ndarray) -> JointBand:
    """HJA^r: the mapped human pose (..., n) of the arm joints as targets."""
    idx = np.asarray(robot.index([m.joint for m in robot.mapping.joints]))
    return JointBand(idx, q_map[..., idx], np.ones(len(idx)), _unlimited(robot, idx))


def human_limits(robot: Robot) -> JointBand:
    """HJL: the MMM model's arm limits mapped into robot joints through ``q = a q_mmm + b``.

    A dynamic offset is frozen at the centre of its source joint's range (the paper does the same
    for ARMAR-6 to get fixed limits). Held joints (a = 0) have no human range and are left out.
    """
    human = human_model(1.0)
    maps = [m for m in robot.mapping.joints if m.mmm is not None and m.a != 0.0]
    lo, hi = [], []
    for m in maps:
        low, high = human.joint(m.mmm).range
        shift = m.b
        if m.offset is not None:
            src = human.joint(m.offset.mmm).range
            shift += float(m.offset(np.array([(src[0] + src[1]) / 2.0]))[0])
        a, b = sorted((m.a * low + shift, m.a * high + shift))
        lo.append(a)
        hi.append(b)
    low_arr, high_arr = np.array(lo), np.array(hi)
    idx = np.asarray(robot.index([m.joint for m in maps]))
    return JointBand(idx, (low_arr + high_arr) / 2.0, (high_arr - low_arr) / 2.0, _unlimited(robot, idx))


def robot_limits(robot: Robot) -> JointBand:
    """fJLA: the robot's own limits; limitless joints are left out."""
    idx = np.flatnonzero(np.isfinite(robot.lower) & np.isfinite(robot.upper))
    lo, hi = robot.lower[idx], robot.upper[idx]
    return JointBand(idx, (lo + hi) / 2.0, (hi - lo) / 2.0, np.zeros(len(idx), bool))


def _unlimited(robot: Robot, idx: np.ndarray) -> np.ndarray:
    return ~np.isfinite(robot.lower[idx])


class HJL(Criterion):
    """HJL: distance to the centre of the human joint limits, in the robot's joint space (e (F, k))."""

    name, gamma, x0, weight = "HJL", 1.0, 0.48, 1 / 15
    needs_sample, sites = False, ()

    def __init__(self, robot: Robot, learned: object = None):
        self.band = human_limits(robot)
        self.constant_jacobian = self.band.jacobian(robot.dof)

    def residual(self, state, sample):
        return self.band.residual(state.q)


class HJA_r(Criterion):  # noqa: N801 - the paper's name
    """HJA^r: the mapped human pose of the sample as the target of the mapped joints (e (F, k))."""

    name, gamma, x0, weight = "HJA_r", 2.0, 0.35, 1 / 30
    sites = ()

    def __init__(self, robot: Robot, learned: object = None):
        self.band = mapped_pose(robot, robot.home)  # targets come from each sample
        self.constant_jacobian = self.band.jacobian(robot.dof)

    def residual(self, state, sample):
        idx = self.band.idx
        return joint_difference(state.q[:, idx], sample.q_map[:, idx], self.band.unlimited) / self.band.half


class fJLA(Criterion):  # noqa: N801
    """fJLA: distance to the centre of the robot's own joint limits (functional, paper Sec. V)."""

    name, functional = "fJLA", True
    needs_sample, sites = False, ()

    def __init__(self, robot: Robot, learned: object = None):
        self.band = robot_limits(robot)
        self.constant_jacobian = self.band.jacobian(robot.dof)

    def residual(self, state, sample):
        return self.band.residual(state.q)


class TrunkUpright(Term):
    """The robot's extra (trunk) joints toward their home angles, e (F, k) in rad: the trunk held
    upright (ARMAR-III's hip), a posture term beside the criteria, not one of them. No rows (k = 0)
    for a robot without extra joints. On ARMAR-III with SYN + HJA^r (four takes, 3 s) at 1 per rad
    the trunk leans 8.7 deg off the subject's instead of 10.6 (m_hl 0.504 -> 0.514, fPOS 0.76 ->
    1.00 cm); at 3, 4.4 deg, but 2.3 cm."""

    name = "trunk"
    sites = ()

    def __init__(self, robot: Robot):
        self.idx = np.array([robot.joint_names.index(j) for j in robot.extra_joints], dtype=int)
        self.home = robot.home[self.idx]
        self.unlimited = np.isinf(robot.lower[self.idx])
        jac = np.zeros((len(self.idx), robot.dof))
        jac[np.arange(len(self.idx)), self.idx] = 1.0
        self.constant_jacobian = jac

    def residual(self, state, sample):
        return joint_difference(state.q[:, self.idx], self.home, self.unlimited)
