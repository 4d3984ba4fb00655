"""MAN^r: tracking the velocity manipulability of the normalised MMM model (paper Sec. III-C).

The robot's 3x3 position manipulability ``M_R = J J^T`` of each arm's manipulability frame (the
robot's ``[manipulability]`` site, where the hand is mounted) over its manipulability chain (the arm,
plus ARMAR-III's hip), scaled by ``1 / lambda_R``, is
compared with the human's ``M_H`` by the affine-invariant distance (Jaquier et al., IJRR 2021, Eq. 4)

    d(A, B) = ||log(A^{-1/2} B A^{-1/2})||_F.

The residual ``mandel(log(T^{-1/2} (M_R / lambda) T^{-1/2}))`` has norm ``d(M_R / lambda, T)`` and an
exact Jacobian (Bruyninckx–De Schutter Jacobian derivative + Daleckii–Krein formula of the log).
Matrices are in metres squared per radian squared; Jacobians in the robot base frame.
"""

from __future__ import annotations

import mujoco
import numpy as np

from hlik.criteria.base import Criterion, block_norm_gradient
from hlik.human.kinematics import human_model
from hlik.human.manipulability import human_tcp_jacobians, velocity_manipulability
from hlik.human.motion import ARM_JOINTS
from hlik.robot.model import SIDES, SITES, Robot
from hlik.robot.state import RobotState
from hlik.util.spatial import cross

SITE = SITES.index("manipulability")

_SQRT2 = np.sqrt(2.0)
_ROWS, _COLS = np.array([0, 1, 2, 0, 1, 0]), np.array([0, 1, 2, 1, 2, 2])
_WEIGHTS = np.array([1.0, 1.0, 1.0, _SQRT2, _SQRT2, _SQRT2])


# Symmetric positive definite matrices.


def mandel(m: np.ndarray) -> np.ndarray:
    """(..., 6) Mandel vector ``[m11, m22, m33, √2 m12, √2 m23, √2 m13]`` of symmetric (..., 3, 3).

    Norm-preserving: ``||mandel(m)|| == ||m||_F``.
    """
    return _WEIGHTS * m[..., _ROWS, _COLS]


def spd_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(...) affine-invariant distance between SPD matrices a, b (..., d, d).

    ``sqrt(sum_i log^2 mu_i)`` with mu the eigenvalues of ``a^{-1} b`` (those of the symmetric
    ``L^{-1} b L^{-T}``, ``a = L L^T``).
    """
    chol = np.linalg.cholesky(a)
    x = np.linalg.solve(chol, np.linalg.solve(chol, b).swapaxes(-1, -2))  # L^-1 b L^-T (b symmetric)
    mu = np.linalg.eigvalsh(0.5 * (x + x.swapaxes(-1, -2)))
    return np.sqrt(np.sum(np.log(mu) ** 2, axis=-1))


def _spd_power(m: np.ndarray, p: float) -> np.ndarray:
    """(..., d, d) ``m^p`` of SPD matrices m (..., d, d)."""
    w, v = np.linalg.eigh(m)
    return (v * w[..., None, :] ** p) @ v.swapaxes(-1, -2)


def _spd_log(x: np.ndarray) -> np.ndarray:
    """(..., d, d) matrix logarithm of SPD matrices x (..., d, d)."""
    mu, v = np.linalg.eigh(x)
    return (v * np.log(mu)[..., None, :]) @ v.swapaxes(-1, -2)


def _log_divided_difference(mu: np.ndarray) -> np.ndarray:
    """(..., d, d) first divided differences ``(log mu_i - log mu_j) / (mu_i - mu_j)`` of (..., d).

    Written as ``log1p(x) / x / mu_j`` with ``x = mu_i / mu_j - 1``, exact for close eigenvalues;
    the limit ``1 / mu_j`` where they are equal.
    """
    mi, mj = mu[..., :, None], mu[..., None, :]
    x = (mi - mj) / mj
    safe = np.where(x == 0.0, 1.0, x)
    return np.where(x == 0.0, 1.0, np.log1p(safe) / safe) / mj


# Robot manipulability and its derivative.


def _arm_jacobian(robot: Robot, state: RobotState) -> np.ndarray:
    """(F, 2, 6, k) manipulability-frame Jacobians over each arm's k chain joints (proximal -> distal)."""
    if state.jac is None:
        raise ValueError("robot_state(..., jacobians=True) is required")
    cols = robot.manipulability_chain  # (2, k)
    jac = state.jac[:, :, SITE]  # (F, 2, 6, n)
    return np.stack([jac[:, i][..., cols[i]] for i in range(len(SIDES))], axis=1)


