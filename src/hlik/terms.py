"""Least-squares terms of the per-frame QP: each criterion as a residual e(q) and Jacobian J(q).

A :class:`Term` reads one :class:`~hlik.criteria.state.RobotState` (one configuration, with site
Jacobians) and the frame's :class:`Frame` context, and returns ``(e, J)``; the same criterion code
computes the metrics (:mod:`hlik.metrics`). :mod:`hlik.tasks` wraps terms as mink tasks;
:mod:`hlik.solvers.qp` stacks them into one QP without per-task overhead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from hlik.criteria import eea, manipulability, soechting
from hlik.criteria.joints import JointBand, human_limits, mapped_pose
from hlik.criteria.smoothness import ACCELERATION, JERK, VELOCITY
from hlik.criteria.state import RobotState, arm_lengths
from hlik.learned import Learned
from hlik.robot import Robot


@dataclass(frozen=True, eq=False)
class Frame:
    """What the terms need to know about one frame besides the robot's configuration.

    Attributes:
        target_pos: (2, 3) TCP target positions, robot base frame.
        target_rot: (2, 3, 3) TCP target orientations.
        q_map: (n,) the human pose mapped to the robot (unclipped; non-arm joints at home).
        psi_mmm: (2,) the human's elbow elevation angles.
        manip: (2, 3, 3) the normalised human's manipulability, robot base frame.
        history: (3, n) the solutions of the three previous frames, newest first.
        dt: Frame period, s.
    """

    target_pos: np.ndarray
    target_rot: np.ndarray
    q_map: np.ndarray
    psi_mmm: np.ndarray
    manip: np.ndarray
    history: np.ndarray
    dt: float


class Term:
    """A residual with its Jacobian; ``cost`` weighs it in the QP (scalar or per row)."""

    name = "term"
    cost: float | np.ndarray = 1.0
    needs_frame = True  # False: the residual depends on the configuration alone
    sites: tuple[int, ...] = (0, 1, 2, 3)  # site Jacobians it reads (indices into SITES)

    def __call__(self, state: RobotState, frame: Frame) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError


class Pose(Term):
    """Both TCPs to their targets: position error (m) and rotation vector of R R*^T (rad)."""

    name = "pose"
    sites = (3,)

    def __init__(self, position_cost: float = 1.0, orientation_cost: float = 0.2):
        self.cost = np.tile(np.r_[np.full(3, position_cost), np.full(3, orientation_cost)], 2)

    def __call__(self, state, frame):
        pos_err = state.tcp[0] - frame.target_pos
        rot_err = rotation_vector(state.tcp_rot[0] @ np.swapaxes(frame.target_rot, -1, -2))
        e = np.concatenate([np.r_[pos_err[i], rot_err[i]] for i in range(2)])
        # Jacobian of the world-frame rotation vector: the angular Jacobian (first order).
        jac = state.jac[0, :, 3].reshape(12, -1)
        return e, jac


def rotation_vector(rot: np.ndarray) -> np.ndarray:
    """(..., 3) axis * angle of rotations (..., 3, 3); closed form, scipy only near pi."""
    axis = np.stack(
        [rot[..., 2, 1] - rot[..., 1, 2], rot[..., 0, 2] - rot[..., 2, 0], rot[..., 1, 0] - rot[..., 0, 1]],
        -1,
    )
    sin2 = np.linalg.norm(axis, axis=-1)  # 2 sin(angle)
    angle = np.arctan2(sin2, np.trace(rot, axis1=-2, axis2=-1) - 1.0)
    if np.any(angle > np.pi - 1e-3):
        return Rotation.from_matrix(rot).as_rotvec()
    scale = np.where(sin2 > 1e-12, angle / np.maximum(sin2, 1e-300), 0.5)
    return axis * scale[..., None]


class Joints(Term):
    """A linear joint-space criterion (HJL, or a fixed band)."""

    needs_frame = False
    sites = ()

    def __init__(self, name: str, band: JointBand, n: int):
        self.name, self.band, self._jac = name, band, band.jacobian(n)

    def __call__(self, state, frame):
        return self.band.residual(state.q)[0], self._jac


class MappedPose(Term):
    """HJA^r: toward the mapped human pose of the frame."""

    name = "HJA_r"
    sites = ()

    def __init__(self, robot: Robot):
        self.band = mapped_pose(robot, robot.home)  # targets replaced per frame
        self._jac = self.band.jacobian(robot.dof)

    def __call__(self, state, frame):
        band = JointBand(self.band.idx, frame.q_map[self.band.idx], self.band.half, self.band.unlimited)
        return band.residual(state.q)[0], self._jac


class Synergy(Term):
    """SYN (reconstruction error) or SYN^r (distance to the mapped human in synergy space)."""

    sites = ()

    def __init__(self, learned: Learned, n: int, reference: bool):
        self.name = "SYN_r" if reference else "SYN"
        self.syn, self.reference, self.needs_frame = learned.synergies, reference, reference
        self._jac = self.syn.syn_r_jacobian(n) if reference else self.syn.syn_jacobian(n)

    def __call__(self, state, frame):
        if self.reference:
            return self.syn.syn_r_residual(state.q, frame.q_map[None])[0], self._jac
        return self.syn.syn_residual(state.q)[0], self._jac


class Misalignment(Term):
    """MIS as a velocity penalty: the scaled joint velocity outside the first-order synergy span."""

    name = "MIS"
    sites = ()

    def __init__(self, learned: Learned, n: int):
        syn = learned.synergies
        proj = np.eye(len(syn.idx)) - syn.vel_basis.T @ syn.vel_basis
        self._map = np.zeros((len(syn.idx), n))
        self._map[:, syn.idx] = proj / syn.vel_scale

    def __call__(self, state, frame):
        return self._map @ (state.q[0] - frame.history[0]) / frame.dt, self._map / frame.dt


class Smooth(Term):
    """Velocity, acceleration or jerk: toward the extrapolation of the previous frames (RelaxedIK)."""

    sites = ()

    def __init__(self, name: str, stencil: np.ndarray, n: int):
        self.name, self.stencil, self._jac = name, stencil, np.eye(n)

    def __call__(self, state, frame):
        return state.q[0] + self.stencil[1:] @ frame.history, self._jac


class Elevation(Term):
    """EEA (toward Psi_human) or EEA^r (toward the nearer of Psi_human and Psi_MMM)."""

    def __init__(self, learned: Learned, reference: bool):
        self.name = "EEA_r" if reference else "EEA"
        self.swivel, self.reference, self.needs_frame = learned.swivel, reference, reference

    def __call__(self, state, frame):
        psi = eea.swivel_angle(state.shoulder, state.elbow, state.wrist)[0]
        target = self.swivel.predict(state.shoulder, state.tcp, state.tcp_rot)[0]
        if self.reference:
            target = eea.eea_r_target(psi, target, frame.psi_mmm)
        jac = eea.swivel_jacobian(state)[0] / np.pi
        e = eea.eea_residual(psi, target)
        return np.nan_to_num(e), np.where(np.isfinite(e)[:, None], jac, 0.0)


class Soechting(Term):
    """SOA_x (predicted elbow position) or SOA_q (predicted shoulder and elbow angles)."""

    def __init__(self, robot: Robot, joints: bool):
        self.name = "SOA_q" if joints else "SOA_x"
        self.robot, self.joints, self.needs_frame = robot, joints, False
        self.l_u, self.l_f = arm_lengths(robot)

    def __call__(self, state, frame):
        elbow, angles = soechting.predict_arm(state.shoulder, state.wrist, self.l_u, self.l_f)
        if self.joints:
            idx, targets = soechting.soa_q_targets(self.robot, angles)
            e = soechting.soa_q_residual(self.robot, state, idx, targets)[0]
            return e, soechting.soa_q_jacobian(state, idx)[0]
        e = soechting.soa_x_residual(state, elbow, self.l_u)[0].ravel()
        return e, soechting.soa_x_jacobian(state, self.l_u)[0].reshape(6, -1)


class Manipulability(Term):
    """MAN^r: the robot's scaled manipulability toward the normalised human's (Mandel log residual)."""

    name = "MAN_r"
    sites = (3,)

    def __init__(self, robot: Robot, learned: Learned):
        self.robot, self.scale = robot, learned.scale

    def __call__(self, state, frame):
        target = frame.manip[None]
        e = manipulability.man_residual(self.robot, state, target, self.scale)[0].ravel()
        jac = manipulability.man_jacobian(self.robot, state, target, self.scale)[0]
        return e, jac.reshape(-1, jac.shape[-1])


def criterion_term(name: str, robot: Robot, learned: Learned) -> Term:
    """The QP term of a paper criterion (``EEA``, ``SOA_x``, ..., ``MAN_r``)."""
    n = robot.dof
    make = {
        "EEA": lambda: Elevation(learned, False),
        "EEA_r": lambda: Elevation(learned, True),
        "SOA_x": lambda: Soechting(robot, False),
        "SOA_q": lambda: Soechting(robot, True),
        "HJL": lambda: Joints("HJL", human_limits(robot), n),
        "HJA_r": lambda: MappedPose(robot),
        "SYN": lambda: Synergy(learned, n, False),
        "SYN_r": lambda: Synergy(learned, n, True),
        "MIS": lambda: Misalignment(learned, n),
        "MJE": lambda: Smooth("MJE", JERK, n),
        "MAN_r": lambda: Manipulability(robot, learned),
    }
    if name not in make:
        raise KeyError(f"unknown criterion {name!r}; choose from: {', '.join(make)}")
    return make[name]()


def smoothness_terms(n: int, velocity: float, acceleration: float, jerk: float) -> list[Term]:
    """RelaxedIK's minimum velocity, acceleration and jerk with the given costs, as one term.

    The three are least squares toward three extrapolations of the same history with the identity
    Jacobian, so their sum equals one term toward the cost-weighted mean extrapolation (up to a
    constant): n rows instead of 3 n.
    """
    costs = np.array([velocity, acceleration, jerk], dtype=float)
    if not np.any(costs > 0):
        return []
    w = costs**2 / np.sum(costs**2)
    term = Smooth("smoothness", w @ np.stack([VELOCITY, ACCELERATION, JERK]), n)
    term.cost = float(np.sqrt(np.sum(costs**2)))
    return [term]
