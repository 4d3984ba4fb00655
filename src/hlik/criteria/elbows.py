"""The elbows kept in front of the back: a posture term beside the criteria, not one of them.

A person working in front of the body keeps the elbows at the sides, not behind the back; the
criteria do not see where the elbow is against the trunk (issue 28: 2-Panda's elbows went more than
5 cm behind the shoulders' frontal plane in 16-22 % of the frames, the subject's in 3 %). The
frontal plane is :mod:`hlik.posture`'s: it holds both shoulders and the base frame's vertical z,
its forward normal f = z x (S_right - S_left) / |.|, through the shoulders' midpoint S.
"""

from __future__ import annotations

import numpy as np

from hlik.criteria.base import Term, block_norm_cost, block_norm_gradient
from hlik.robot.state import RobotState

UP = np.array([0.0, 0.0, 1.0])


class ElbowsAhead(Term):
    """Per arm, how far (m) the elbow E is behind ``allowance`` behind the frontal plane, 0 where it
    is not: e_p = max(0, -allowance - (E_p - S)·f), e (F, 2). A one-sided (hinge) residual: it only
    acts on an elbow going behind the back and leaves every other posture to the criteria.

    Its cost h is the mean over the arms of e_p, in m (like fPOS, so that SLSQP's groove treats it
    as a length). Its Jacobian is exact (the shoulders' motion and the turn of f included, for a
    robot whose trunk joints move the shoulders), from the shoulder and elbow site Jacobians.
    """

    name = "elbows"
    needs_sample = False
    sites = (0, 1)
    value_sites = ()
    parts, part_form = 2, "norm"

    def __init__(self, allowance: float = 0.02):
        self.allowance = float(allowance)

    def _plane(self, state: RobotState) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per sample: the elbows' distances in front (F, 2), f (F, 3), u = z x L (F, 3), S (F, 3)."""
        left, right = state.shoulder[:, 0], state.shoulder[:, 1]
        u = np.cross(UP, right - left)
        f = u / np.linalg.norm(u, axis=-1, keepdims=True)
        mid = 0.5 * (left + right)
        ahead = np.einsum("fai,fi->fa", state.elbow - mid[:, None], f)
        return ahead, f, u, mid

    def cost(self, e: np.ndarray) -> np.ndarray:
        return block_norm_cost(e, 2)

    def cost_gradient(self, e: np.ndarray) -> np.ndarray:
        return block_norm_gradient(e, 2)

    def residual(self, state, sample):
        ahead, *_ = self._plane(state)
        return np.maximum(0.0, -self.allowance - ahead)

    def jacobian(self, state, sample):
        ahead, f, u, mid = self._plane(state)
        active = (-self.allowance - ahead) > 0.0
        if not active.any():  # the usual case: both elbows in front
            return np.zeros((*ahead.shape, state.q.shape[-1]))
        jac = state.jac[:, :, :2, :3]  # (F, arm, site (shoulder, elbow), xyz, n)
        j_mid = 0.5 * (jac[:, 0, 0] + jac[:, 1, 0])  # (F, 3, n)
        du = np.cross(UP[None, :, None], jac[:, 1, 0] - jac[:, 0, 0], axis=1)  # z x dL, (F, 3, n)
        norm = np.linalg.norm(u, axis=-1)[:, None, None]
        df = (np.eye(3) - f[:, :, None] * f[:, None, :]) @ du / norm  # (F, 3, n)
        rel = state.elbow - mid[:, None]  # (F, 2, 3)
        d_ahead = np.einsum("fi,fain->fan", f, jac[:, :, 1] - j_mid[:, None]) + np.einsum(
            "fai,fin->fan", rel, df
        )
        return np.where(active[..., None], -d_ahead, 0.0)
