"""QP retargeting: per frame, repeated convex QP steps over a stack of least-squares terms, on mink.

Each step minimises ``sum_i ||c_i (J_i dq + e_i)||^2 + damping ||dq||^2`` subject to the frame's
joint box (stops, speed, acceleration, torque), a step bound, self-collision rows and the hands'
band if set; the stack is the two TCP pose terms (or the hands' relative pose), smoothness toward
the previous frames and the chosen human-likeness criteria, each a ``mink.Task``
(:class:`~hlik.solvers.mink_tasks.CriterionTask`), solved by :class:`~hlik.solvers.mink_ik.MinkSolver`
(mink's ``build_ik``, daqp by default). Frames are warm-started from the previous solution; a frame
stops when no joint moves more than ``tol`` in a step or after ``max_iter`` steps.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial

import mink
import numpy as np

from hlik.criteria import unified
from hlik.criteria.base import Term
from hlik.criteria.elbows import ElbowsAhead
from hlik.criteria.functional import HAND_TERMS, target_terms
from hlik.criteria.joints import TrunkUpright
from hlik.criteria.learned import Learned
from hlik.criteria.smoothness import Smoothness, smoothness_terms
from hlik.problem.problem import Problem
from hlik.robot.model import Robot
from hlik.solvers.base import ConfiguredSolver, SolverResult
from hlik.solvers.frames import FIRST_FRAME_SCENARIO, first_frame_terms
from hlik.solvers.mink_ik import MinkSolver, is_hand_task
from hlik.solvers.mink_tasks import CriterionTask, HandBandLimit, StateCache
from hlik.solvers.preview import PathTask, solve_with_look_ahead
from hlik.solvers.settings import QPSettings

# the terms a hands-first QP (``hands_first``) solves before the criteria, trunk and elbow terms
HANDS_FIRST = (*HAND_TERMS, Smoothness)


def build_terms(
    robot: Robot,
    settings: QPSettings,
    learned: Learned | None,
    first: bool = False,
) -> list[tuple[Term, float]]:
    """The stack of ``settings`` for ``robot``: targets, smoothness, criteria, each with its weight
    (the cost of its least-squares residual: ``||weight * e||^2`` in the objective).

    ``first``: the first frame's stack (:func:`~hlik.solvers.frames.first_frame_terms`: the TCP
    poses, no term of motion).
    """
    scenario = FIRST_FRAME_SCENARIO if first else settings.scenario
    position, orientation = target_terms(scenario)
    if scenario == "relative":
        hands = [
            (position, settings.relative_position_cost),
            (orientation, settings.relative_orientation_cost),
        ]
    else:
        hands = [(position, settings.position_cost), (orientation, settings.orientation_cost)]
    terms: list[tuple[Term, float]] = [(t, w) for t, w in hands if w > 0]
    terms += smoothness_terms(robot, settings.velocity_cost, settings.acceleration_cost, settings.jerk_cost)
    if settings.trunk_cost > 0 and robot.extra_joints:
        terms.append((TrunkUpright(robot), settings.trunk_cost))
    if settings.elbow_cost > 0:
        terms.append((ElbowsAhead(settings.elbow_allowance), settings.elbow_cost))
    # the objective weighs ||e_i||^2 by gamma_i * criterion_cost / k, as the paper weighs h_i
    weighted = unified.weighted_criteria(
        settings.criteria, robot, learned, settings.criterion_cost, settings.gamma
    )
    terms += [(term, float(np.sqrt(weight))) for term, weight in weighted]
    return first_frame_terms(terms) if first else terms


def build_solver(
    robot: Robot,
    settings: QPSettings = QPSettings(),
    learned: Learned | None = None,
    tasks: Sequence[mink.Task] = (),
    limits: Sequence[mink.Limit] = (),
    progress: Callable[[int], None] | None = None,
) -> MinkSolver:
    """The QP's stack on mink: every term of :func:`build_terms` (the TCP pose or relative pose
    terms, smoothness, trunk, the criteria, with their weights) as a
    :class:`~hlik.solvers.mink_tasks.CriterionTask`, the first frame's stack as its own, the hands'
    band as a :class:`~hlik.solvers.mink_tasks.HandBandLimit`, and the stopping rule, step bound,
    damping, limits and collision margins of ``settings``; ``tasks`` and ``limits`` (mink's own,
    or a user's) are added to every frame's. With ``settings.hands_first`` every term and task but
    the hands', smoothness and the look-ahead is the solver's ``posture``, solved in the hands'
    null space."""
    cache = StateCache(robot)

    posture: list[mink.Task] = []

    def damped(term: Term) -> float:  # the hands' targets damp their own steps out of reach
        return settings.error_damping if isinstance(term, HAND_TERMS) else 0.0

    def stack(*args) -> list[mink.Task]:
        weighted = build_terms(robot, settings, learned, *args)
        terms = [
            (t, CriterionTask(robot, t, cost, lm_damping=damped(t), cache=cache)) for t, cost in weighted
        ]
        # what shapes the arms after the hands: all but the hands' and the smoothness terms
        posture.extend(task for t, task in terms if not isinstance(t, HANDS_FIRST))
        posture.extend(t for t in tasks if not isinstance(t, PathTask) and not is_hand_task(t))
        return [*(task for _, task in terms), *tasks]

    band = settings.position_band > 0 or settings.orientation_band > 0
    return MinkSolver(
        stack(),
        [*limits, *([HandBandLimit(settings.position_band, settings.orientation_band)] if band else [])],
        max_iter=settings.max_iter,
        tol=settings.tol,
        max_step=settings.max_step,
        damping=settings.damping,
        solver=settings.solver,
        motion_limits=settings,
        self_collision=settings.self_collision,
        first_tasks=stack(True),
        progress=progress,
        collision_margin=settings.collision_margin,
        collision_detect=settings.collision_detect,
        collision_gain=settings.collision_gain,
        posture=posture if settings.hands_first else (),
    )


def solve(
    problem: Problem,
    settings: QPSettings = QPSettings(),
    progress: Callable[[int], None] | None = None,
    tasks: Sequence[mink.Task] = (),
    limits: Sequence[mink.Limit] = (),
) -> SolverResult:
    """Retarget frame by frame (:func:`build_solver`, with ``tasks`` and ``limits`` added);
    diagnostics count the QP steps per frame. With ``settings.preview_cost`` the take is solved
    twice (:mod:`hlik.solvers.preview`): first without the acceleration and torque limits, then
    with every limit and a :class:`~hlik.solvers.preview.PathTask` toward the nearest path that
    keeps them; the diagnostics are the second pass's. ``settings.preview_hands_first`` holds the
    hands first in the first pass only."""
    robot, learned = problem.robot, problem.learned

    def solve_pass(s: QPSettings, progress, path: np.ndarray | None) -> SolverResult:
        toward = [] if path is None else [PathTask(robot.model, path, s.preview_cost)]
        return build_solver(robot, s, learned, [*tasks, *toward], limits, progress)(problem)

    hands_first = settings.hands_first or settings.preview_hands_first
    return solve_with_look_ahead(problem, settings, solve_pass, progress, hands_first=hands_first)


def qp_solver(
    settings: QPSettings = QPSettings(),
    progress: Callable[[int], None] | None = None,
    limits: Sequence[mink.Limit] = (),
) -> ConfiguredSolver:
    """The QP solver with the given settings (and a caller's ``mink.Limit``\\ s), for
    :func:`hlik.retarget.retarget`."""
    return ConfiguredSolver("qp", partial(solve, limits=limits) if limits else solve, settings, progress)
