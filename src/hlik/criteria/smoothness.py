"""MJE: minimum jerk as RelaxedIK's backward difference of the last four configurations (no dt)."""

from __future__ import annotations

import numpy as np

from hlik.robot.model import SIDES, Robot

# backward-difference stencils over (q_t, q_t-1, q_t-2, q_t-3)
VELOCITY = np.array([1.0, -1.0, 0.0, 0.0])
ACCELERATION = np.array([1.0, -2.0, 1.0, 0.0])
JERK = np.array([1.0, -3.0, 3.0, -1.0])


def history(q: np.ndarray) -> np.ndarray:
    """(T, 4, n) windows (q_t, q_t-1, q_t-2, q_t-3); before the start the first frame repeats."""
    padded = np.concatenate([np.repeat(q[:1], 3, axis=0), q])
    return np.stack([padded[3 - k : len(padded) - k] for k in range(4)], axis=1)


def jerk(q: np.ndarray) -> np.ndarray:
    """(T, n) jerk approximation q_t - 3 q_t-1 + 3 q_t-2 - q_t-3 of a trajectory (T, n)."""
    return np.einsum("k,tkn->tn", JERK, history(q))


def mje_cost(robot: Robot, q: np.ndarray) -> np.ndarray:
    """(T,) h_MJE: the norm of each arm's jerk, averaged over the two arms."""
    j = jerk(q)
    return np.mean([np.linalg.norm(j[:, robot.index(robot.arm_joints[s])], axis=-1) for s in SIDES], axis=0)
