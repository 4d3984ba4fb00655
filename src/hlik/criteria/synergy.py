"""Synergies: SYN (reconstruction), SYN^r (pose similarity in synergy space), MIS (first-order).

Postural synergies are the first k principal components of robot-mapped human poses (both arms
together); first-order synergies those of the joint velocities of the joints the mapping moves, each
velocity scaled by its standard deviation. Fitting lives in :mod:`hlik.criteria.learned`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter
from sklearn.decomposition import PCA

from hlik.criteria.angles import joint_difference
from hlik.criteria.base import Criterion, block_norm_cost, block_norm_gradient
from hlik.robot.model import Robot

N_COMPONENTS = 5
SAVGOL_WINDOW, SAVGOL_ORDER = 21, 3  # paper Sec. III-B, at 100 Hz


@dataclass(frozen=True, eq=False)
class Synergies:
    """Principal components of a robot's mapped human corpus.

    Attributes:
        idx: (d,) robot joint indices the components span (both arms' joints).
        unlimited: (d,) joints compared by angular distance.
        mean: (d,) mean pose, rad.
        basis: (k, d) postural components (orthonormal rows).
        explained: (k,) explained variance ratios of the postural components.
        moving: (d,) True for the joints the first-order components span: those the mapping moves.
        vel_scale: (d_v,) standard deviation of each moving joint's velocity, rad/s.
        vel_basis: (k, d_v) first-order components of the scaled velocities.
        vel_explained: (k,) their explained variance ratios.
    """

    idx: np.ndarray
    unlimited: np.ndarray
    mean: np.ndarray
    basis: np.ndarray
    explained: np.ndarray
    moving: np.ndarray
    vel_scale: np.ndarray
    vel_basis: np.ndarray
    vel_explained: np.ndarray

    @property
    def vel_idx(self) -> np.ndarray:
        """(d_v,) robot joint indices of the first-order components."""
        return self.idx[self.moving]

    def syn_residual(self, q: np.ndarray) -> np.ndarray:
        """SYN: (F, d) part of the pose (F, n) outside the synergy subspace, (I - P^T P)(q - mean)."""
        d = joint_difference(q[..., self.idx], self.mean, self.unlimited)
        return d - (d @ self.basis.T) @ self.basis

    def syn_jacobian(self, n: int) -> np.ndarray:
        """(d, n) constant Jacobian of :meth:`syn_residual`."""
        jac = np.zeros((len(self.idx), n))
        jac[:, self.idx] = np.eye(len(self.idx)) - self.basis.T @ self.basis
        return jac

    def syn_r_residual(self, q: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
        """SYN^r: (F, k) synergy coordinates of pose minus reference, P (q - q_ref)."""
        return joint_difference(q[..., self.idx], q_ref[..., self.idx], self.unlimited) @ self.basis.T

    def syn_r_jacobian(self, n: int) -> np.ndarray:
        """(k, n) constant Jacobian of :meth:`syn_r_residual`."""
        jac = np.zeros((len(self.basis), n))
        jac[:, self.idx] = self.basis
        return jac


def velocities(q: np.ndarray, dt: float) -> np.ndarray:
    """(T, n) joint velocities by a Savitzky-Golay derivative (order 3, window 21 or shorter)."""
    window = min(SAVGOL_WINDOW, len(q) - (1 - len(q) % 2))
    if window <= SAVGOL_ORDER:
        return np.gradient(q, dt, axis=0)
    return savgol_filter(q, window, SAVGOL_ORDER, deriv=1, delta=dt, axis=0)


def fit_synergies(
    poses: list[np.ndarray],
    dt: float,
    idx: np.ndarray,
    unlimited: np.ndarray,
    moving: np.ndarray | None = None,
    k: int = N_COMPONENTS,
) -> Synergies:
    """Fit postural and first-order synergies on pose sequences, each (T_i, d) at step ``dt``.

    ``moving`` (d,) selects the joints of the first-order synergies (default all). A joint the
    mapping holds fixed has no human velocity to learn from: left in, it would carry no component,
    so any motion of it would lie wholly outside the span and h_MIS would saturate at 1.
    """
    moving = np.ones(len(idx), dtype=bool) if moving is None else np.asarray(moving, dtype=bool)
    stacked = np.concatenate(poses)
    pose_pca = PCA(n_components=k).fit(stacked)
    # unlimited joints difference as angles: a recorded angle wrapping at ±pi is no 2 pi jump
    unwrapped = [np.where(unlimited, np.unwrap(p, axis=0), p) for p in poses]
    vel = np.concatenate([velocities(p[:, moving], dt) for p in unwrapped])
    # a joint the corpus barely moves gets a floor, or any motion of it would dominate the rest
    std = vel.std(axis=0)
    scale = np.maximum(std, 0.05 * std.max() + 1e-9)
    vel_pca = PCA(n_components=k).fit(vel / scale)
    return Synergies(
        idx=idx,
        unlimited=unlimited,
        mean=pose_pca.mean_,
        basis=pose_pca.components_,
        explained=pose_pca.explained_variance_ratio_,
        moving=moving,
        vel_scale=scale,
        vel_basis=vel_pca.components_,
        vel_explained=vel_pca.explained_variance_ratio_,
    )


# --- the criteria ----------------------------------------------------------------------------


class SYN(Criterion):
    """SYN: the part of the pose outside the robot's postural synergy subspace (e (F, d), rad)."""

    name, gamma, x0, weight = "SYN", 6.0, 0.12, 1 / 15
    needs_sample, sites, learned = False, (), "synergies"

    def __init__(self, robot: Robot, synergies: Synergies):
        self.syn = synergies
        self.constant_jacobian = self.syn.syn_jacobian(robot.dof)

    def residual(self, state, sample):
        return self.syn.syn_residual(state.q)


class SYN_r(Criterion):  # noqa: N801 - the paper's name
    """SYN^r: the pose minus the mapped human pose, in synergy coordinates (e (F, k), rad)."""

    name, gamma, x0, weight = "SYN_r", 2.0, 0.47, 1 / 30
    sites, learned = (), "synergies"

    def __init__(self, robot: Robot, synergies: Synergies):
        self.syn = synergies
        self.constant_jacobian = self.syn.syn_r_jacobian(robot.dof)

    def residual(self, state, sample):
        return self.syn.syn_r_residual(state.q, sample.q_map)


# SLSQP's MIS stand-in over the RMS of the velocity outside the span (in corpus velocity scales).
# At 1 it pulled so hard that OPT+MIS lost the hands (ARMAR-6, Cut and Close, 3 s: m_f 0.553, median
# fPOS 2.7 cm on Close); at 0.1 it tracks as the quartic form did (m_f 0.632 against 0.622) with the
# same m_hl (0.563 against 0.561).
MIS_SLSQP_SCALE = 0.1


class MIS(Criterion):
    """MIS: how far the joint velocity leaves the first-order synergy span (formulas.md §3).

    e (F, d_v) is the scaled velocity since the previous sample of the joints the mapping moves,
    ``(q - q_prev) / dt / scale`` (unlimited joints as angular distance), and h the paper's
    misalignment ``sin^2`` of its angle to the span (0 at rest). Joints the mapping holds fixed
    (ARMAR-6's clavicles, Panda joint 7) are left out: the corpus gives them no velocity, so their
    motion would be all misalignment (h near 1 whenever they move); SYN and HJA^r judge their
    pose. Solver form: ``sin^2`` is scale-free and not differentiable at rest, so
    the solvers minimise the velocity outside the span instead (a velocity penalty, formulas.md
    §9) and report h: the QP its squares ``||(I - U^T U) e||^2``, SLSQP a tenth of its root mean
    square (:data:`MIS_SLSQP_SCALE`). Under the groove loss, quadratic near 0, a norm gives a loss
    quadratic in the velocity, as the QP's; the mean of squares gave a quartic one, where SLSQP's
    steps only shrank the error by a third (ARMAR-6, two KIT takes: 51 evaluations a frame, 4.5
    now).
    """

    name, gamma, x0, weight = "MIS", 1.0, 0.49, 1 / 5
    sites, motion, part_form = (), True, "norm"  # the stand-in's
    solver_form = "velocity penalty: (I - U^T U) e, its squares (QP) or RMS / 10 (SLSQP), formulas.md §9"

    learned = "synergies"

    def __init__(self, robot: Robot, synergies: Synergies):
        syn = synergies
        self.syn, self.n = syn, robot.dof
        self.idx, self.unlimited = syn.vel_idx, syn.unlimited[syn.moving]
        self.outside = np.eye(len(self.idx)) - syn.vel_basis.T @ syn.vel_basis
        self.norm_scale = MIS_SLSQP_SCALE / np.sqrt(len(self.idx))  # RMS / 10

    def residual(self, state, sample):
        d = joint_difference(state.q[:, self.idx], sample.history[:, 0, self.idx], self.unlimited)
        return d / sample.dt / self.syn.vel_scale

    def jacobian(self, state, sample):
        jac = np.zeros((len(self.idx), self.n))
        jac[:, self.idx] = np.diag(1.0 / (sample.dt * self.syn.vel_scale))
        return np.broadcast_to(jac, (len(state.q), *jac.shape))

    def cost(self, e):
        norm2 = np.sum(e * e, axis=-1)
        inside = np.sum(np.square(e @ self.syn.vel_basis.T), axis=-1)
        return np.where(norm2 > 1e-12, 1.0 - inside / np.maximum(norm2, 1e-12), 0.0)

    def cost_gradient(self, e):
        norm2 = np.sum(e * e, axis=-1, keepdims=True)
        inside = e @ self.syn.vel_basis.T @ self.syn.vel_basis
        safe = np.maximum(norm2, 1e-12)
        grad = -2.0 * inside / safe + 2.0 * np.sum(inside * e, axis=-1, keepdims=True) * e / safe**2
        return np.where(norm2 > 1e-12, grad, 0.0)

    def __call__(self, state, sample):
        jac = self.jacobian(state, sample)[0]
        return self.outside @ self.residual(state, sample)[0], self.outside @ jac

    def metrics(self, e):
        return self.norm_scale * block_norm_cost(e, 1), self.norm_scale * block_norm_gradient(e, 1)
