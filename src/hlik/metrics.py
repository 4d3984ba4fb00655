"""Metrics of a trajectory: per-frame costs h_i(t) of every criterion, the scores m_i and the unified
metric. Each cost comes from the same criterion code the solvers use; only the assembly is here.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

import mujoco
import numpy as np
from scipy.ndimage import uniform_filter1d

from hlik.criteria import registry, unified
from hlik.criteria.angles import joint_difference
from hlik.criteria.base import Sample
from hlik.criteria.functional import position_error, rotation_angle
from hlik.criteria.learned import Learned
from hlik.criteria.smoothness import history
from hlik.executable import ControllerChecks, controller_checks
from hlik.posture import Posture, posture
from hlik.problem.reference import HumanReference, reference_sample
from hlik.robot.model import Robot, self_contacts
from hlik.robot.state import robot_state
from hlik.trajectory import Trajectory


@dataclass(frozen=True, eq=False)
class Evaluation:
    """Costs and scores of one trajectory.

    Attributes:
        h: Criterion name -> (T,) per-frame cost (the 11 criteria and the functional ones).
        m: Criterion name -> score m_i in [0, 1] (paper Eq. 1); functional ones by the scenario's x0.
        m_hl: Hierarchical human-likeness score (Eq. 2).
        m_f: Functional score of the scenario.
        m_hl_f: alpha m_hl + (1 - alpha) m_f.
        scenario: ``pose`` (end-effector poses) or ``relative`` (relative pose of the hands).
        speed_ratio: (T - 1,) each step's largest joint speed over that joint's limit (> 1: too fast).
        collisions: (T,) True where the robot touches itself (:func:`hlik.robot.model.self_contacts`).
        controller: What a controller checks: accelerations, jerk, torques, stops, floor
            (:mod:`hlik.executable`).
        posture: Trunk lean, elbows and hands against the shoulders, swivel and joint path,
            the robot's beside the subject's (:mod:`hlik.posture`; not part of m_hl).
        metric: The weights and x0 the scores used (Table III unless another was given).
        fpos: (T, 2) each hand's TCP distance from its target, m (left, right).
        fori: (T, 2) each hand's TCP rotation from its target's orientation, rad.
    """

    h: MappingProxyType
    m: MappingProxyType
    m_hl: float
    m_f: float
    m_hl_f: float
    scenario: str
    speed_ratio: np.ndarray
    collisions: np.ndarray
    metric: unified.Metric
    controller: ControllerChecks
    posture: Posture
    fpos: np.ndarray
    fori: np.ndarray

    @property
    def n_frames(self) -> int:
        return len(self.collisions)

    @property
    def max_speed_ratio(self) -> float:
        """The largest joint speed over its limit in any step (> 1: faster than the robot can move)."""
        return float(self.speed_ratio.max(initial=0.0))

    def curves(self, window: int = 1) -> dict[str, np.ndarray]:
        """Criterion name -> (T,) per-frame score f_x0(h_i(t)), the curves m_i averages.

        ``window`` (frames, odd): the scores of the criteria of motion (MJE, MIS: differences of a
        few frames) as their running mean over that many frames. Their per-frame h sits near x0 on
        retargeted motion (MJE's median jerk on the Cut take: 0.9 x0), where Eq. 1's logistic turns
        +-20 % of a frame's jerk into 0.73 / 0.27, so the raw curve flips between 0 and 1 from
        frame to frame (19-41 % of the QP's frames, 3 % of the human's). The ends are reflected,
        which keeps each curve's mean exactly m_i (a symmetric, doubly stochastic filter).
        """
        if window < 1 or window % 2 == 0:
            raise ValueError(f"window must be a positive odd number of frames, got {window}")
        x0 = unified.midpoints(self.scenario, self.metric)
        out = {k: unified.logistic(self.h[k], x0[k]) for k in self.m}
        n = self.n_frames
        size = min(window, n if n % 2 else n - 1)  # odd: a symmetric filter
        for k in out:
            if size > 1 and registry.criterion_class(k).motion:
                out[k] = uniform_filter1d(out[k], size, mode="reflect")
        return out

    def unified_curves(self, window: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """(T,) m_hl(t) = sum_i w_i f_i(t) and (T,) m_f(t), the mean of the scenario's functional
        f_i(t).

        A per-frame m_hl is not defined by the paper; these are the weighted sums Eq. 2 applies to
        the per-frame scores f_i(t) (:meth:`curves`, the criteria of motion over ``window``
        frames), so that their means over the frames are exactly m_hl and m_f (the m_i are such
        means).
        """
        f = self.curves(window)
        m_hl = sum(self.metric.weights[k] * f[k] for k in registry.human_likeness())
        m_f = np.mean([f[k] for k in unified.FUNCTIONAL_X0[self.scenario]], axis=0)
        return np.asarray(m_hl, dtype=float), np.asarray(m_f, dtype=float)

    def to_json(self) -> dict:
        """The JSON object of ``hlik evaluate --json``."""
        pair = lambda k: {"h": float(np.mean(self.h[k])), "m": self.m[k]}  # noqa: E731
        return {
            "metrics": {k: pair(k) for k in registry.human_likeness()},
            "functional": {k: pair(k) for k in unified.FUNCTIONAL_X0[self.scenario]},
            "m_hl": self.m_hl,
            "m_f": self.m_f,
            "m_hl_f": self.m_hl_f,
            "scenario": self.scenario,
            "collisions": int(np.count_nonzero(self.collisions)),
            "max_speed_ratio": self.max_speed_ratio,
            "controller": self.controller.to_json(),
            "posture": self.posture.to_json(),
            "metric": self.metric.source,
        }


COST_CHUNK = 4096  # frames whose Jacobians are held at once (7.7 kB a frame on ARMAR-6)


def trajectory_sample(traj: Trajectory, reference: HumanReference) -> Sample:
    """The :class:`Sample` of every frame of ``traj``: its targets, the human reference, the previous
    three configurations (the first frame repeated before the start) and the median frame period."""
    return reference_sample(reference, traj.targets, slice(None), history(traj.q), traj.period)


def costs(traj: Trajectory, robot: Robot, learned: Learned) -> dict[str, np.ndarray]:
    """Criterion name -> (T,) cost h(t) of every registered criterion, functional ones included.

    Each is the criterion's own :meth:`~hlik.criteria.base.Term.cost` of its residual, the cost the
    solvers report, computed :data:`COST_CHUNK` frames at a time (one forward-kinematics pass each)
    so that memory does not grow with the take.
    """
    criteria = [
        registry.criterion(n, robot, learned) for n in registry.human_likeness() + registry.functional()
    ]
    sites = tuple(sorted({i for c in criteria for i in c.value_sites}))
    dt, parts = traj.period, []
    for start in range(0, traj.n_frames, COST_CHUNK):
        rows = slice(start, start + COST_CHUNK)
        # the three configurations before each frame of the chunk (the first repeated before the start)
        past = history(traj.q[max(start - 3, 0) : rows.stop])[min(start, 3) :]
        sample = reference_sample(traj.reference, traj.targets, rows, past, dt)
        state = robot_state(robot, traj.q[rows], jacobians=bool(sites), jacobian_sites=sites)
        parts.append({c.name: c.cost(c.residual(state, sample)) for c in criteria})
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def evaluate(
    traj: Trajectory,
    robot: Robot,
    learned: Learned,
    scenario: str = "pose",
    alpha: float = unified.ALPHA,
    metric: unified.Metric | None = None,
) -> Evaluation:
    """Costs, scores and the unified metric of ``traj`` (scenario ``pose`` or ``relative``), with
    ``metric``'s weights and x0 (default Table III's)."""
    unified.check_scenario(scenario)
    h = costs(traj, robot, learned)
    metric = metric or unified.Metric.table3()
    x0 = unified.midpoints(scenario, metric)
    m = {k: unified.score(h[k], x0[k]) for k in x0}
    m_hl, m_f = unified.hierarchical(m, metric), unified.functional(m, scenario)
    return Evaluation(
        h=MappingProxyType(h),
        m=MappingProxyType(m),
        m_hl=m_hl,
        m_f=m_f,
        m_hl_f=unified.combined(m_hl, m_f, alpha),
        scenario=scenario,
        speed_ratio=speed_ratios(traj, robot),
        collisions=collision_frames(traj, robot),
        metric=metric,
        controller=controller_checks(traj, robot),
        posture=posture(traj, robot),
        fpos=position_error(traj.tcp_pos, traj.targets.pos),
        fori=rotation_angle(traj.tcp_rot, traj.targets.rot),
    )


def speed_ratios(traj: Trajectory, robot: Robot) -> np.ndarray:
    """(T - 1,) per step, the largest |dq/dt| over the joint's speed limit (unlimited joints as angles)."""
    if traj.n_frames < 2:
        return np.zeros(0)
    step = joint_difference(traj.q[1:], traj.q[:-1], np.isinf(robot.lower))
    speed = np.abs(step) / np.diff(traj.times)[:, None]
    return np.max(speed / robot.velocity_limit, axis=1)


def collision_frames(traj: Trajectory, robot: Robot) -> np.ndarray:
    """(T,) True where the robot's collision geometry touches itself."""
    data = mujoco.MjData(robot.model)
    return np.array([bool(self_contacts(robot, q, data)) for q in traj.q], dtype=bool)


__all__ = ["Evaluation", "costs", "evaluate"]
