"""Retarget with mink: per frame, mink's QP over any mix of mink's tasks and hlik's criterion tasks.

:class:`MinkSolver` is the one per-frame QP of hlik (``--solver qp`` is it with the QP's stack,
:func:`hlik.solvers.qp.build_solver`; ``--solver mink`` that stack with a stack file's own mink
tasks and limits). Per frame it points every ``mink.FrameTask`` on a ``left_tcp`` / ``right_tcp``
site at the hand targets, gives every :class:`hlik.solvers.mink_tasks.CriterionTask` the frame's
context, and steps from the previous frame's solution until it converges, each step mink's
objective (``mink.build_ik``) under the frame's joint box, the limits, self-collision rows and the
hands' band, with the rows that give way where no step keeps them all
(:func:`hlik.solvers.frames.constrained_steps`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import mink
import numpy as np

from hlik.criteria.base import Sample
from hlik.criteria.functional import HAND_TERMS
from hlik.problem.problem import Problem
from hlik.robot.model import SIDES
from hlik.solvers.base import SolverResult
from hlik.solvers.frames import (
    FrameResult,
    JointBox,
    StepConstraints,
    constrained_steps,
    iterate,
    limit_rows,
    solve_step,
    step_budget,
    track,
)
from hlik.solvers.limits import MotionLimits
from hlik.solvers.mink_specs import on_a_tcp
from hlik.solvers.mink_tasks import CriterionTask, HandBandLimit, SelfCollisionLimit, StateCache
from hlik.solvers.preview import PathTask
from hlik.solvers.qp_backend import solve_qp
from hlik.solvers.settings import LimitSettings


class MinkSolver:
    r"""A solver for :func:`hlik.retarget.retarget` from mink tasks and limits.

    Args:
        tasks: mink tasks; ``FrameTask`` on ``<side>_tcp`` sites follow the hands. The
            :class:`~hlik.solvers.mink_tasks.CriterionTask`\ s share one kinematics pass per step.
        limits: mink limits (e.g. ``ConfigurationLimit``, :class:`hlik.solvers.mink_tasks.HumanJointLimit`),
            kept wherever a step can keep them (the last fallback gives way on them, below); a
            :class:`~hlik.solvers.mink_tasks.HandBandLimit` is the hands' band, kept where a step
            can and otherwise as nearly as the rest allows. Each frame's
            joint box (:mod:`hlik.solvers.limits`, what every hlik solver keeps: stops with their
            margin, speed, acceleration, braking, torque) bounds every step.
        max_iter: Steps per frame at most (the first frame gets ten times more).
        tol: A frame has converged when no joint moves more than this in a step, rad
            (:func:`~hlik.solvers.frames.iterate`, reversals damped).
        max_step: Bound on any joint's change in one step, rad.
        damping: Levenberg-Marquardt damping of every step (``mink.build_ik``).
        solver: QP backend (:func:`hlik.solvers.qp_backend.solve_qp`: daqp, or a qpsolvers name).
        motion_limits: Stop margin, acceleration and torque limits of the frame box.
        self_collision: Keep the robot's collision geoms apart
            (:class:`~hlik.solvers.mink_tasks.SelfCollisionLimit`, the velocity damper with braking).
        collision_margin, collision_detect, collision_gain: Its margin and how near a pair is
            looked at, m, and the share of the gap a pair may close per step (the QP's settings).
        first_tasks: The first frame's tasks (default: ``tasks``), e.g. without the criteria of
            motion, which have no past there.
        progress: Called with each frame index as it is solved.
        posture: Tasks (among ``tasks`` and ``first_tasks``) that shape the arms after the hands,
            a strict priority: each step first solves the other tasks alone, then adds these
            and keeps what that first step does to the hands (every hand task's ``J dq``, within
            :data:`HELD`), so that they act in the hands' null space only
            (:func:`hands_first_step`). Empty: one weighted QP of every task.

    Where no step keeps every row, the collision rows give way first (missed as little as the rest
    allows), then the box's torque rows, and last ``limits``' rows, in a frame then reported failed
    (:func:`~hlik.solvers.frames.constrained_steps`); the box's bounds hold in every step. A
    ``mink.Limit`` sees positions only: a joint may arrive at its row faster than its acceleration
    limit can stop it there, and then brakes past it as hard as the box allows. Put the row about
    v²/(2a) (the joint's speed and acceleration limits) inside the bound that must hold.
    """

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
        collision_margin: float = 0.01,
        collision_detect: float = 0.10,
        collision_gain: float = 0.5,
        posture: Sequence[mink.Task] = (),
    ):
        self.posture = {id(t) for t in posture}
        self.progress = progress
        self.tasks, self.limits = list(tasks), list(limits)
        self.first_tasks = list(first_tasks) if first_tasks is not None else self.tasks
        self.motion_limits = motion_limits or LimitSettings()
        self.max_iter, self.tol, self.max_step = max_iter, tol, max_step
        self.damping, self.solver, self.self_collision = damping, solver, self_collision
        self.collision = (collision_margin, collision_detect, collision_gain)

    def __call__(self, problem: Problem) -> SolverResult:
        """Joint angles (T, n), each frame iterated to convergence from the previous one."""
        robot = problem.robot
        config = mink.Configuration(robot.model)
        hands = {f"{side}_tcp": i for i, side in enumerate(SIDES)}
        criteria = [
            t
            for t in {id(t): t for t in (*self.tasks, *self.first_tasks)}.values()
            if isinstance(t, CriterionTask) and t.robot is robot
        ]
        # one kinematics pass per step for every criterion task, with the site Jacobians they read
        cache = StateCache(robot, tuple(sorted({i for t in criteria for i in t.term.sites})))
        for task in criteria:
            task.cache = cache
        collision = SelfCollisionLimit(robot, *self.collision) if self.self_collision else None
        band = [lim for lim in self.limits if isinstance(lim, HandBandLimit)]
        hard = [lim for lim in self.limits if not isinstance(lim, HandBandLimit)]
        n = robot.dof

        def solve_frame(k: int, sample: Sample, q: np.ndarray, box: JointBox) -> FrameResult:
            if collision is not None:
                collision.set_box(box)
            tasks = self.first_tasks if k == 0 else self.tasks
            self._aim(tasks, hands, sample, k)
            for limit in band:
                limit.set_tasks(tasks)
            missed = False  # a step gave way on the caller's limits
            first = [t for t in tasks if id(t) not in self.posture]  # every task without a posture
            after = [t for t in tasks if id(t) in self.posture]

            def step(x: np.ndarray) -> np.ndarray | None:
                config.update(x)
                objective = mink.build_ik(config, first, sample.dt, self.damping, limits=[])
                a_hard, b_hard = limit_rows(hard, config, sample.dt, n)
                a_col, b_col = limit_rows([collision] if collision else [], config, sample.dt, n)
                a_band, b_band = limit_rows(band, config, sample.dt, n)
                tries = constrained_steps(box, x, self.max_step, a_col, b_col, a_band, b_band, a_hard, b_hard)
                dq, taken = solve_step(objective.P, objective.q, tries, self.solver, len(b_band))
                if after and dq is not None and taken is not None:
                    # the whole stack's objective: the first level's plus the posture's (each task's
                    # rows evaluated once, the damping once)
                    rest = mink.build_ik(config, after, sample.dt, 0.0, limits=[])
                    whole = (objective.P + rest.P, objective.q + rest.q)
                    dq = hands_first_step(*whole, dq, taken, hand_rows(config, first), self.solver)
                if taken is not None and taken.misses_limits:
                    nonlocal missed
                    missed = True
                return dq

            steps = step_budget(k, self.max_iter)
            result = iterate(step, q, box, steps, self.tol, damp_reversals=True)
            return replace(result, converged=False, failed=True) if missed else result

        return track(problem, solve_frame, self.progress, MotionLimits.of(robot, self.motion_limits))

    @staticmethod
    def _aim(tasks: Sequence[mink.Task], hands: dict[str, int], sample: Sample, k: int) -> None:
        """Point the hands' ``FrameTask``\\ s at frame ``k``'s targets and a ``PathTask`` at its
        configuration; give the criteria its context."""
        for task in tasks:
            if isinstance(task, mink.FrameTask) and task.frame_name in hands:
                i = hands[task.frame_name]
                rot = mink.SO3.from_matrix(sample.target_rot[0, i])
                task.set_target(mink.SE3.from_rotation_and_translation(rot, sample.target_pos[0, i]))
            elif isinstance(task, CriterionTask):
                task.set_sample(sample)
            elif isinstance(task, PathTask):
                task.at(k)


# rad or m per step: how far the second level of a hands-first step may move a hand task's rows
# (J dq) from the first level's; roundoff room, so that the second QP is feasible where the first was
HELD = 1e-5


def hand_rows(config: mink.Configuration, tasks: Sequence[mink.Task]) -> np.ndarray:
    """(k, n) the Jacobians of the hand tasks among ``tasks`` (:func:`is_hand_task`)."""
    rows = [t.compute_jacobian(config) for t in tasks if is_hand_task(t)]
    return np.vstack([np.zeros((0, config.model.nv)), *rows])


def is_hand_task(task: mink.Task) -> bool:
    """A task on the hands' pose: a :class:`CriterionTask` on a target term (fPOS, fORI and their
    relative forms) or a mink ``FrameTask`` on a TCP site."""
    if isinstance(task, CriterionTask):
        return isinstance(task.term, HAND_TERMS)
    return on_a_tcp(task)


def hands_first_step(
    hessian: np.ndarray,
    gradient: np.ndarray,
    first: np.ndarray,
    taken: StepConstraints,
    held: np.ndarray,
    solver: str,
) -> np.ndarray:
    """The second level of a hands-first step: the step (n,) minimising the whole stack's
    ``1/2 dq' H dq + g' dq`` under the constraints the first level's step ``first`` met
    (``taken``), with the hands' rows ``held`` (k, n) moving as in ``first`` (within
    :data:`HELD`): the posture tasks act in the hands' null space. ``first`` where that QP fails."""
    if not len(held):
        return first
    target = held @ first
    rows = np.vstack([taken.rows, held, -held])
    bound = np.concatenate([taken.bound, target + HELD, -target + HELD])
    soft = None if taken.soft is None else np.concatenate([taken.soft, np.zeros(2 * len(held))])
    dq = solve_qp(hessian, gradient, taken.lower, taken.upper, solver, rows, bound, soft)
    return first if dq is None or not np.all(np.isfinite(dq)) else dq
