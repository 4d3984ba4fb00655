"""hlik's criteria as mink tasks and limits, usable in a plain ``mink.solve_ik`` beside mink's own.

:class:`CriterionTask` adapts any :class:`hlik.criteria.base.Term` (the same residual and Jacobian the
QP solver and the metrics use); the frame's context is set per frame with :meth:`CriterionTask.set_sample`.
:class:`HumanJointLimit` keeps the mapped joints inside the human's range as hard inequalities;
:class:`SelfCollisionLimit` keeps the robot's collision geoms apart and :class:`HandBandLimit` the
hands in their band, for :class:`hlik.solvers.mink_ik.MinkSolver`, which keeps the frame's joint
box of :mod:`hlik.solvers.limits` itself.
"""

from __future__ import annotations

from types import SimpleNamespace

import mink
import mujoco
import numpy as np
from mink.limits import Constraint, Limit

from hlik.criteria import registry
from hlik.criteria.base import Sample, Term
from hlik.criteria.joints import human_limits
from hlik.criteria.learned import Learned
from hlik.robot.collision import DistanceBounds, collision_pairs
from hlik.robot.model import Robot
from hlik.robot.state import SITES, RobotState, robot_state
from hlik.solvers.frames import JointBox, collision_floors, collision_rows, hand_band


class StateCache:
    r"""One kinematics pass per configuration, shared by the :class:`CriterionTask`\ s of a stack
    (mink asks every task on its own; each would run forward kinematics and site Jacobians).
    ``sites``: the site Jacobians computed (indices into :data:`hlik.robot.state.SITES`; default
    all), the others left zero."""

    def __init__(self, robot: Robot, sites: tuple[int, ...] | None = None):
        self.robot, self.data = robot, mujoco.MjData(robot.model)
        self.sites = tuple(range(len(SITES))) if sites is None else sites
        self._key: bytes | None = None
        self._state: RobotState | None = None

    def state(self, q: np.ndarray) -> RobotState:
        key = np.asarray(q, dtype=float).tobytes()
        if key != self._key or self._state is None:
            self._state = robot_state(
                self.robot, q, jacobians=True, data=self.data, jacobian_sites=self.sites
            )
            self._key = key
        return self._state


class CriterionTask(mink.Task):
    """A least-squares hlik term as a ``mink.Task``; the robot's ``qpos`` is its configuration.
    ``cost``: the weight of its residual's rows (a scalar, or one per row), as mink's tasks weigh
    theirs. Tasks given one :class:`StateCache` share its kinematics pass."""

    def __init__(
        self,
        robot: Robot,
        term: Term,
        cost: float | np.ndarray = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        cache: StateCache | None = None,
    ):
        self.robot, self.term = robot, term
        self.sample: Sample | None = None
        self._cost = np.asarray(cost, dtype=float)
        self.cache = cache or StateCache(robot)
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
        e, jac = self.term(self.cache.state(configuration.q), self.sample)  # type: ignore[arg-type]  # None only if not needed
        # mink reads the cost vector's length as the task dimension
        if self.cost.shape != e.shape:
            self.cost = np.broadcast_to(self._cost, e.shape).astype(float)
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


class HandBandLimit(Limit):
    r"""The hands' tolerance band as a ``mink.Limit`` (RangedIK's ranged goals): after the step, each
    hand target task's error stays within ``position_band`` (m) or ``orientation_band`` (rad),
    component by component within band / sqrt(3) so that its norm does, as the linear rows
    ``-b <= w (e + J dq) <= b`` in the task's weighted units. The target tasks are the
    :class:`CriterionTask`\ s of the frame's stack on fPOS, fORI, fPOS^off or fORI^off
    (:meth:`set_tasks`). :class:`hlik.solvers.mink_ik.MinkSolver` keeps it where a step can and,
    where none can, moves the bound out by as little as its other rows allow
    (:func:`hlik.solvers.frames.nearest_band`); in a plain ``mink.solve_ik`` it is a hard limit."""

    def __init__(self, position_band: float = 0.0, orientation_band: float = 0.0):
        self.position_band, self.orientation_band = float(position_band), float(orientation_band)
        self.tasks: list[tuple[CriterionTask, float]] = []

    def set_tasks(self, tasks) -> None:
        """Bound the target tasks among ``tasks`` (the frame's stack)."""
        self.tasks = [
            (t, band) for t in tasks if isinstance(t, CriterionTask) and (band := hand_band(t.term, self)) > 0
        ]

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> Constraint:
        if not self.tasks:
            return Constraint()
        rows, bounds = [], []
        for task, band in self.tasks:
            e, jac = task._residual(configuration)
            w = np.asarray(task.cost, dtype=float)
            b = w * band / np.sqrt(3.0)
            rows += [w[:, None] * jac, -w[:, None] * jac]
            bounds += [b - w * e, b + w * e]
        return Constraint(G=np.vstack(rows), h=np.concatenate(bounds))


class SelfCollisionLimit(Limit):
    """Self-collision avoidance as a ``mink.Limit``: hlik's velocity-damper rows on every pair of
    the robot's collision geoms (:func:`~hlik.solvers.frames.collision_rows`, the QP's and JV's:
    a pair closer than ``collision_detect`` may approach its ``collision_margin`` by at most
    ``collision_gain`` of the gap per step), braking before the margin as the frame's box asks
    (:meth:`set_box`). The rows are read from the configuration's own kinematics, which mink
    keeps current (``Configuration.update``)."""

    def __init__(
        self,
        robot: Robot,
        collision_margin: float = 0.01,
        collision_detect: float = 0.10,
        collision_gain: float = 0.5,
    ):
        self.robot = robot
        self.data = mujoco.MjData(robot.model)  # for the braking floors, apart from the configuration
        self.settings = SimpleNamespace(
            collision_margin=collision_margin,
            collision_detect=collision_detect,
            collision_gain=collision_gain,
        )
        self.pairs = collision_pairs(robot)
        self.bounds = DistanceBounds(self.pairs) if self.pairs is not None else None
        self.floors: tuple[np.ndarray, np.ndarray] | None = None

    def set_box(self, box: JointBox) -> None:
        """The frame's braking floors (:func:`~hlik.solvers.frames.collision_floors`)."""
        self.floors = collision_floors(self.robot, self.data, self.pairs, box, self.settings, self.bounds)

    def rows(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """The rows (k, n) and bounds (k,) on the step at the configuration whose kinematics
        ``data`` holds (JV's own data; mink's configuration's in the QP)."""
        if self.pairs is None or not len(self.pairs):
            return np.zeros((0, self.robot.dof)), np.zeros(0)
        return collision_rows(self.robot, data, self.pairs, self.bounds, self.settings, self.floors)

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> Constraint:
        rows, bound = self.rows(configuration.data)
        return Constraint(G=rows, h=bound) if len(bound) else Constraint()