def arm_manipulability(robot: Robot, state: RobotState) -> np.ndarray:
    """(F, 2, 3, 3) velocity manipulability of each arm's frame over its chain, m²."""
    return velocity_manipulability(_arm_jacobian(robot, state)[..., :3, :])


def manipulability_derivative(robot: Robot, state: RobotState) -> np.ndarray:
    """(F, 2, n, 3, 3) ``dM/dq_k`` of :func:`arm_manipulability` for every robot joint k.

    Chain joints use the Bruyninckx–De Schutter derivative of the frame Jacobian's linear part: for
    chain columns i, j, ``dv_i/dq_j = w_j x v_i`` if j < i, else ``w_i x v_j``. A joint outside the
    chain that moves the frame is proximal to the whole chain, so ``dv_i/dq_k = w_k x v_i``; it is
    zero for joints that do not move the frame (the other arm).
    """
    arm = _arm_jacobian(robot, state)  # (F, 2, 6, k)
    v = np.swapaxes(arm[..., :3, :], -1, -2)  # (F, 2, k, 3) linear columns
    w = np.swapaxes(arm[..., 3:, :], -1, -2)  # (F, 2, k, 3) angular columns
    k = v.shape[-2]
    # dv[..., j, i, :] = d v_i / d q_j
    before = cross(w[..., :, None, :], v[..., None, :, :])  # w_j x v_i
    after = cross(w[..., None, :, :], v[..., :, None, :])  # w_i x v_j
    proximal = np.arange(k)[:, None] < np.arange(k)[None, :]  # j < i
    d_arm = np.where(proximal[..., None], before, after)  # (F, 2, k, k, 3)
    assert state.jac is not None  # checked by _arm_jacobian
    w_all = np.swapaxes(state.jac[:, :, SITE, 3:, :], -1, -2)  # (F, 2, n, 3)
    d_jac = cross(w_all[..., :, None, :], v[..., None, :, :])  # (F, 2, n, k, 3) non-chain rule
    for i, cols in enumerate(robot.manipulability_chain):
        d_jac[:, i, cols] = d_arm[:, i]
    d_jac = np.swapaxes(d_jac, -1, -2)  # (F, 2, n, 3, k)
    jac = np.swapaxes(v, -1, -2)[:, :, None]  # (F, 2, 1, 3, k)
    half = d_jac @ np.swapaxes(jac, -1, -2)
    return half + np.swapaxes(half, -1, -2)


# The MAN^r residual, its Jacobian and cost.


def _scaled(robot: Robot, state: RobotState, target: np.ndarray, lam: float):
    """``T^{-1/2}`` (F, 2, 3, 3) and ``X = T^{-1/2} (M_R / lam) T^{-1/2}`` (F, 2, 3, 3)."""
    t_inv_sqrt = _spd_power(np.asarray(target, dtype=float), -0.5)
    x = t_inv_sqrt @ (arm_manipulability(robot, state) / lam) @ t_inv_sqrt
    return t_inv_sqrt, 0.5 * (x + np.swapaxes(x, -1, -2))


def man_residual(robot: Robot, state: RobotState, target: np.ndarray, lam: float) -> np.ndarray:
    """(F, 2, 6) ``mandel(log(T^{-1/2} (M_R / lam) T^{-1/2}))`` per arm.

    Args:
        target: (F, 2, 3, 3) target (human) manipulabilities in the robot base frame, m².
        lam: Manipulability scale factor lambda_R of the robot (:func:`scale_factor`).

    Its norm is ``spd_distance(M_R / lam, target)``.
    """
    _, x = _scaled(robot, state, target, lam)
    return mandel(_spd_log(x))


def man_jacobian(robot: Robot, state: RobotState, target: np.ndarray, lam: float) -> np.ndarray:
    """(F, 2, 6, n) exact derivative of :func:`man_residual` with respect to q (target fixed).

    ``dlog X = V (D ∘ (V^T dX V)) V^T`` (Daleckii–Krein) with ``X = V diag(mu) V^T`` and D the
    divided differences of log at mu.
    """
    return man_residual_and_jacobian(robot, state, target, lam)[1]


