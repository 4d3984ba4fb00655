"""Retarget with a plain ``mink.solve_ik`` over any mix of mink's tasks and hlik's criterion tasks.

:class:`MinkSolver` is the glue a user-composed stack needs: per frame it points every
``mink.FrameTask`` on a ``left_tcp`` / ``right_tcp`` site at the hand targets, gives every
:class:`hlik.solvers.mink_tasks.CriterionTask` the frame's context, and integrates ``solve_ik`` a few times,
warm-started from the previous frame.
"""

from __future__ import annotations

from collections.abc import Sequence

import mink
import numpy as np

from hlik.criteria.base import Sample
from hlik.problem.problem import Problem
from hlik.robot.model import SIDES
from hlik.solvers.base import SolverResult
from hlik.solvers.frames import FrameResult, JointBox, track
from hlik.solvers.limits import LimitSettings, MotionLimits
from hlik.solvers.mink_tasks import CriterionTask, FrameBoxLimit


class MinkSolver:
    """A solver for :func:`hlik.retarget.retarget` from mink tasks and limits.

    Args:
        tasks: mink tasks; ``FrameTask`` on ``<side>_tcp`` sites follow the hands.
        limits: mink limits (e.g. ``ConfigurationLimit``, :class:`hlik.solvers.mink_tasks.HumanJointLimit`);
            each frame's joint box (:mod:`hlik.solvers.limits`, what every hlik solver keeps) is
            added as a :class:`hlik.solvers.mink_tasks.FrameBoxLimit`.
        iterations: ``solve_ik`` steps per frame (the first frame gets ten times more).
        damping: Levenberg-Marquardt damping of ``solve_ik``.
        solver: qpsolvers backend.
        motion_limits: Stop margin, acceleration and torque limits of the frame box.
    """

    name = "mink"

    def __init__(
        self,
        tasks: Sequence[mink.Task],
        limits: Sequence[mink.Limit] = (),
        iterations: int = 5,
        damping: float = 1e-3,
        solver: str = "daqp",
        motion_limits: LimitSettings | None = None,
    ):
        self.tasks, self.limits = list(tasks), list(limits)
        self.motion_limits = motion_limits or LimitSettings()
        self.iterations, self.damping, self.solver = iterations, damping, solver

    def __call__(self, problem: Problem) -> SolverResult:
        """Joint angles (T, n); each frame runs a fixed number of ``solve_ik`` steps."""
        config = mink.Configuration(problem.robot.model)
        hands = {f"{side}_tcp": i for i, side in enumerate(SIDES)}
        frame_box = FrameBoxLimit(problem.robot.dof)
        limits = [*self.limits, frame_box]

        def solve_frame(k: int, sample: Sample, q: np.ndarray, box: JointBox) -> FrameResult:
            config.update(q)
            frame_box.set_box(box)
            for task in self.tasks:
                if isinstance(task, mink.FrameTask) and task.frame_name in hands:
                    i = hands[task.frame_name]
                    rot = mink.SO3.from_matrix(sample.target_rot[0, i])
                    task.set_target(mink.SE3.from_rotation_and_translation(rot, sample.target_pos[0, i]))
                elif isinstance(task, CriterionTask):
                    task.set_sample(sample)
            steps = self.iterations * (10 if k == 0 else 1)
            for _ in range(steps):
                v = mink.solve_ik(config, self.tasks, sample.dt, self.solver, self.damping, limits=limits)
                config.integrate_inplace(v, sample.dt)
            return FrameResult(box.clip(config.q), steps)

        return track(problem, solve_frame, limits=MotionLimits.of(problem.robot, self.motion_limits))
