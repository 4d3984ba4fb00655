"""Synergies: SYN (reconstruction), SYN^r (pose similarity in synergy space), MIS (first-order).

Postural synergies are the first k principal components of robot-mapped human poses (both arms
together); first-order synergies those of the joint velocities, each velocity scaled by its
standard deviation (the robots carry no velocity limits). Fitting lives in :mod:`hlik.learned`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter
from sklearn.decomposition import PCA

from hlik.criteria.angles import joint_difference

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
        vel_scale: (d,) standard deviation of each joint's velocity, rad/s.
        vel_basis: (k, d) first-order components of the scaled velocities.
        vel_explained: (k,) their explained variance ratios.
    """

    idx: np.ndarray
    unlimited: np.ndarray
    mean: np.ndarray
    basis: np.ndarray
    explained: np.ndarray
    vel_scale: np.ndarray
    vel_basis: np.ndarray
    vel_explained: np.ndarray

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

    def mis_cost(self, qdot: np.ndarray, eps: float = 1e-6) -> np.ndarray:
        """MIS: (F,) sin^2 of the angle between scaled velocity and the first-order span; 0 at rest."""
        v = qdot[..., self.idx] / self.vel_scale
        norm2 = np.sum(v * v, axis=-1)
        inside = np.sum(np.square(v @ self.vel_basis.T), axis=-1)
        return np.where(norm2 > eps**2, 1.0 - inside / np.maximum(norm2, eps**2), 0.0)


def velocities(q: np.ndarray, dt: float) -> np.ndarray:
    """(T, n) joint velocities by a Savitzky-Golay derivative (order 3, window 21 or shorter)."""
    window = min(SAVGOL_WINDOW, len(q) - (1 - len(q) % 2))
    if window <= SAVGOL_ORDER:
        return np.gradient(q, dt, axis=0)
    return savgol_filter(q, window, SAVGOL_ORDER, deriv=1, delta=dt, axis=0)


def fit_synergies(
    poses: list[np.ndarray], dt: float, idx: np.ndarray, unlimited: np.ndarray, k: int = N_COMPONENTS
) -> Synergies:
    """Fit postural and first-order synergies on pose sequences, each (T_i, d) at step ``dt``."""
    stacked = np.concatenate(poses)
    pose_pca = PCA(n_components=k).fit(stacked)
    vel = np.concatenate([velocities(p, dt) for p in poses])
    # joints the corpus never moves get a floor, or any motion of theirs would weigh ~1e6 times more
    std = vel.std(axis=0)
    scale = np.maximum(std, 0.05 * std.max() + 1e-9)
    vel_pca = PCA(n_components=k).fit(vel / scale)
    return Synergies(
        idx=idx,
        unlimited=unlimited,
        mean=pose_pca.mean_,
        basis=pose_pca.components_,
        explained=pose_pca.explained_variance_ratio_,
        vel_scale=scale,
        vel_basis=vel_pca.components_,
        vel_explained=vel_pca.explained_variance_ratio_,
    )
