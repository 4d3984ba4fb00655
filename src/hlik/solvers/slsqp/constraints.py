"""SLSQP's inequality constraints: self-collision distances, the hands' band and the joint box in
a chart's variables."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from hlik.criteria.base import Sample
from hlik.robot.collision import CollisionPairs, DistanceBounds, near_pairs
from hlik.robot.model import Robot
from hlik.robot.state import robot_state
from hlik.solvers.frames import JointBox, collision_floors, hand_band
from hlik.solvers.gradients import part_gradients
from hlik.solvers.settings import SLSQPSettings
from hlik.solvers.slsqp.objective import Chart, Loss, loss_sites

COLLISION_TOLERANCE = 1e-4  # m, NLopt's tolerance on the collision constraints
BAND_TOLERANCE = 1e-4  # m or rad, NLopt's tolerance on the hands' band
BOX_TOLERANCE = 1e-8  # rad, NLopt's tolerance on the joint box rows of a Chart (solve_frame says why)


class CollisionConstraint:
    """NLopt's ``floor_i - d_i(q) <= 0`` for the k collision pairs nearest their floors (fewer:
    padded, met), in the variables of :attr:`chart` when it is set. A pair's floor is the margin,
    or the frame's braking distance where that is larger (:meth:`brake`)."""

    def __init__(self, robot: Robot, pairs: CollisionPairs, settings: SLSQPSettings):
        self.robot, self.pairs, self.settings = robot, pairs, settings
        self.data = mujoco.MjData(robot.model)
        self.bounds = DistanceBounds(pairs)
        self.chart: Chart | None = None
        self.floors = np.full(len(pairs), settings.collision_margin)
        self.detect: float | np.ndarray = settings.collision_detect

    def distances(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pairs closer than :attr:`detect` at ``q`` (n,) (``collision_detect``, or per pair
        as far as :meth:`brake` looks): indices (k,), signed distances (k,) and their gradients
        (k, n)."""
        m = self.robot.model
        self.data.qpos[:] = q
        mujoco.mj_kinematics(m, self.data)
        mujoco.mj_comPos(m, self.data)
        return near_pairs(self.robot, self.data, self.pairs, self.detect, self.bounds)

    def brake(self, box: JointBox) -> None:
        """Set the floors for the frame of ``box``: the margin, raised to the braking distance of
        the pairs near at its start, each looked for as far as it needs
        (:func:`hlik.solvers.frames.collision_floors`)."""
        margin = self.settings.collision_margin
        found = collision_floors(self.robot, self.data, self.pairs, box, self.settings, self.bounds)
        if found is None:
            self.floors, self.detect = np.full(len(self.pairs), margin), self.settings.collision_detect
        else:
            self.floors, self.detect = np.maximum(margin, found[0]), found[1]

    def __call__(self, result: np.ndarray, x: np.ndarray, grad: np.ndarray) -> None:
        s = self.settings
        index, dist, jac = self.distances(x if self.chart is None else self.chart.q(x))
        slack = self.floors[index] - dist
        order = np.argsort(-slack)[: s.collision_pairs]
        result[:] = s.collision_margin - s.collision_detect  # absent pairs: far, met
        result[: len(order)] = slack[order]
        if grad.size:
            grad[:] = 0.0
            grad[: len(order)] = -jac[order] if self.chart is None else -jac[order] @ self.chart.T


class BandConstraint:
    """The hands' tolerance band as NLopt's ``h_p(q) - bound_p <= 0``, one row per arm (per part)
    of each target term that has a band: the error of hand p (m or rad) within the band or, in a
    frame where that cannot be met (a target out of reach, or one the limits let the hand only lag
    behind), no worse than as near as the frame can bring it (``bound_p = max(band, h_p(q_near))``,
    ``q_near`` minimising the misses alone, :meth:`misses`): a criterion cannot hold a hand off
    that the frame could have brought closer. In the variables of :attr:`chart` when set.
    """

    def __init__(self, robot: Robot, losses: Sequence[Loss], settings: SLSQPSettings):
        self.robot = robot
        self.terms = [loss.term for loss in losses if hand_band(loss.term, settings) > 0.0]
        self.bands = [hand_band(t, settings) for t in self.terms]
        self.sites = loss_sites(t.sites for t in self.terms)
        self.data = mujoco.MjData(robot.model)
        self.chart: Chart | None = None
        self.bound = np.zeros(0)
        self.frame: Sample | None = None

    def __len__(self) -> int:
        return sum(t.parts for t in self.terms)

    def errors(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each hand's error (k,) of each banded term at ``q`` (n,) and its gradient (k, n)."""
        if self.frame is None:
            raise RuntimeError("BandConstraint.reset(frame, ...) must be called before evaluating")
        state = robot_state(self.robot, q, True, self.data, self.sites)
        parts = [part_gradients(t, state, self.frame) for t in self.terms]
        return np.concatenate([h for h, _ in parts]), np.vstack([g for _, g in parts])

    @property
    def band(self) -> np.ndarray:
        """(k,) each row's band."""
        return np.concatenate([np.full(t.parts, b) for t, b in zip(self.terms, self.bands)])

    def reset(self, frame: Sample, q_start: np.ndarray, chart: Chart | None, strict: bool) -> None:
        """Set the frame, its start ``q_start`` (n,) and the objective's chart; ``strict``: the
        bound is the band, else the band or the error at ``q_start`` where that is larger."""
        self.frame, self.chart = frame, chart
        self.bound = self.band if strict else np.maximum(self.band, self.errors(q_start)[0])

    def misses(self, q: np.ndarray, grad: np.ndarray) -> float:
        """``sum_p (max(0, h_p(q) - band_p) / band_p)^2`` at ``q`` (n,), the hands' squared misses of
        the band in band widths (a position's 5 mm weighs as an orientation's 3 deg, not as 5 mrad),
        with its gradient written into ``grad`` (n,) where NLopt asks for it."""
        h, dh_dq = self.errors(q)
        width = self.band
        miss = np.maximum(h - width, 0.0) / width
        if grad.size:
            grad[:] = (2.0 * miss / width) @ dh_dq
        return float(miss @ miss)

    def holds(self, q: np.ndarray) -> bool:
        """Whether every hand is within the current bound (:meth:`reset`) at ``q`` (n,), within
        NLopt's tolerance."""
        return self._within(q, self.bound)

    def met(self, q: np.ndarray) -> bool:
        """Whether every hand is inside its band at ``q`` (n,), within NLopt's tolerance."""
        return self._within(q, self.band)

    def _within(self, q: np.ndarray, bound: np.ndarray) -> bool:
        return bool(np.all(self.errors(q)[0] <= bound + BAND_TOLERANCE))

    def __call__(self, result: np.ndarray, x: np.ndarray, grad: np.ndarray) -> None:
        h, dh_dq = self.errors(x if self.chart is None else self.chart.q(x))
        result[:] = h - self.bound
        if grad.size:
            grad[:] = dh_dq if self.chart is None else dh_dq @ self.chart.T


class BoxConstraint:
    """The joint box ``lower <= q(x) <= upper`` (its finite rows only) and the box's rows
    ``rows @ q(x) <= bound`` (the torque limits) as NLopt's linear ``A x <= b`` in a chart's
    variables; without a chart (x = q), the rows alone (NLopt takes the box as bounds)."""

    def __init__(self, chart: Chart | None, box: JointBox):
        rows, bound = box.step_rows(np.zeros_like(box.lower) if chart is None else chart.origin)
        if chart is None:
            self.a, self.b = rows, bound
            return
        finite_upper, finite_lower = np.isfinite(box.upper), np.isfinite(box.lower)
        self.a = np.vstack([chart.T[finite_upper], -chart.T[finite_lower], rows @ chart.T])
        self.b = np.concatenate(
            [(box.upper - chart.origin)[finite_upper], (chart.origin - box.lower)[finite_lower], bound]
        )

    def __len__(self) -> int:
        return len(self.b)

    def __call__(self, result: np.ndarray, x: np.ndarray, grad: np.ndarray) -> None:
        result[:] = self.a @ x - self.b
        if grad.size:
            grad[:] = self.a
