"""Retarget with a plain ``mink.solve_ik`` over any mix of mink's tasks and hlik's criterion tasks.

:class:`MinkSolver` is the glue a user-composed stack needs: per frame it points every
``mink.FrameTask`` on a ``left_tcp`` / ``right_tcp`` site at the hand targets, gives every
:class:`hlik.solvers.mink_tasks.CriterionTask` the frame's context, and integrates ``solve_ik``,
warm-started from the previous frame, iterated to convergence with the QP's rule, inside the
frame's joint box and (by default) clear of self-collision.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import mink
import numpy as np

from hlik.criteria.base import Sample
from hlik.criteria.learned import Learned
from hlik.errors import SettingsError
from hlik.problem.problem import Problem
from hlik.robot.model import SIDES, Robot
from hlik.solvers.base import SolverResult
from hlik.solvers.frames import FrameResult, JointBox, iterate, step_budget, track
from hlik.solvers.limits import LimitSettings, MotionLimits
from hlik.solvers.mink_tasks import BoxOnlyLimit, CriterionTask, FrameBoxLimit, SelfCollisionLimit, StateCache
from hlik.solvers.qp import QPSettings, build_terms


class MinkSolver:
    r"""A solver for :func:`hlik.retarget.retarget` from mink tasks and limits.

    Args:
        tasks: mink tasks; ``FrameTask`` on ``<side>_tcp`` sites follow the hands. The
            :class:`~hlik.solvers.mink_tasks.CriterionTask`\ s share one kinematics pass per step.
        limits: mink limits (e.g. ``ConfigurationLimit``, :class:`hlik.solvers.mink_tasks.HumanJointLimit`);
            each frame's joint box (:mod:`hlik.solvers.limits`, what every hlik solver keeps) is
            added as a :class:`hlik.solvers.mink_tasks.FrameBoxLimit`, and with ``self_collision``
            hlik's :class:`~hlik.solvers.mink_tasks.SelfCollisionLimit`.
        max_iter: ``solve_ik`` steps per frame at most (the first frame gets ten times more).
        tol: A frame has converged when no joint moves more than this in a step, rad (the QP's
            rule, :func:`~hlik.solvers.frames.iterate`, reversals damped).
        max_step: Bound on any joint's change in one step, rad.
        damping: Levenberg-Marquardt damping of ``solve_ik``.
        solver: qpsolvers backend.
        motion_limits: Stop margin, acceleration and torque limits of the frame box.
        self_collision: Keep the robot's collision geoms apart (the QP's rows and margins).
        first_tasks: The first frame's tasks (default: ``tasks``), e.g. without the criteria of
            motion, which have no past there.
        progress: Called with each frame index as it is solved.

    Where no step meets every limit, the step is solved again without the collision rows, then
    within the frame box's bounds without its torque rows, as the QP's soft rows give way
    (:func:`~hlik.solvers.frames.constrained_steps`; mink's limits are hard, so they give way
    whole). ``limits`` are kept in every try: a frame where no step keeps them fails (reported in
    the diagnostics), it never passes them silently. A ``mink.Limit`` sees positions only, so one
    tighter than a joint's stops cannot brake ahead of its bound as the frame box does: keep a
    margin of about v²/(2a) (the joint's speed and acceleration limits) or expect failed frames.
    """

    @classmethod
    def from_settings(
        cls,
        robot: Robot,
        settings: QPSettings,
        learned: Learned | None = None,
        tasks: Sequence[mink.Task] = (),
        limits: Sequence[mink.Limit] = (),
        progress: Callable[[int], None] | None = None,
    ) -> MinkSolver:
        """The QP solver's stack on mink: every term of :func:`hlik.solvers.qp.build_terms` (the TCP
        pose or relative pose terms, smoothness, trunk, the criteria, with the QP's weights) as a
        :class:`~hlik.solvers.mink_tasks.CriterionTask`, the first frame's stack as its own, and
        the QP's stopping rule, step bound, damping, limits and collision margins; ``tasks`` and
        ``limits`` (mink's own, or a user's) are added to every frame's.

        Raises:
            SettingsError: a hands' band (``position_band``, ``orientation_band``), which this stack
                has no rows for.
        """
        if settings.position_band > 0 or settings.orientation_band > 0:
            raise SettingsError("the hands' band has no mink form here; use --solver qp")
        cache = StateCache(robot)

        def stack(*args) -> list[mink.Task]:
            terms = build_terms(robot, settings, learned, *args)
            return [*(CriterionTask(robot, t, cache=cache) for t in terms), *tasks]

        return cls(
            stack(),
            limits,
            max_iter=settings.max_iter,
            tol=settings.tol,
            max_step=settings.max_step,
            damping=settings.damping,
            solver=settings.solver,
            motion_limits=settings,
            self_collision=settings.self_collision,
            first_tasks=stack("pose", True),
            progress=progress,
        )

    name = "mink"

    def __init__(
        self,
        tasks: Sequence[mink.Task],
        limits: Sequence[mink.Limit] = (),
        max_iter: int = 20,
        tol: float = 1e-4,
        max_step: float = 0.2,
        damping: float = 1e-6,
        solver: str = "daqp",
        motion_limits: LimitSettings | None = None,
        self_collision: bool = True,
        first_tasks: Sequence[mink.Task] | None = None,
        progress: Callable[[int], None] | None = None,
    ):
        self.progress = progress
        self.tasks, self.limits = list(tasks), list(limits)
        self.first_tasks = list(first_tasks) if first_tasks is not None else self.tasks
        self.motion_limits = motion_limits or LimitSettings()
        self.max_iter, self.tol, self.max_step = max_iter, tol, max_step
        self.damping, self.solver, self.self_collision = damping, solver, self_collision

    def __call__(self, problem: Problem) -> SolverResult:
        """Joint angles (T, n), each frame iterated to convergence from the previous one."""
        robot = problem.robot
        config = mink.Configuration(robot.model)
        hands = {f"{side}_tcp": i for i, side in enumerate(SIDES)}
        cache = StateCache(robot)
        for task in {id(t): t for t in (*self.tasks, *self.first_tasks)}.values():
            if isinstance(task, CriterionTask) and task.robot is robot:
                task.cache = cache
        frame_box = FrameBoxLimit(robot.dof, self.max_step)
        collision = SelfCollisionLimit(robot, cache=cache) if self.self_collision else None
        # the tries of a step: every limit; without the collision rows; the box's bounds without its
        # torque rows. The caller's limits stay in every try: where none keeps them the step fails.
        tries: list[list[mink.Limit]] = (
            [[*self.limits, frame_box, collision]] if collision is not None else []
        )
        tries += [[*self.limits, frame_box], [*self.limits, BoxOnlyLimit(frame_box)]]

        def solve_frame(k: int, sample: Sample, q: np.ndarray, box: JointBox) -> FrameResult:
            frame_box.set_box(box)
            if collision is not None:
                collision.set_box(box)
            tasks = self.first_tasks if k == 0 else self.tasks
            self._aim(tasks, hands, sample)

            def step(x: np.ndarray) -> np.ndarray | None:
                config.update(x)
                for limits in tries:
                    try:
                        v = mink.solve_ik(config, tasks, sample.dt, self.solver, self.damping, limits=limits)
                    except mink.exceptions.NoSolutionFound:
                        continue
                    return v * sample.dt
                return None

            steps = step_budget(k, self.max_iter)
            return iterate(step, q, box, steps, self.tol, damp_reversals=True)

        return track(problem, solve_frame, self.progress, MotionLimits.of(robot, self.motion_limits))

    @staticmethod
    def _aim(tasks: Sequence[mink.Task], hands: dict[str, int], sample: Sample) -> None:
        """Point the hands' ``FrameTask``\\ s at the frame's targets; give the criteria its context."""
        for task in tasks:
            if isinstance(task, mink.FrameTask) and task.frame_name in hands:
                i = hands[task.frame_name]
                rot = mink.SO3.from_matrix(sample.target_rot[0, i])
                task.set_target(mink.SE3.from_rotation_and_translation(rot, sample.target_pos[0, i]))
            elif isinstance(task, CriterionTask):
                task.set_sample(sample)
