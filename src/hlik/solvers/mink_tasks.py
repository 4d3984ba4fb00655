"""hlik's criteria as mink tasks and limits, usable in a plain ``mink.solve_ik`` beside mink's own.

:class:`CriterionTask` adapts any :class:`hlik.criteria.base.Term` (the same residual and Jacobian the
QP solver and the metrics use); the frame's context is set per frame with :meth:`CriterionTask.set_sample`.
:class:`HumanJointLimit` keeps the mapped joints inside the human's range as hard inequalities;
:class:`FrameBoxLimit` keeps a frame's joint box of :mod:`hlik.solvers.limits` (position stops with
their margin, speed, acceleration, braking, torque), the same bounds every hlik solver keeps.
"""

from __future__ import annotations

import mink
import mujoco
import numpy as np
from mink.limits import Constraint, Limit

from hlik.criteria import registry
from hlik.criteria.base import Sample, Term
from hlik.criteria.joints import human_limits
from hlik.criteria.learned import Learned
from hlik.robot.model import Robot
from hlik.robot.state import robot_state
from hlik.solvers.frames import JointBox


class CriterionTask(mink.Task):
    """A least-squares hlik term as a ``mink.Task``; the robot's ``qpos`` is its configuration."""

    def __init__(
        self, robot: Robot, term: Term, cost: float = 1.0, gain: float = 1.0, lm_damping: float = 0.0
    ):
        self.robot, self.term = robot, term
        self.sample: Sample | None = None
        self._scale = float(cost)
        self._data = mujoco.MjData(robot.model)
        super().__init__(cost=np.ones(0), gain=gain, lm_damping=lm_damping)

    @classmethod
    def criterion(cls, name: str, robot: Robot, learned: Learned, cost: float = 1.0) -> CriterionTask:
        """The task of a paper criterion (``EEA``, ``SOA_x``, ..., ``MAN_r``)."""
        return cls(robot, registry.criterion(name, robot, learned), cost)

    def set_sample(self, sample: Sample) -> None:
        """Set the frame's context (hand targets, mapped human pose, previous solutions; one row)."""
        self.sample = sample

    def compute_error(self, configuration: mink.Configuration) -> np.ndarray:
        return self._residual(configuration)[0]

    def compute_jacobian(self, configuration: mink.Configuration) -> np.ndarray:
        return self._residual(configuration)[1]

    def compute_qp_residual(self, configuration: mink.Configuration) -> tuple[np.ndarray, np.ndarray, float]:
        # error and Jacobian from one kinematics pass (mink's default calls the two methods above)
        return self._weighted_residual(*self._residual(configuration))

    def _residual(self, configuration: mink.Configuration) -> tuple[np.ndarray, np.ndarray]:
        if self.sample is None and self.term.needs_sample:
            raise mink.exceptions.TargetNotSet(type(self).__name__)
        state = robot_state(self.robot, configuration.q, jacobians=True, data=self._data)
        e, jac = self.term(state, self.sample)  # type: ignore[arg-type]  # None only if not needed
        # mink reads the cost vector's length as the task dimension
        self.cost = self._scale * np.broadcast_to(self.term.cost_weight, e.shape).astype(float)
        return e, jac


class HumanJointLimit(Limit):
    """HJL as hard limits: mapped joints stay within the MMM range mapped through (a, b)."""

    def __init__(self, robot: Robot, gain: float = 0.95):
        band = human_limits(robot)
        self.idx, self.gain, self.n = band.idx, gain, robot.dof
        self.lower, self.upper = band.centre - band.half, band.centre + band.half

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> Constraint:
        q = configuration.q[self.idx]
        # a joint already outside the human range may move back, never further out
        upper = np.maximum(self.gain * (self.upper - q), 0.0)
        lower = np.maximum(self.gain * (q - self.lower), 0.0)
        select = np.zeros((len(self.idx), self.n))
        select[np.arange(len(self.idx)), self.idx] = 1.0
        return Constraint(G=np.vstack([select, -select]), h=np.concatenate([upper, lower]))


class FrameBoxLimit(Limit):
    """A frame's :class:`~hlik.solvers.frames.JointBox` as a ``mink.Limit``: ``lower <= q + dq <=
    upper`` on its finite sides, and its rows ``rows @ (q + dq) <= bound``, for the configuration
    mink steps from. :class:`hlik.solvers.mink_ik.MinkSolver` sets the box each frame
    (:meth:`set_box`); a joint outside the box may only move back."""

    def __init__(self, n: int):
        self.n = n
        self.box: JointBox | None = None

    def set_box(self, box: JointBox) -> None:
        self.box = box

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> Constraint:
        if self.box is None:
            return Constraint()
        q, eye = configuration.q, np.eye(self.n)
        upper, lower = np.isfinite(self.box.upper), np.isfinite(self.box.lower)
        rows, bound = self.box.step_rows(q)
        g = np.vstack([eye[upper], -eye[lower], rows])
        h = np.concatenate(
            [np.maximum(self.box.upper - q, 0.0)[upper], np.maximum(q - self.box.lower, 0.0)[lower], bound]
        )
        return Constraint(G=g, h=h)
