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

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import mink
import numpy as np

from hlik.criteria import registry, unified
from hlik.criteria.base import Term
from hlik.criteria.elbows import ElbowsAhead
from hlik.criteria.functional import target_terms
from hlik.criteria.joints import TrunkUpright
from hlik.criteria.learned import Learned
from hlik.criteria.smoothness import smoothness_terms
from hlik.problem.problem import Problem
from hlik.robot.model import Robot
from hlik.solvers.base import ConfiguredSolver, SolverResult, check_settings
from hlik.solvers.frames import FIRST_FRAME_SCENARIO, first_frame_terms
from hlik.solvers.mink_ik import MinkSolver
from hlik.solvers.mink_tasks import CriterionTask, HandBandLimit, StateCache
from hlik.solvers.qp_backend import qp_backends
from hlik.solvers.settings import SolverSettings
from hlik.util.errors import SettingsError

# HJA_r's Table II gamma (2) doubled for the QP: beside SYN (gamma 6) it barely acted, and SYN +
# HJA_r raised 2-Panda's m_hl by 0.042; at 4 by 0.051 (README, quality table), tracking within 2 cm.
GAMMA: Mapping[str, float] = MappingProxyType({"HJA_r": 4.0})


@dataclass(frozen=True)
class QPSettings(SolverSettings):
    """The task stack, the stopping rule and the limits (:class:`LimitSettings`: stop margin,
    acceleration and torque limits).

    Attributes:
        criteria: Human-likeness criteria added to the stack (paper names).
        scenario: ``pose`` tracks both TCP poses; ``relative`` tracks the relative pose of the hands
            (paper Eqs. 3-4) and the TCP poses only at the first frame (Sec. V-B).
        position_cost, orientation_cost: TCP pose term weights, per metre and per radian.
        relative_position_cost, relative_orientation_cost: Relative pose weights (``relative``).
        gamma: Criterion name -> scaling weight, overriding the criterion's Table II gamma
            (:data:`GAMMA`: HJA_r's doubled).
        criterion_cost: Objective weight of the criteria: criterion i adds
            ``gamma_i * criterion_cost / len(criteria) * ||e_i||^2`` (divided by the number of
            criteria as in the paper; its least-squares cost is the square root).
        velocity_cost, acceleration_cost, jerk_cost: Weights of the smoothness terms.
        trunk_cost: Weight per rad of the extra (trunk) joints toward home
            (:class:`~hlik.criteria.joints.TrunkUpright`; 0: none; robots without them: no term).
        elbow_cost: Weight per metre of an elbow behind the shoulders' frontal plane by more than
            ``elbow_allowance`` (m) (:class:`~hlik.criteria.elbows.ElbowsAhead`; 0: none).
        damping: Levenberg-Marquardt damping of every step.
        max_iter: QP steps per frame at most (the first frame gets ten times more).
        tol: A frame has converged when no joint moves more than this in a step, rad.
        max_step: Bound on any joint's change in one step, rad.
        solver: qpsolvers backend.
        position_band, orientation_band: The hands' tolerance band, m and rad (0: none, the
            paper's weighted form): each target term's error after a step stays within it,
            component by component within band / sqrt(3) (so its norm within band), as linear
            inequalities below the body's; where no step can meet them, as near as the body's rows
            let a step come (:func:`~hlik.solvers.frames.nearest_band`); the criteria act inside.
        self_collision: Keep every pair of the robot's collision geoms ``collision_margin`` apart
            (m), as linear inequalities on the step from their signed distances and gradients
            (the velocity damper of mink's ``CollisionAvoidanceLimit``: a pair closer than
            ``collision_detect`` may approach by at most ``collision_gain`` of its distance to the
            margin per step).
    """

    gamma: Mapping[str, float] = field(default_factory=lambda: GAMMA)
    # hands first (issue 28; were 10 and 1): the criteria had bought m_hl by turning the hands
    # (tasks/ee_pose.toml and README "Hands first" have the measurements)
    position_cost: float = 30.0
    orientation_cost: float = 2.0
    relative_position_cost: float = 10.0
    relative_orientation_cost: float = 2.0
    criterion_cost: float = 0.05
    velocity_cost: float = 0.02
    acceleration_cost: float = 0.01
    jerk_cost: float = 0.005
    # ARMAR-III's hip upright (issue 28; tasks/ee_pose.toml and README "Trunk upright" say why 2)
    trunk_cost: float = 2.0
    # 2-Panda's elbows out from behind its back (issue 28; tasks/ee_pose.toml says why 10)
    elbow_cost: float = 10.0
    elbow_allowance: float = 0.02
    position_band: float = 0.0
    orientation_band: float = 0.0
    damping: float = 1e-6
    max_iter: int = 20
    tol: float = 1e-4
    max_step: float = 0.2
    solver: str = "daqp"
    collision_gain: float = 0.5

    def __post_init__(self):
        check_settings(
            self,
            at_least_zero=("position_band", "orientation_band", "damping", "elbow_allowance"),
            positive=("tol", "max_step"),
            fractions=("collision_gain",),
            counts=("max_iter",),
        )
        if self.solver not in qp_backends():
            raise SettingsError(
                f"QPSettings.solver {self.solver!r} is not an installed QP solver; "
                f"choose one of: {', '.join(qp_backends())}"
            )


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
    for name in settings.criteria:
        term = registry.criterion(name, robot, learned)
        # the objective weighs ||e_i||^2 by gamma_i * criterion_cost / k, as the paper weighs h_i
        weight = unified.gamma(name, settings.gamma) * settings.criterion_cost / len(settings.criteria)
        terms.append((term, float(np.sqrt(weight))))
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
    or a user's) are added to every frame's."""
    cache = StateCache(robot)

    def stack(*args) -> list[mink.Task]:
        terms = build_terms(robot, settings, learned, *args)
        return [*(CriterionTask(robot, t, cost, cache=cache) for t, cost in terms), *tasks]

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
    )


def solve(
    problem: Problem,
    settings: QPSettings = QPSettings(),
    progress: Callable[[int], None] | None = None,
) -> SolverResult:
    """Retarget frame by frame (:func:`build_solver`); diagnostics count the QP steps per frame."""
    return build_solver(problem.robot, settings, problem.learned, progress=progress)(problem)


def qp_solver(
    settings: QPSettings = QPSettings(),
    progress: Callable[[int], None] | None = None,
) -> ConfiguredSolver:
    """The QP solver with the given settings, for :func:`hlik.retarget.retarget`."""
    return ConfiguredSolver("qp", solve, settings, progress)