def man_residual_and_jacobian(
    robot: Robot, state: RobotState, target: np.ndarray, lam: float
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`man_residual` (F, 2, 6) and :func:`man_jacobian` (F, 2, 6, n) from one eigen-
    decomposition of X."""
    t_inv_sqrt, x = _scaled(robot, state, target, lam)
    mu, v = np.linalg.eigh(x)  # (F, 2, 3), (F, 2, 3, 3)
    residual = mandel((v * np.log(mu)[..., None, :]) @ v.swapaxes(-1, -2))
    dm = manipulability_derivative(robot, state) / lam  # (F, 2, n, 3, 3)
    a = (v.swapaxes(-1, -2) @ t_inv_sqrt)[:, :, None]  # V^T T^{-1/2}, (F, 2, 1, 3, 3)
    inner = a @ dm @ a.swapaxes(-1, -2) * _log_divided_difference(mu)[:, :, None]
    vv = v[:, :, None]
    d_log = vv @ inner @ vv.swapaxes(-1, -2)  # (F, 2, n, 3, 3)
    return residual, np.swapaxes(mandel(d_log), -1, -2)


def man_cost(residual: np.ndarray) -> np.ndarray:
    """(F,) MAN^r cost: mean over both arms of ``||residual||`` (F, 2, 6)."""
    return np.linalg.norm(residual, axis=-1).mean(axis=-1)


# Human manipulability and the scale factor.


def _robot_max_det(robot: Robot, rng: np.random.Generator, n: int) -> float:
    """Largest ``det M_R`` over both arms at n configurations uniform within the joint limits."""
    lower = np.where(np.isinf(robot.lower), -np.pi, robot.lower)
    upper = np.where(np.isinf(robot.upper), np.pi, robot.upper)
    q = rng.uniform(lower, upper, size=(n, robot.dof))
    model, data = robot.model, mujoco.MjData(robot.model)
    sites = [robot.site_id(s, "manipulability") for s in SIDES]
    cols = robot.manipulability_chain
    jac_pos = np.empty((3, model.nv))
    best = 0.0
    for side_site, side_cols in zip(sites, cols):
        jac = np.empty((n, 3, len(side_cols)))
        for t, qt in enumerate(q):
            data.qpos[:] = qt
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            mujoco.mj_jacSite(model, data, jac_pos, None, side_site)
            jac[t] = jac_pos[:, side_cols]
        best = max(best, float(np.linalg.det(velocity_manipulability(jac)).max()))
    return best


def _human_max_det(rng: np.random.Generator, n: int) -> float:
    """Largest ``det M_H`` of the normalised MMM at n configurations of each arm within its ranges."""
    model = human_model(1.0)
    qpos = np.tile(model.qpos0, (n, 1))
    for side in SIDES:
        ids = [model.joint(j).id for j in ARM_JOINTS[side]]
        lo, hi = model.jnt_range[ids].T
        qpos[:, model.jnt_qposadr[ids]] = rng.uniform(lo, hi, size=(n, len(ids)))
    # The arms are independent chains, so one sample of both arms is one sample of each.
    return float(np.linalg.det(velocity_manipulability(human_tcp_jacobians(model, qpos))).max())


def scale_factor(robot: Robot, n: int = 20000, seed: int = 0) -> float:
    """Manipulability scale ``lambda_R = (max det M_R / max det M_H)^(1/3)`` (paper Sec. III-C).

    ``M_R`` is taken at the robot's manipulability frame over its chain, ``M_H`` at the MMM TCP over
    its 7 arm joints. Both maxima run over n random configurations: robot joints uniform within their limits
    ([-pi, pi] if unlimited), MMM arm joints uniform within the model's ranges (other joints 0).
    """
    rng = np.random.default_rng(seed)
    return float(np.cbrt(_robot_max_det(robot, rng, n) / _human_max_det(rng, n)))


class MAN_r(Criterion):  # noqa: N801 - the paper's name
    """MAN^r: each arm's manipulability, scaled by 1 / lambda_R, to the normalised human's.

    e (F, 12) is the Mandel vector of ``log(T^-1/2 (M_R / lambda) T^-1/2)`` per arm; h the mean over
    the arms of its norm, the affine-invariant distance (Jaquier et al., Eq. 4).
    """

    name, gamma, x0, weight = "MAN_r", 0.5, 1.9, 1 / 5
    sites = value_sites = (SITE,)
    parts, part_form, learned = 2, "norm", "scale"

    def __init__(self, robot: Robot, scale: float):
        self.robot, self.scale = robot, scale

    def residual(self, state, sample):
        return man_residual(self.robot, state, sample.manip, self.scale).reshape(len(state.q), 12)

    def jacobian(self, state, sample):
        jac = man_jacobian(self.robot, state, sample.manip, self.scale)  # (F, 2, 6, n)
        return jac.reshape(len(state.q), 12, -1)

    def __call__(self, state, sample):
        e, jac = man_residual_and_jacobian(self.robot, state, sample.manip, self.scale)
        return e[0].reshape(12), jac[0].reshape(12, -1)

    def cost(self, e):
        return man_cost(e.reshape(len(e), 2, 6))

    def cost_gradient(self, e):
        return block_norm_gradient(e, 2)
