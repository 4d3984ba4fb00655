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
from hlik.human.motion import HumanMotion
from hlik.problem.placement import Placement
from hlik.problem.targets import HandTargets
from hlik.robot.model import SIDES, Robot
from hlik.solvers.frames import track
from hlik.solvers.mink_tasks import CriterionTask


class MinkSolver:
    """A solver for :func:`hlik.retarget.retarget` from mink tasks and limits.

    Args:
        tasks: mink tasks; ``FrameTask`` on ``<side>_tcp`` sites follow the hands.
        limits: mink limits (e.g. ``ConfigurationLimit``, :class:`hlik.solvers.mink_tasks.HumanJointLimit`).
        iterations: ``solve_ik`` steps per frame (the first frame gets ten times more).
        damping: Levenberg-Marquardt damping of ``solve_ik``.
        solver: qpsolvers backend.
    """

    __name__ = "mink"

    def __init__(
        self,
        tasks: Sequence[mink.Task],
        limits: Sequence[mink.Limit] = (),
        iterations: int = 5,
        damping: float = 1e-3,
        solver: str = "daqp",
    ):
        self.tasks, self.limits = list(tasks), list(limits)
        self.iterations, self.damping, self.solver = iterations, damping, solver

    def __call__(
        self, robot: Robot, motion: HumanMotion, targets: HandTargets, placement: Placement
    ) -> np.ndarray:
        """(T, n) joint angles."""
        config = mink.Configuration(robot.model)
        hands = {f"{side}_tcp": i for i, side in enumerate(SIDES)}

        def solve_frame(k: int, sample: Sample, q: np.ndarray) -> np.ndarray:
            config.update(q)
            for task in self.tasks:
                if isinstance(task, mink.FrameTask) and task.frame_name in hands:
                    i = hands[task.frame_name]
                    rot = mink.SO3.from_matrix(sample.target_rot[0, i])
                    task.set_target(mink.SE3.from_rotation_and_translation(rot, sample.target_pos[0, i]))
                elif isinstance(task, CriterionTask):
                    task.set_sample(sample)
            for _ in range(self.iterations * (10 if k == 0 else 1)):
                v = mink.solve_ik(
                    config, self.tasks, sample.dt, self.solver, self.damping, limits=self.limits
                )
                config.integrate_inplace(v, sample.dt)
            return config.q.copy()

        return track(robot, motion, targets, placement, solve_frame)
