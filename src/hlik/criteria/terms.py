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
from hlik.criteria.learned import Learned
from hlik.criteria.smoothness import ACCELERATION, JERK, VELOCITY
from hlik.robot.model import Robot
from hlik.robot.state import RobotState, arm_lengths


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
    """A residual e(q) with its Jacobian, and the scalar cost h(e) the metric of the same name uses.

    ``cost`` weighs the residual in the QP (scalar or per row). :meth:`metric` maps e to h (a mean of
    squares unless a subclass says otherwise); :meth:`gradient` chains it with the Jacobian, which is
    what the null-space (JV) and SLSQP solvers need.
    """

    name = "term"
    cost: float | np.ndarray = 1.0
    needs_frame = True  # False: the residual depends on the configuration alone
    sites: tuple[int, ...] = (0, 1, 2, 3)  # site Jacobians it reads (indices into SITES)
    constant_jacobian: np.ndarray | None = None  # set when J depends on neither q nor the frame

    def __call__(self, state: RobotState, frame: Frame) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def metric(self, e: np.ndarray) -> tuple[float, np.ndarray]:
        """The cost h of residual ``e`` (m,) and dh/de (m,)."""
        return float(np.mean(e * e)), 2.0 * e / max(len(e), 1)

    def gradient(self, state: RobotState, frame: Frame) -> tuple[float, np.ndarray]:
        """The cost h at ``state`` and its gradient dh/dq (n,)."""
        e, jac = self(state, frame)
        h, dh_de = self.metric(e)
        return h, dh_de @ jac


def block_norms(e: np.ndarray, blocks: int) -> tuple[float, np.ndarray]:
    """Mean of the norms of ``blocks`` equal slices of ``e``, and its gradient (zero at zero)."""
    parts = e.reshape(blocks, -1)
    norms = np.linalg.norm(parts, axis=1)
    grad = parts / np.maximum(norms, 1e-12)[:, None] / blocks
    return float(norms.mean()), grad.ravel()


class Position(Term):
    """Both TCPs to their target positions (m); h is fPOS, the mean distance."""

    name = "position"
    sites = (3,)

    def __call__(self, state, frame):
        return (state.tcp[0] - frame.target_pos).ravel(), state.jac[0, :, 3, :3].reshape(6, -1)

    def metric(self, e):
        return block_norms(e, 2)


class Orientation(Term):
    """Both TCPs to their target orientations: rotation vectors of R R*^T (rad); h is fORI."""

    name = "orientation"
    sites = (3,)

    def __call__(self, state, frame):
        err = rotation_vector(state.tcp_rot[0] @ np.swapaxes(frame.target_rot, -1, -2))
        # Jacobian of the world-frame rotation vector: the angular Jacobian (first order)
        return err.ravel(), state.jac[0, :, 3, 3:].reshape(6, -1)

    def metric(self, e):
        return block_norms(e, 2)


def relative_target(frame: Frame) -> tuple[np.ndarray, np.ndarray]:
    """The targets' right hand seen from their left hand: position (3,) and rotation (3, 3)."""
    rot_l = frame.target_rot[0]
    return rot_l.T @ (frame.target_pos[1] - frame.target_pos[0]), rot_l.T @ frame.target_rot[1]


class RelativePosition(Term):
    """Paper Eq. 3: t_left + R_left t_rel - t_right (m); h is fPOS^off."""

    name = "relative_position"
    sites = (3,)

    def __call__(self, state, frame):
        rel_pos, _ = relative_target(frame)
        offset = state.tcp_rot[0, 0] @ rel_pos
        e = state.tcp[0, 0] + offset - state.tcp[0, 1]
        jac = state.jac[0, :, 3]  # (2, 6, n)
        # d(R_l t_rel) = omega_l x (R_l t_rel) = -[R_l t_rel]x omega_l
        return e, jac[0, :3] - _skew(offset) @ jac[0, 3:] - jac[1, :3]

    def metric(self, e):
        return block_norms(e, 1)


class RelativeOrientation(Term):
    """Paper Eq. 4: rotation vector of (R_left R_rel) R_right^T (rad); h is fORI^off."""

    name = "relative_orientation"
    sites = (3,)

    def __call__(self, state, frame):
        _, rel_rot = relative_target(frame)
        e = rotation_vector(state.tcp_rot[0, 0] @ rel_rot @ state.tcp_rot[0, 1].T)
        jac = state.jac[0, :, 3, 3:]
        return e, jac[0] - jac[1]

    def metric(self, e):
        return block_norms(e, 1)


