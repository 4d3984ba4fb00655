"""SOA_x and SOA_q: Soechting & Flanders' arm posture for "pointing in the dark" (formulas.md §2).

From the wrist position relative to the shoulder, a linear model in shoulder-centred spherical
coordinates predicts the upper-arm and forearm elevation and yaw (θ, η, β, α); these give the
predicted elbow position and the MMM shoulder and elbow angles (s_x, s_y, e_x).

Frames: positions are in the robot base frame (x right, y forward, z up). The model works in the
arm frame of formulas.md §0 (x towards the arm's side), i.e. the left arm is mirrored (x -> -x).
The MMM angles come from the upper-arm and forearm directions in the body frame (not mirrored),
where ``s_x = π - atan2(u_y, u_z)``, ``s_y = -asin(u_x)`` and ``e_x = ∠(u, f)`` are exactly the MMM
joints LSx/RSx, LSy/RSy and LEx/REx of a pose with S_z = 0 (MMM's chain is S_x, S_z, S_y; abduction
is positive S_y on the left and negative on the right). Decision: s_x is wrapped to [-π/2, 3π/2),
which contains MMM's S_x range, so a slightly backward upper arm gives a small negative s_x.

In the QP the prediction is held fixed within a step (formulas.md §9): the residual Jacobians are
the elbow position Jacobian (SOA_x) and selection rows (SOA_q). SLSQP and JV take the exact
gradient (:meth:`SOA_x.gradient`): the prediction's derivative with respect to the wrist offset,
central differences of the closed-form model in those 3 coordinates (no kinematics), chained
through the shoulder and wrist Jacobians.
"""

from __future__ import annotations

import numpy as np

from hlik.criteria.angles import joint_difference, wrap
from hlik.criteria.base import Criterion, block_norm_gradient
from hlik.robot.model import Robot
from hlik.robot.state import RobotState, arm_lengths

MMM_ARM_LENGTH = 0.6  # m, upper arm + forearm of the MMM model scaled to 1.8 m
_MIRROR = np.array([[-1.0, 1.0, 1.0], [1.0, 1.0, 1.0]])  # per arm (left, right): x -> -x on the left
_PREFIX = ("L", "R")
ANGLE_JOINTS = ("Sx", "Sy", "Ex")  # order of the predicted angles


def dark_pointing(r_cm: np.ndarray, chi_deg: np.ndarray, psi_deg: np.ndarray) -> np.ndarray:
    """(θ, η, β, α) (..., 4) in degrees: Soechting & Flanders' pointing-in-the-dark regression.

    θ: upper-arm elevation from the downward vertical; η: upper-arm yaw from anterior, positive
    lateral; β: forearm elevation from the upward vertical; α: forearm yaw.
    """
    return np.stack(
        [
            -4.0 + 1.10 * r_cm + 0.90 * psi_deg,
            13.2 + 0.86 * chi_deg + 0.11 * psi_deg,
            39.4 + 0.54 * r_cm - 1.06 * psi_deg,
            -10.0 + 1.08 * chi_deg - 0.35 * psi_deg,
        ],
        axis=-1,
    )


def mmm_angles(u: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(s_x, s_y, e_x) (..., 3) from unit upper-arm ``u`` and forearm ``f`` vectors (..., 3), body frame."""
    s_x = (np.pi - np.arctan2(u[..., 1], u[..., 2]) + np.pi / 2) % (2 * np.pi) - np.pi / 2
    s_y = -np.arcsin(np.clip(u[..., 0], -1.0, 1.0))
    e_x = np.arccos(np.clip(np.sum(u * f, axis=-1), -1.0, 1.0))
    return np.stack([s_x, s_y, e_x], axis=-1)


def predict_arm(
    shoulder: np.ndarray, wrist: np.ndarray, l_u: np.ndarray, l_f: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Soechting's predicted elbow and MMM angles for wrist targets.

    Args:
        shoulder, wrist: (..., 2, 3) positions in the base frame, arm 0 = left.
        l_u, l_f: (2,) the robot's upper-arm and forearm lengths, metres; the wrist distance is
            scaled by 0.6 / (l_u + l_f) to the MMM arm (paper Sec. IV).

    Returns:
        elbow_pred (..., 2, 3) in the base frame (shoulder + l_u û), and (..., 2, 3) MMM angles
        (s_x, s_y, e_x) in rad.
    """
    l_u = np.asarray(l_u, float)
    l_f = np.asarray(l_f, float)
    d = (np.asarray(wrist, float) - np.asarray(shoulder, float)) * _MIRROR  # arm frame
    r_cm = 100.0 * MMM_ARM_LENGTH / (l_u + l_f) * np.sqrt(np.einsum("...i,...i->...", d, d))
    chi = np.degrees(np.arctan2(d[..., 0], d[..., 1]))
    psi = np.degrees(np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])))
    angles = np.radians(dark_pointing(r_cm, chi, psi))
    theta, eta, beta, alpha = angles[..., 0], angles[..., 1], angles[..., 2], angles[..., 3]
    u = np.stack([np.sin(theta) * np.sin(eta), np.sin(theta) * np.cos(eta), -np.cos(theta)], -1)
    f = np.stack([np.sin(beta) * np.sin(alpha), np.sin(beta) * np.cos(alpha), np.cos(beta)], -1)
    u = u * _MIRROR  # back to the body / base frame
    f = f * _MIRROR
    elbow = np.asarray(shoulder, float) + l_u[:, None] * u
    return elbow, mmm_angles(u, f)


