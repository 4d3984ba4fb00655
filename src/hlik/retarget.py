"""The retargeting pipeline: motion -> human kinematics -> placement, targets -> solver -> trajectory."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from hlik.errors import HlikError
from hlik.human.kinematics import forward_kinematics
from hlik.human.motion import HumanMotion
from hlik.problem.placement import Placement, shoulder_placement
from hlik.problem.targets import hand_targets
from hlik.robot.model import Robot, tcp_poses
from hlik.solvers import SOLVER_NAMES, Solver, get_solver
from hlik.trajectory import Trajectory


def retarget(
    motion: HumanMotion, robot: Robot, solver: str | Solver = "jm", placement: Placement | None = None
) -> Trajectory:
    """Retarget ``motion`` to ``robot`` with ``solver``: a name in ``SOLVER_NAMES``, or a callable.

    ``placement`` defaults to :func:`hlik.placement.shoulder_placement`.
    """
    if isinstance(solver, str):
        if solver not in SOLVER_NAMES:
            raise HlikError(f"unknown solver {solver!r}; choose one of: {', '.join(SOLVER_NAMES)}")
        name, solve = solver, get_solver(solver)
    else:
        name, solve = getattr(solver, "__name__", "custom"), solver
    human = forward_kinematics(motion)
    placement = placement or shoulder_placement(robot, human)
    targets = hand_targets(human, placement)
    q = np.asarray(solve(robot, motion, targets, placement), dtype=float)
    tcp_pos, tcp_rot = tcp_poses(robot, q)
    return Trajectory(
        robot=robot.name,
        solver=name,
        times=motion.times,
        joint_names=robot.joint_names,
        q=q,
        tcp_pos=tcp_pos,
        tcp_rot=tcp_rot,
        targets=targets,
        placement=placement,
        reference=_without_body_markers(motion),
    )


def _without_body_markers(motion: HumanMotion) -> HumanMotion:
    return replace(motion, markers={})