def target_terms(scenario: str) -> tuple[Term, Term]:
    """The position and orientation terms ``scenario`` tracks: the TCP poses (``pose``) or the
    relative pose of the hands (``relative``, paper Eqs. 3-4)."""
    if scenario == "pose":
        return Position(), Orientation()
    if scenario == "relative":
        return RelativePosition(), RelativeOrientation()
    raise ValueError(f"scenario must be 'pose' or 'relative', got {scenario!r}")


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rotation_vector(rot: np.ndarray) -> np.ndarray:
    """(..., 3) axis * angle of rotations (..., 3, 3); closed form, scipy only near pi."""
    axis = rot[..., _ROWS, _COLS] - rot[..., _COLS, _ROWS]  # 2 sin(angle) * unit axis
    sin2 = np.sqrt(np.sum(axis * axis, axis=-1))
    angle = np.arctan2(sin2, rot[..., 0, 0] + rot[..., 1, 1] + rot[..., 2, 2] - 1.0)
    if np.max(angle) > np.pi - 1e-3:
        return Rotation.from_matrix(rot).as_rotvec()
    return axis * np.where(sin2 > 1e-12, angle / np.maximum(sin2, 1e-300), 0.5)[..., None]


_ROWS, _COLS = (2, 0, 1), (1, 2, 0)


class Joints(Term):
    """A linear joint-space criterion (HJL, or a fixed band)."""

    needs_frame = False
    sites = ()

    def __init__(self, name: str, band: JointBand, n: int):
        self.name, self.band, self.constant_jacobian = name, band, band.jacobian(n)

    def __call__(self, state, frame):
        return self.band.residual(state.q)[0], self.constant_jacobian


class MappedPose(Term):
    """HJA^r: toward the mapped human pose of the frame."""

    name = "HJA_r"
    sites = ()

    def __init__(self, robot: Robot):
        self.band = mapped_pose(robot, robot.home)  # targets replaced per frame
        self.constant_jacobian = self.band.jacobian(robot.dof)

    def __call__(self, state, frame):
        band = JointBand(self.band.idx, frame.q_map[self.band.idx], self.band.half, self.band.unlimited)
        return band.residual(state.q)[0], self.constant_jacobian


class Synergy(Term):
    """SYN (reconstruction error) or SYN^r (distance to the mapped human in synergy space)."""

    sites = ()

    def __init__(self, learned: Learned, n: int, reference: bool):
        self.name = "SYN_r" if reference else "SYN"
        self.syn, self.reference, self.needs_frame = learned.synergies, reference, reference
        self.constant_jacobian = self.syn.syn_r_jacobian(n) if reference else self.syn.syn_jacobian(n)

    def __call__(self, state, frame):
        if self.reference:
            return self.syn.syn_r_residual(state.q, frame.q_map[None])[0], self.constant_jacobian
        return self.syn.syn_residual(state.q)[0], self.constant_jacobian


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
        self.name, self.stencil, self.constant_jacobian = name, stencil, np.eye(n)

    def __call__(self, state, frame):
        return state.q[0] + self.stencil[1:] @ frame.history, self.constant_jacobian

    def metric(self, e):
        return block_norms(e, 1)  # RelaxedIK's ||q - extrapolation||


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

    def metric(self, e):
        return float(np.mean(np.abs(e))), np.sign(e) / len(e)  # eea_cost


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

    def metric(self, e):
        return block_norms(e, 2) if not self.joints else super().metric(e)  # soa_x_cost per arm


class Manipulability(Term):
    """MAN^r: the robot's scaled manipulability toward the normalised human's (Mandel log residual)."""

    name = "MAN_r"
    sites = (4,)

    def __init__(self, robot: Robot, learned: Learned):
        self.robot, self.scale = robot, learned.scale

    def __call__(self, state, frame):
        target = frame.manip[None]
        e = manipulability.man_residual(self.robot, state, target, self.scale)[0].ravel()
        jac = manipulability.man_jacobian(self.robot, state, target, self.scale)[0]
        return e, jac.reshape(-1, jac.shape[-1])

    def metric(self, e):
        return block_norms(e, 2)  # man_cost: mean over arms of the Mandel residual norm


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
