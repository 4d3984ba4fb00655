"""MJE, minimum jerk, and RelaxedIK's smoothness terms: backward differences of the last configurations.

MJE (paper Sec. III-B, formulas.md §6) is RelaxedIK's jerk approximation
``q_t - 3 q_t-1 + 3 q_t-2 - q_t-3`` (no dt; x0 assumes 100 Hz), its cost the norm of each arm's part
averaged over the two arms, as every bimanual criterion. Unlimited joints difference as angles, so a
joint that winds by 2π has no jerk. :class:`Smoothness` is the solvers' velocity, acceleration and
jerk term toward the extrapolation of the previous frames.

Why the solvers do not minimise the jerk alone: a frame solved once, toward its target and toward
the cubic extrapolation ``3 q_t-1 - 3 q_t-2 + q_t-3`` of the frames before, feeds its own past back
with gains 3, -3, 1. Its stencil's frequency response ``S(w) = (1 - e^-iw)^3`` has a negative real
part below a third of the frame rate, so there the frame loop amplifies the motion's jerk, and in a
direction the targets hold weakly (jerk weight above the tracking stiffness, the velocity term
small) its poles leave the unit circle: a growing oscillation (up to x1.15 per frame). A per-frame
term lowers the jerk at every frequency, for every tracking stiffness, when the real part of its
stencil's response is nowhere negative; ``jerk + a velocity`` (weighted squares) is that from
a = 9/4 on. (Any causal term with that property acts as a velocity penalty on slow motion, where
the jerk stencil's phase is 3 pi/2.)
"""

from __future__ import annotations

import numpy as np

from hlik.criteria.angles import wrap
from hlik.criteria.base import Criterion, Term
from hlik.robot.model import SIDES, Robot

# backward-difference stencils over (q_t, q_t-1, q_t-2, q_t-3)
VELOCITY = np.array([1.0, -1.0, 0.0, 0.0])
ACCELERATION = np.array([1.0, -2.0, 1.0, 0.0])
JERK = np.array([1.0, -3.0, 3.0, -1.0])
# MJE's solver form: ||jerk||^2 + 3 ||velocity||^2, above the bound 9/4 with a margin (module docstring)
MJE_VELOCITY = 3.0


def history(q: np.ndarray) -> np.ndarray:
    """(T, 3, n) the three configurations before each of ``q`` (T, n), newest first; before the
    start the first configuration repeats."""
    padded = np.concatenate([np.repeat(q[:1], 3, axis=0), q])
    return np.stack([padded[3 - k : len(padded) - k] for k in range(1, 4)], axis=1)


def backward_difference(q: np.ndarray, previous: np.ndarray, stencil: np.ndarray, unlimited: np.ndarray):
    """(F, n) ``stencil . (q_t, q_t-1, q_t-2, q_t-3)`` from q (F, n) and ``previous`` (F, 3, n),
    with consecutive differences wrapped where ``unlimited`` (n,) is True."""
    # a stencil over 4 samples that sums to 0 is a stencil over the 3 steps between them
    w = np.cumsum(stencil)[:-1]
    out = np.zeros(q.shape)
    newer = q
    for k in range(3):
        if w[k] != 0.0:
            step = newer - previous[:, k]
            if unlimited.any():
                step = np.where(unlimited, wrap(step), step)
            out += w[k] * step
        newer = previous[:, k]
    return out


class MJE(Criterion):
    """MJE: the jerk approximation (F, n), rad per sample³; h the mean over the arms of its norm.

    Solver form: the jerk alone would excite the frame loop (module docstring), so the solvers
    minimise ``||jerk||^2 + 3 ||velocity||^2`` as one residual (n,) toward the weighted mean of the
    cubic extrapolation and the previous frame, ``q_t - (x_jerk + 3 q_t-1) / 4`` (Jacobian I, as
    :class:`Smoothness` combines its terms), and report h.
    """

    name, gamma, x0, weight = "MJE", 1.0, 2e-4, 1 / 5
    sites, motion, parts, part_form = (), True, 2, "norm"
    solver_form = "||jerk||^2 + 3 ||velocity||^2 toward the previous frames (never amplifies the jerk)"
    solver_stencil = (JERK + MJE_VELOCITY * VELOCITY) / (1.0 + MJE_VELOCITY)

    def __init__(self, robot: Robot, learned: object = None):
        self.unlimited = np.isinf(robot.lower)
        self.arms = [robot.index(robot.arm_joints[s]) for s in SIDES]
        self.constant_jacobian = np.eye(robot.dof)

    def residual(self, state, sample):
        return backward_difference(state.q, sample.history, JERK, self.unlimited)

    def __call__(self, state, sample):
        e = backward_difference(state.q, sample.history, self.solver_stencil, self.unlimited)
        return e[0], self.constant_jacobian

    def part_rows(self, m):
        return self.arms

    def cost(self, e):
        return np.mean([np.linalg.norm(e[:, arm], axis=-1) for arm in self.arms], axis=0)

    def cost_gradient(self, e):
        grad = np.zeros_like(e)
        for arm in self.arms:
            part = e[:, arm]
            grad[:, arm] = (
                part / np.maximum(np.linalg.norm(part, axis=-1, keepdims=True), 1e-12) / len(self.arms)
            )
        return grad


class Smoothness(Term):
    """Velocity, acceleration and jerk toward the extrapolation of the previous frames (RelaxedIK),
    as one least-squares term: ``stencil . (q_t, ..., q_t-3)`` with the identity Jacobian."""

    sites, part_form, motion = (), "norm", True

    def __init__(self, stencil: np.ndarray, robot: Robot, name: str = "smoothness"):
        self.name, self.stencil, self.unlimited = name, stencil, np.isinf(robot.lower)
        self.constant_jacobian = np.eye(robot.dof)

    def residual(self, state, sample):
        return backward_difference(state.q, sample.history, self.stencil, self.unlimited)

    def cost(self, e):
        return np.linalg.norm(e, axis=-1)  # RelaxedIK's ||q - extrapolation||

    def cost_gradient(self, e):
        return e / np.maximum(np.linalg.norm(e, axis=-1, keepdims=True), 1e-12)


def smoothness_terms(
    robot: Robot, velocity: float, acceleration: float, jerk: float
) -> list[tuple[Term, float]]:
    """RelaxedIK's minimum velocity, acceleration and jerk with the given costs, as one term with
    its weight (none where every cost is 0).

    The three are least squares toward three extrapolations of the same history with the identity
    Jacobian, so their sum equals one term toward the cost-weighted mean extrapolation (up to a
    constant): n rows instead of 3 n.
    """
    costs = np.array([velocity, acceleration, jerk], dtype=float)
    if not np.any(costs > 0):
        return []
    w = costs**2 / np.sum(costs**2)
    return [
        (Smoothness(w @ np.stack([VELOCITY, ACCELERATION, JERK]), robot), float(np.sqrt(np.sum(costs**2))))
    ]
