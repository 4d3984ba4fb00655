"""Metrics of a trajectory: per-frame costs h_i(t) of every criterion, the scores m_i and the unified
metric. Each cost comes from the same criterion code the solvers use; only the assembly is here.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from hlik.criteria import unified
from hlik.criteria.eea import eea_cost, eea_r_target, eea_residual, forward_fill, swivel_angle
from hlik.criteria.functional import position_error, relative_errors, rotation_angle
from hlik.criteria.joints import human_limits, mapped_pose, mean_square, robot_limits
from hlik.criteria.learned import Learned
from hlik.criteria.manipulability import man_cost, man_residual
from hlik.criteria.smoothness import mje_cost
from hlik.criteria.soechting import predict_arm, soa_q_residual, soa_q_targets, soa_x_cost, soa_x_residual
from hlik.criteria.synergy import velocities
from hlik.problem.reference import human_reference
from hlik.robot.model import Robot
from hlik.robot.state import arm_lengths, robot_state
from hlik.trajectory import Trajectory

FUNCTIONAL = ("fJLA", "fPOS", "fORI", "fPOS_off", "fORI_off")


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
    """

    h: MappingProxyType
    m: MappingProxyType
    m_hl: float
    m_f: float
    m_hl_f: float
    scenario: str

    def curves(self) -> dict[str, np.ndarray]:
        """Criterion name -> (T,) per-frame score f_x0(h_i(t)), the curves m_i averages."""
        x0 = unified.midpoints(self.scenario)
        return {k: unified.logistic(self.h[k], x0[k]) for k in self.m}

    def to_json(self) -> dict:
        """The JSON object of ``hlik evaluate --json``."""
        pair = lambda k: {"h": float(np.mean(self.h[k])), "m": self.m[k]}  # noqa: E731
        return {
            "metrics": {k: pair(k) for k in unified.CRITERIA},
            "functional": {k: pair(k) for k in unified.FUNCTIONAL_X0[self.scenario]},
            "m_hl": self.m_hl,
            "m_f": self.m_f,
            "m_hl_f": self.m_hl_f,
            "scenario": self.scenario,
        }


def costs(traj: Trajectory, robot: Robot, learned: Learned) -> dict[str, np.ndarray]:
    """Criterion name -> (T,) cost h(t) of every criterion, functional ones included."""
    q, ref, syn = traj.q, traj.reference, learned.synergies
    state = robot_state(robot, q, jacobians=True)
    human = human_reference(robot, ref, traj.placement)
    h = {}

    psi = forward_fill(swivel_angle(state.shoulder, state.elbow, state.wrist))
    psi_human = learned.swivel.predict(state.shoulder, state.tcp, state.tcp_rot)
    h["EEA"] = eea_cost(eea_residual(psi, psi_human))
    h["EEA_r"] = eea_cost(eea_residual(psi, eea_r_target(psi, psi_human, human.psi)))

    l_u, l_f = arm_lengths(robot)
    elbow_pred, angles = predict_arm(state.shoulder, state.wrist, l_u, l_f)
    h["SOA_x"] = soa_x_cost(soa_x_residual(state, elbow_pred, l_u))
    idx, targets = soa_q_targets(robot, angles)
    h["SOA_q"] = mean_square(soa_q_residual(robot, state, idx, targets))

    h["HJL"] = mean_square(human_limits(robot).residual(q))
    h["HJA_r"] = mean_square(mapped_pose(robot, human.q_map).residual(q))
    h["SYN"] = mean_square(syn.syn_residual(q))
    h["SYN_r"] = mean_square(syn.syn_r_residual(q, human.q_map))
    h["MIS"] = syn.mis_cost(velocities(q, float(np.median(np.diff(traj.times)))))
    h["MJE"] = mje_cost(robot, q)

    h["MAN_r"] = man_cost(man_residual(robot, state, human.manip, learned.scale))

    h["fJLA"] = mean_square(robot_limits(robot).residual(q))
    h["fPOS"] = position_error(traj.tcp_pos, traj.targets.pos).mean(axis=-1)
    h["fORI"] = rotation_angle(traj.tcp_rot, traj.targets.rot).mean(axis=-1)
    h["fPOS_off"], h["fORI_off"] = relative_errors(
        traj.tcp_pos, traj.tcp_rot, traj.targets.pos, traj.targets.rot
    )
    return h


def evaluate(
    traj: Trajectory, robot: Robot, learned: Learned, scenario: str = "pose", alpha: float = unified.ALPHA
) -> Evaluation:
    """Costs, scores and the unified metric of ``traj`` (scenario ``pose`` or ``relative``)."""
    if scenario not in unified.FUNCTIONAL_X0:
        raise ValueError(f"scenario must be one of {tuple(unified.FUNCTIONAL_X0)}, got {scenario!r}")
    h = costs(traj, robot, learned)
    x0 = unified.midpoints(scenario)
    m = {k: unified.score(h[k], x0[k]) for k in x0}
    m_hl, m_f = unified.hierarchical(m), unified.functional(m, scenario)
    return Evaluation(
        h=MappingProxyType(h),
        m=MappingProxyType(m),
        m_hl=m_hl,
        m_f=m_f,
        m_hl_f=unified.combined(m_hl, m_f, alpha),
        scenario=scenario,
    )


__all__ = ["FUNCTIONAL", "Evaluation", "costs", "evaluate"]
