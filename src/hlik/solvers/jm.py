"""JM: the naive joint mapping baseline (paper Sec. III-A), blind to the hand targets.

The mapping itself lives with the robot (:func:`hlik.robot.model.joint_mapping`): JM is the mapped
human pose clipped into the joint limits, as a robot controller would.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from hlik.problem.problem import Problem
from hlik.robot.model import joint_mapping
from hlik.solvers.base import Diagnostics, SolverResult


@dataclass(frozen=True)
class JMSolver:
    """The JM solver."""

    name: str = "jm"

    def __call__(self, problem: Problem) -> SolverResult:
        start = time.perf_counter()
        q = joint_mapping(problem.robot, problem.motion)
        return SolverResult(q, Diagnostics.trivial(problem.n_frames, time.perf_counter() - start))


def jm_solver(settings: object = None, progress: Callable[[int], None] | None = None) -> JMSolver:
    """The JM solver (it has no settings; the arguments keep the factories alike)."""
    return JMSolver()
