"""QP retargeting: per frame, repeated convex QP steps over a stack of least-squares terms.

Each step minimises ``sum_i ||c_i (J_i dq + e_i)||^2 + damping ||dq||^2`` subject to the joint
limits (and a step bound), the stack being the two TCP pose terms, smoothness toward the previous
frames and the chosen human-likeness criteria (:mod:`hlik.terms`). All residuals and Jacobians come
from one forward-kinematics pass and are stacked into a single problem for the QP solver (daqp by
default), so no per-task Python objects are built per step. Frames are warm-started from the
previous solution; a frame stops when the step is below ``tol`` or after ``max_iter`` steps.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import mujoco
import numpy as np

from hlik.criteria import registry, unified
from hlik.criteria.base import Sample, Term
from hlik.criteria.functional import target_terms
from hlik.criteria.joints import TrunkUpright
from hlik.criteria.learned import Learned
from hlik.criteria.smoothness import smoothness_terms
from hlik.errors import SettingsError
from hlik.problem.problem import Problem
from hlik.robot.collision import CollisionPairs, DistanceBounds, collision_pairs
from hlik.robot.model import Robot
from hlik.robot.state import robot_state
from hlik.solvers.base import ConfiguredSolver, SolverResult, check_settings
from hlik.solvers.frames import (
    FrameResult,
    JointBox,
    collision_floors,
    collision_rows,
    constrained_steps,
    hand_band,
    iterate,
    nearest_band,
    step_budget,
    track,
)
from hlik.solvers.limits import MotionLimits
from hlik.solvers.qp_backend import qp_backends, solve_qp
from hlik.solvers.settings import SolverSettings

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
            (:class:`~hlik.criteria.joints.TrunkUpright`; 0: none).
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
    trunk_cost: float = 0.0
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
            at_least_zero=("position_band", "orientation_band", "damping"),
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
    scenario: str | None = None,
    first: bool = False,
) -> list[Term]:
    """The stack of ``settings`` for ``robot``: targets, smoothness, criteria with their weights.

    ``scenario`` overrides ``settings.scenario`` (the first frame of ``relative`` uses ``pose``);
    ``first``: the first frame's stack, without the criteria of motion (``Criterion.motion``).
    """
    scenario = scenario or settings.scenario
    position, orientation = target_terms(scenario)
    if scenario == "relative":
        position.cost_weight = settings.relative_position_cost
        orientation.cost_weight = settings.relative_orientation_cost
    else:
        position.cost_weight, orientation.cost_weight = settings.position_cost, settings.orientation_cost
    terms: list[Term] = [t for t in (position, orientation) if np.all(np.asarray(t.cost_weight) > 0)]
    terms += smoothness_terms(robot, settings.velocity_cost, settings.acceleration_cost, settings.jerk_cost)
    if settings.trunk_cost > 0 and robot.extra_joints:
        trunk = TrunkUpright(robot)
        trunk.cost_weight = settings.trunk_cost
        terms.append(trunk)
    for name in settings.criteria:
        term = registry.criterion(name, robot, learned)
        if first and term.motion:
            continue
        # the objective weighs ||e_i||^2 by gamma_i * criterion_cost / k, as the paper weighs h_i
        weight = unified.gamma(name, settings.gamma) * settings.criterion_cost / len(settings.criteria)
        term.cost_weight = float(np.sqrt(weight))
        terms.append(term)
    return terms


class Assembly:
    """A stack prepared for repeated QP steps.

    Terms with a constant Jacobian contribute a constant ``J^T W^2 J`` to the Hessian, summed once
    here; per step they only add ``J^T W^2 e`` to the gradient. The other terms are stacked.
    """

    def __init__(self, terms: Sequence[Term], n: int, damping: float):
        self.terms = tuple(terms)
        self.sites = tuple(sorted({i for term in terms for i in term.sites}))
        self.hessian = damping * np.eye(n)
        self.weights, self.gradient_maps = [], []
        for term in self.terms:
            w = np.asarray(term.cost_weight, dtype=float)
            jac = term.constant_jacobian
            self.weights.append(w[:, None] if w.ndim else w)
            self.gradient_maps.append(None if jac is None else (np.square(self.weights[-1]) * jac).T)
            if jac is not None:
                self.hessian += self.gradient_maps[-1] @ jac


def step(
    robot: Robot,
    stack: Assembly,
    q: np.ndarray,
    frame: Sample,
    settings: QPSettings,
    data: mujoco.MjData | None = None,
    box: JointBox | None = None,
    pairs: CollisionPairs | None = None,
    bounds: DistanceBounds | None = None,
    floors: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray | None:
    """One QP step from ``q`` (n,) within ``box`` (default: the joint limits), keeping the collision
    ``pairs`` apart (none closer than its ``floors``, :func:`~hlik.solvers.frames.collision_floors`):
    the joint change dq (n,), or None where the QP solver found none. Reuse ``data`` and the pairs'
    distance ``bounds`` across steps."""
    data = mujoco.MjData(robot.model) if data is None else data
    state = robot_state(robot, q, jacobians=bool(stack.sites), data=data, jacobian_sites=stack.sites)
    gradient = np.zeros(robot.dof)
    rows, errors = [], []
    band_rows, band_bounds = [], []
    for term, w, gradient_map in zip(stack.terms, stack.weights, stack.gradient_maps):
        e, jac = term(state, frame)
        band = hand_band(term, settings) / np.sqrt(3.0)  # per component: the norm within the band
        if band > 0.0:  # -b <= e + J dq <= b per component, in the term's weighted units
            wj, we, wb = w * jac, w.ravel() * e, w.ravel() * band
            band_rows += [wj, -wj]
            band_bounds += [wb - we, wb + we]
        if gradient_map is not None:
            gradient += gradient_map @ e
        else:
            rows.append(w * jac)
            errors.append(w.ravel() * e)
    hessian = stack.hessian
    if rows:
        a = np.vstack(rows)
        hessian = hessian + a.T @ a
        gradient += a.T @ np.concatenate(errors)
    box = box or JointBox(robot.lower, robot.upper)
    a_col, b_col = np.zeros((0, robot.dof)), np.zeros(0)
    if pairs is not None and len(pairs):
        a_col, b_col = collision_rows(robot, data, pairs, bounds, settings, floors)  # q's kinematics in data
    dq = None
    a_band = np.vstack(band_rows) if band_rows else None
    b_band = np.concatenate(band_bounds) if band_rows else None
    tries = constrained_steps(box, q, settings.max_step, a_col, b_col, a_band, b_band)
    for k, c in enumerate(tries):
        dq = solve_qp(hessian, gradient, c.lower, c.upper, settings.solver, c.rows, c.bound, c.soft)
        if dq is None and k == 0 and b_band is not None:  # the band out of reach: as near as the body allows
            nearest = nearest_band(c, len(b_band), settings.solver)
            if nearest is not None:
                dq = solve_qp(hessian, gradient, c.lower, c.upper, settings.solver, c.rows, nearest)
        if dq is not None:
            break
    if dq is None or not np.all(np.isfinite(dq)):
        return None  # no step found: the frame stays where it is, failed (limits hold, nothing NaN)
    return dq


def solve(
    problem: Problem,
    settings: QPSettings = QPSettings(),
    progress: Callable[[int], None] | None = None,
) -> SolverResult:
    """Retarget frame by frame; diagnostics count the QP steps per frame."""
    robot, learned = problem.robot, problem.learned
    terms = Assembly(build_terms(robot, settings, learned), robot.dof, settings.damping)
    first = Assembly(build_terms(robot, settings, learned, "pose", first=True), robot.dof, settings.damping)
    data = mujoco.MjData(robot.model)
    pairs = collision_pairs(robot) if settings.self_collision else None
    bounds = DistanceBounds(pairs) if pairs is not None else None

    def solve_frame(k: int, frame: Sample, q: np.ndarray, box: JointBox) -> FrameResult:
        stack = first if k == 0 else terms
        max_iter = step_budget(k, settings.max_iter)
        floors = collision_floors(robot, data, pairs, box, settings, bounds)
        return iterate(
            lambda x: step(robot, stack, x, frame, settings, data, box, pairs, bounds, floors),
            q,
            box,
            max_iter,
            settings.tol,
            damp_reversals=True,
        )

    return track(problem, solve_frame, progress, MotionLimits.of(robot, settings))


def qp_solver(
    settings: QPSettings = QPSettings(),
    progress: Callable[[int], None] | None = None,
) -> ConfiguredSolver:
    """The QP solver with the given settings, for :func:`hlik.retarget.retarget`."""
    return ConfiguredSolver("qp", solve, settings, progress)
