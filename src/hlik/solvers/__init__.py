"""Retargeting solvers: ``(robot, motion, targets, placement) -> joint angles (T, n)``.

:func:`hlik.retarget.retarget` wraps any of them into a :class:`hlik.trajectory.Trajectory`.
Solvers are imported on demand: ``qp`` needs the learned criteria, which need ``jm``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hlik.motion import HumanMotion
from hlik.placement import Placement
from hlik.robot import Robot
from hlik.targets import HandTargets

Solver = Callable[[Robot, HumanMotion, HandTargets, Placement], np.ndarray]

SOLVER_NAMES = ("jm", "qp")


def get_solver(name: str) -> Solver:
    """The solver called ``name`` with its default settings."""
    if name == "jm":
        from hlik.solvers.jm import joint_mapping

        return joint_mapping
    if name == "qp":
        from hlik.solvers.qp import qp_solver

        return qp_solver()
    raise KeyError(name)