_WRIST_STEPS = np.concatenate([np.zeros((1, 3)), np.eye(3), -np.eye(3)])  # (7, 3): none, +, -


def prediction_derivatives(
    shoulder: np.ndarray, wrist: np.ndarray, l_u: np.ndarray, l_f: np.ndarray, eps: float = 1e-6
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`predict_arm`'s elbow_pred and angles (each (..., 2, 3)), and d elbow_pred / d wrist
    and d angles / d wrist (each (..., 2, 3, 3): output, wrist coordinate), the shoulder held
    (``d / d shoulder`` is ``I - `` the first, ``-`` the second).

    Central differences of :func:`predict_arm`, in one vectorised call with the prediction itself;
    the angles' differences are wrapped, so s_x's cut at ±π/2 does not show.
    """
    step = eps * _WRIST_STEPS.reshape(7, *([1] * (np.ndim(wrist) - 1)), 3)
    moved = np.asarray(wrist, float)[None] + step
    elbow, angles = predict_arm(np.broadcast_to(shoulder, moved.shape), moved, l_u, l_f)
    d_elbow = (elbow[1:4] - elbow[4:]) / (2 * eps)  # (3 coordinates, ..., 2, 3 outputs)
    d_angles = wrap(angles[1:4] - angles[4:]) / (2 * eps)
    return elbow[0], angles[0], np.moveaxis(d_elbow, 0, -1), np.moveaxis(d_angles, 0, -1)


def _relative_jacobian(state: RobotState, d_wrist: np.ndarray) -> np.ndarray:
    """(F, 2, m, n) d/dq of a function of (shoulder, wrist) that depends on wrist - shoulder only,
    from its derivative ``d_wrist`` (F, 2, m, 3)."""
    if state.jac is None:
        raise ValueError("needs a RobotState with Jacobians (jacobians=True)")
    rel = state.jac[:, :, 2, :3, :] - state.jac[:, :, 0, :3, :]  # (F, 2, 3, n)
    return d_wrist @ rel


# --- SOA_x -----------------------------------------------------------------------------------


def soa_x_residual(state: RobotState, elbow_pred: np.ndarray, l_u: np.ndarray) -> np.ndarray:
    """(F, 2, 3) (elbow - predicted elbow) / l_u, dimensionless."""
    return (state.elbow - elbow_pred) / np.asarray(l_u, float)[:, None]


def soa_x_jacobian(state: RobotState, l_u: np.ndarray) -> np.ndarray:
    """(F, 2, 3, n) d residual / dq with the prediction held fixed: elbow Jacobian / l_u."""
    if state.jac is None:
        raise ValueError("soa_x_jacobian needs a RobotState with Jacobians (jacobians=True)")
    return state.jac[:, :, 1, :3, :] / np.asarray(l_u, float)[:, None, None]


def soa_x_cost(residual: np.ndarray) -> np.ndarray:
    """h_SOAx (F,): the mean over both arms of the residual's norm."""
    return np.mean(np.linalg.norm(residual, axis=-1), axis=-1)


# --- SOA_q -----------------------------------------------------------------------------------


def soa_q_targets(robot: Robot, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Robot joint targets from predicted MMM angles, through the robot's Table I mapping.

    Every mapped joint that follows a side's S_x, S_y or E_x (a != 0) gets ``a angle + b`` plus its
    dynamic offset, evaluated at the predicted angle when its source is one of these three joints
    and at 0 otherwise (the prediction says nothing about the other MMM joints).

    Args:
        angles: (F, 2, 3) predicted (s_x, s_y, e_x), arm 0 = left.

    Returns:
        idx (k,) robot joint indices and targets (F, k) in rad.
    """
    angles = np.asarray(angles, float)
    source = {
        f"{p}{j}_joint": angles[:, i, c] for i, p in enumerate(_PREFIX) for c, j in enumerate(ANGLE_JOINTS)
    }
    idx, targets = [], []
    for m in robot.mapping.joints:
        if m.mmm not in source or m.a == 0.0:
            continue
        q = m.a * source[m.mmm] + m.b
        if m.offset is not None:
            q = q + m.offset(source.get(m.offset.mmm, np.zeros(len(angles))))
        idx.append(robot.index(m.joint))
        targets.append(q)
    return np.array(idx, dtype=int), np.stack(targets, axis=-1).reshape(len(angles), len(idx))


def soa_q_residual(robot: Robot, state: RobotState, idx: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(F, k) q[idx] - targets, as angular distance for unlimited joints."""
    return joint_difference(state.q[:, idx], targets, np.isinf(robot.lower[idx]))


def soa_q_jacobian(state: RobotState, idx: np.ndarray) -> np.ndarray:
    """(F, k, n) selection rows (the prediction held fixed)."""
    sel = np.zeros((len(state.q), len(idx), state.q.shape[1]))
    sel[:, np.arange(len(idx)), idx] = 1.0
    return sel


def soa_q_cost(residual: np.ndarray) -> np.ndarray:
    """h_SOAq (F,): the mean of the squared residuals (rad²)."""
    return np.mean(np.square(residual), axis=-1)


# --- the criteria ----------------------------------------------------------------------------


class SOA_x(Criterion):  # noqa: N801 - the paper's name
    """SOA_x: elbow to its Soechting prediction from the wrist, per upper-arm length (e (F, 6))."""

    name, gamma, x0, weight = "SOA_x", 10.0, 0.2, 1 / 20
    exact_jacobian = False  # jacobian() holds the prediction fixed; exact() does not
    parts, part_form = 2, "norm"
    needs_sample = False

    def __init__(self, robot: Robot, learned: object = None):
        self.l_u, self.l_f = arm_lengths(robot)

    def residual(self, state, sample):
        elbow, _ = predict_arm(state.shoulder, state.wrist, self.l_u, self.l_f)
        return soa_x_residual(state, elbow, self.l_u).reshape(len(state.q), 6)

    def jacobian(self, state, sample):
        return soa_x_jacobian(state, self.l_u).reshape(len(state.q), 6, -1)

    def cost(self, e):
        return soa_x_cost(e.reshape(len(e), 2, 3))

    def cost_gradient(self, e):
        return block_norm_gradient(e, 2)

    def exact(self, state, sample):
        """The residual (6,) and d residual / dq (6, n) with the prediction moving with the wrist and
        shoulder."""
        elbow, _, d_elbow, _ = prediction_derivatives(state.shoulder, state.wrist, self.l_u, self.l_f)
        assert state.jac is not None
        pred = state.jac[:, :, 0, :3, :] + _relative_jacobian(state, d_elbow)  # elbow_pred = shoulder + ...
        jac = (state.jac[:, :, 1, :3, :] - pred) / np.asarray(self.l_u, float)[:, None, None]
        e = soa_x_residual(state, elbow, self.l_u).reshape(len(state.q), 6)
        return e[0], jac.reshape(len(state.q), 6, -1)[0]


class SOA_q(Criterion):  # noqa: N801
    """SOA_q: the mapped joints to the predicted shoulder and elbow angles (e (F, k), rad)."""

    name, gamma, x0, weight = "SOA_q", 2.0, 0.34, 1 / 20
    exact_jacobian = False  # jacobian() holds the prediction fixed; exact() does not
    needs_sample = False

    def __init__(self, robot: Robot, learned: object = None):
        self.robot = robot
        self.l_u, self.l_f = arm_lengths(robot)

    def residual(self, state, sample):
        _, angles = predict_arm(state.shoulder, state.wrist, self.l_u, self.l_f)
        idx, targets = soa_q_targets(self.robot, angles)
        return soa_q_residual(self.robot, state, idx, targets)

    def jacobian(self, state, sample):
        _, angles = predict_arm(state.shoulder[:1], state.wrist[:1], self.l_u, self.l_f)
        return soa_q_jacobian(state, soa_q_targets(self.robot, angles)[0])

    def exact(self, state, sample, eps: float = 1e-6):
        """The residual (k,) and d residual / dq (k, n) with the predicted targets moving with the
        wrist and shoulder."""
        _, angles, _, d_angles = prediction_derivatives(state.shoulder, state.wrist, self.l_u, self.l_f)
        f = len(angles)
        # d targets / d angles (F, k, 2, 3): the mapping (and its dynamic offsets), central differences
        step = eps * np.concatenate([np.zeros((1, 6)), np.eye(6), -np.eye(6)]).reshape(13, 1, 2, 3)
        idx, targets = soa_q_targets(self.robot, (angles[None] + step).reshape(-1, 2, 3))
        targets = targets.reshape(13, f, len(idx))  # the prediction, then +eps and -eps per angle
        d_targets = np.moveaxis((targets[1:7] - targets[7:]) / (2 * eps), 0, -1).reshape(f, len(idx), 2, 3)
        d_angles_dq = _relative_jacobian(state, d_angles)  # (F, 2, 3, n)
        e = soa_q_residual(self.robot, state, idx, targets[0])
        return e[0], (soa_q_jacobian(state, idx) - np.einsum("fkac,facn->fkn", d_targets, d_angles_dq))[0]
