"""JV: the paper's Jacobian velocity controller (Sec. IV-B), the baseline the QP replaces.

Per step, the TCP targets are the primary task, solved by Chan & Dubey's weighted least-norm
solution with damping (joints moving toward a limit are weighted down); the chosen human-likeness
criteria and Chan & Dubey's joint-limit criterion H are the secondary task, their weighted gradient
projected onto the null space of the target Jacobian (gradient projection; formulas §5):

    dq = W⁻¹Jᵀ(J W⁻¹Jᵀ + λ²I)⁻¹ (-step e) + bound(k N ∇(Σ w_i h_i + w_H H)),

the whole capped to ``max_step`` and clipped into the joint limits. Frames are warm-started from
the previous solution; a frame stops when no joint moves more than ``tol``, after ``max_iter``
steps, or (``paper_opt.toml``, as the paper's) once its targets are reached, after its first step.
The criterion gradients are the analytic ones of :mod:`hlik.terms` (the paper uses finite
differences).

Self-collision avoidance (not in the paper) is the task of highest priority, with the QP's velocity
damper on the signed distances of :mod:`hlik.robot.collision`: a step that keeps every pair of
collision geoms apart is taken as it is; one that would bring a pair closer than the damper allows is
replaced by the same damped least-squares step on the targets solved subject to the damper rows (a
small QP), with the null-space term in the null space of the targets and of the rows it holds. Its
fixed point is a stationary point of the tracking error on the body's surface, so the hand slides
along the body and the frame converges (a projection of the free step onto the rows would not: it
depends on Chan & Dubey's weights, which flip as the cut step turns back, and cycles).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import partial

import mink
import mujoco
import numpy as np

from hlik.criteria import unified
from hlik.criteria.base import Sample, Term
from hlik.criteria.functional import fORI, fORI_off, target_terms
from hlik.problem.problem import Problem
from hlik.robot.model import Robot
from hlik.robot.state import RobotState, robot_state
from hlik.solvers.base import ConfiguredSolver, SolverResult
from hlik.solvers.frames import (
    FIRST_FRAME_SCENARIO,
    FrameResult,
    JointBox,
    StepConstraints,
    constrained_steps,
    first_frame_terms,
    iterate,
    limit_rows,
    step_budget,
    track,
)
from hlik.solvers.gradients import gradient, part_metric
from hlik.solvers.limits import MotionLimits
from hlik.solvers.mink_tasks import SelfCollisionLimit
from hlik.solvers.qp_backend import solve_qp
from hlik.solvers.settings import JVSettings


@dataclass(frozen=True, eq=False)
class Memory:
    """What a step keeps for the next one.

    Attributes:
        jla: (n,) dH/dq, to tell the joints moving toward a limit (weights W).
        null: (n,) the null-space step taken, to tell a reversal.
        null_bound: The current bound on the null-space step, rad (at each frame twice the last
            frame's, within ``NULL_FLOOR * max_null`` and ``max_null``).
        constrained: A step of this frame met the rows only by the constrained step, so the later
            ones take it too (else the free and the constrained steps took turns, a two-cycle
            until the iteration cap in 13 % of ARMAR-III's frames beside its hip).
        missed: A step of this frame gave way on a caller's limits (the frame is then failed).
    """

    jla: np.ndarray
    null: np.ndarray
    null_bound: float
    constrained: bool = False
    missed: bool = False


def chan_dubey(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[float, np.ndarray]:
    """Chan & Dubey's joint-limit criterion H (Eq. 11) and its gradient dH/dq (n,) at ``q`` (n,).

    ``H = sum_i (u_i - l_i)² / (4 (u_i - q_i)(q_i - l_i))``: 1 per joint at the centre of its
    range, infinite at the limits. Unlimited joints (infinite bounds) contribute nothing. Distances
    to the limits are floored at 1e-6 of the range, so a joint clipped onto a limit gives a huge but
    finite value.
    """
    limited = np.isfinite(lower) & np.isfinite(upper)
    lo, hi, x = lower[limited], upper[limited], q[limited]
    span = hi - lo
    to_hi, to_lo = np.maximum(hi - x, 1e-6 * span), np.maximum(x - lo, 1e-6 * span)
    grad = np.zeros(len(q))
    grad[limited] = span**2 * (to_lo - to_hi) / (4.0 * to_hi**2 * to_lo**2)
    return float(np.sum(span**2 / (4.0 * to_hi * to_lo))), grad


def limit_weights(grad: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """Chan & Dubey's diagonal W (Eq. 13), (n,): 1 + |dH/dq_i| where |dH/dq_i| did not fall since
    the previous step (moving toward a limit), else 1. ``grad``, ``previous``: dH/dq (n,).

    A joint that did not move keeps the weight of one moving toward its limit whatever the rounding
    of |dH/dq| (a fall of 1e-16 turned its weight from 1 + |dH/dq| to 1 in one run and not the other).
    """
    return np.where(np.abs(grad) >= np.abs(previous) * (1.0 - 1e-9), 1.0 + np.abs(grad), 1.0)


def weighted_least_norm(jac: np.ndarray, xdot: np.ndarray, weights: np.ndarray, damping: float) -> np.ndarray:
    """qdot (n,) = W⁻¹Jᵀ(J W⁻¹Jᵀ + λ²I)⁻¹ xdot for J (m, n), xdot (m,), diagonal W (n,).

    An infinite weight takes its joint out of the solution.
    """
    scaled = jac / weights  # J W⁻¹
    gram = scaled @ jac.T
    gram.flat[:: len(gram) + 1] += damping**2  # the diagonal (np.diag_indices_from costs 30 µs)
    return scaled.T @ np.linalg.solve(gram, xdot)


def clamped_least_norm(
    jac: np.ndarray, xdot: np.ndarray, weights: np.ndarray, damping: float, q: np.ndarray, box: JointBox
) -> np.ndarray:
    """:func:`weighted_least_norm` within ``box`` (the joint limits, or the frame's box): where
    the free step leaves it, the least-squares step inside it (:func:`avoiding_least_norm`).

    Clipping the free step leaves a residual the rest of the arm never compensates; holding the
    joints it pushes past a bound and solving again for the others (an active set that only
    grows) ends on a corner of the box where no joint can move: on 2-Panda, whose acceleration
    limits leave a box 2-8 mrad wide per frame, the hands lagged more than 5 cm in half the frames.
    """
    qdot = weighted_least_norm(jac, xdot, weights, damping)
    if np.all((q + qdot >= box.lower) & (q + qdot <= box.upper)):
        return qdot
    lower, upper = np.minimum(box.lower - q, 0.0), np.maximum(box.upper - q, 0.0)
    empty = np.zeros((0, len(q)))
    inside = avoiding_least_norm(jac, xdot, weights, damping, empty, np.zeros(0), lower, upper)
    return np.clip(qdot, lower, upper) if inside is None else inside


def _fraction_inside(q: np.ndarray, step: np.ndarray, box: JointBox) -> float:
    """The largest s in [0, 1] with ``q + s step`` inside ``box`` where ``q`` is (joints outside
    already do not count). Components under :data:`AT_BOUND` are rounding (a null-space step's
    1e-17 on a held joint) and do not count: pointed out of the box from a joint on its bound,
    they would stop the whole step."""
    with np.errstate(divide="ignore", invalid="ignore"):
        out, back = step > AT_BOUND, step < -AT_BOUND
        room = np.where(out, (box.upper - q) / step, np.where(back, (box.lower - q) / step, np.inf))
    return min(max(float(np.min(room, initial=1.0)), 0.0), 1.0)


def null_space_projector(jac: np.ndarray, rcond: float = 1e-6) -> np.ndarray:
    """(n, n) orthogonal projector N onto the null space of J (m, n), from its SVD.

    Unlike ``I - J⁺J`` with a damped inverse, ``J N = 0`` up to the singular values counted as null
    (below ``rcond`` times the largest), so the secondary task leaves the primary alone to first order.
    """
    _, s, vt = np.linalg.svd(jac, full_matrices=False)
    rows = vt[s > rcond * s.max(initial=0.0)]
    return np.eye(jac.shape[1]) - rows.T @ rows


def bound(v: np.ndarray, limit: float) -> np.ndarray:
    """``v`` scaled down uniformly so that max|v_i| <= limit (its direction kept)."""
    largest = np.max(np.abs(v), initial=0.0)
    return v * (limit / largest) if largest > limit else v


def avoiding_least_norm(
    jac: np.ndarray,
    xdot: np.ndarray,
    weights: np.ndarray,
    damping: float,
    rows: np.ndarray,
    rhs: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    soft: np.ndarray | None = None,
) -> np.ndarray | None:
    """:func:`weighted_least_norm` subject to ``rows @ qdot <= rhs`` and ``lower <= qdot <= upper``.

    It solves ``min |J qdot - xdot|² + λ² qdotᵀ W qdot``, whose unconstrained minimiser is the
    weighted least-norm solution; with the rows, its fixed point (``qdot = 0``) is a stationary
    point of the tracking error among the configurations that keep the rows, whatever the weights.
    Weights are capped at 1e6 (larger ones hold a joint all the same). ``soft``: the rows it may
    miss, as :func:`~hlik.solvers.qp_backend.solve_qp` takes them. None if infeasible.
    """
    w = np.minimum(weights, 1e6)
    hessian = jac.T @ jac + damping**2 * np.diag(w)
    x = solve_qp(hessian, -jac.T @ xdot, lower, upper, "daqp", rows, rhs, soft)
    return x if x is not None and np.all(np.isfinite(x)) else None


def _fraction_within(rows: np.ndarray, rhs: np.ndarray, x: np.ndarray, v: np.ndarray) -> float:
    """The largest s in [0, 1] with ``rows @ (x + s v) <= rhs`` for the rows ``x`` meets."""
    rate, room = rows @ v, rhs - rows @ x
    with np.errstate(divide="ignore", invalid="ignore"):
        limits = np.where((rate > 0) & (room >= 0), room / rate, np.inf)
    return min(max(float(np.min(limits, initial=1.0)), 0.0), 1.0)


def _null_within(
    task: np.ndarray, null: np.ndarray, rows: np.ndarray, rhs: np.ndarray, max_step: float, last: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The step ``task + null`` (n,) with the null-space step cut so that it breaks none of the
    ``rows`` (k, n) the task step left free (nor worsens one it could not meet), nor ``max_step``;
    and the null-space step to remember: the cut one, or ``last`` where it was cut to nothing, so
    that a reversal is still told (else the null space zig-zags against the rows at the full
    bound)."""
    n = len(task)
    within = np.vstack([rows, np.eye(n), -np.eye(n)])
    limit = np.concatenate([np.maximum(rhs, rows @ task), np.full(2 * n, max_step)])
    null = null * _fraction_within(within, limit, task, null)
    return task + null, (null if np.any(null) else last)


def _avoiding_step(
    jac: np.ndarray,
    xdot: np.ndarray,
    weights: np.ndarray,
    damping: float,
    tries: Sequence[StepConstraints],
    null_step: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> tuple[np.ndarray, np.ndarray, StepConstraints | None]:
    """The task step under the rows (:func:`avoiding_least_norm`) and the null-space step of the
    targets and the rows it holds at their bound (before bounding), each (n,), under the first of
    ``tries`` (:func:`hlik.solvers.frames.constrained_steps`) that can be met, and that try; if
    none can, zeros and None."""
    n = jac.shape[1]
    for c in tries:
        task = avoiding_least_norm(jac, xdot, weights, damping, c.rows, c.bound, c.lower, c.upper, c.soft)
        if task is not None:
            active = c.rows @ task >= c.bound - 1e-7
            return task, null_step(np.vstack([jac, c.rows[active]]), task), c
    return np.zeros(n), np.zeros(n), None


ROTATIONAL = (fORI, fORI_off)  # the target terms in rad; the others are in m
AT_BOUND = 1e-9  # rad: a joint this close to a bound of the frame's box is held there
NULL_FLOOR = 1e-3  # the least carried null-space bound, a share of max_null


def evaluate_targets(
    targets: Sequence[Term], state: RobotState, frame: Sample
) -> list[tuple[Term, np.ndarray, np.ndarray]]:
    """Each target term with its residual (m_i,) and Jacobian (m_i, n) at ``state``."""
    return [(t, *t(state, frame)) for t in targets]


def primary(
    evaluated: Sequence[tuple[Term, np.ndarray, np.ndarray]], orientation_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """Stacked residual e (m,) and Jacobian J (m, n) of the :func:`evaluate_targets` terms,
    orientation rows weighted."""
    w = [orientation_weight if isinstance(t, ROTATIONAL) else 1.0 for t, _, _ in evaluated]
    return (
        np.concatenate([wi * e for wi, (_, e, _) in zip(w, evaluated)]),
        np.vstack([wi * jac for wi, (_, _, jac) in zip(w, evaluated)]),
    )


def targets_reached(evaluated: Sequence[tuple[Term, np.ndarray, np.ndarray]], settings: JVSettings) -> bool:
    """Whether every target of the :func:`evaluate_targets` terms (each hand's, or the relative
    pose's) is within ``settings.reached_position`` (m) and ``reached_orientation`` (rad); False if
    either is 0."""
    if settings.reached_position <= 0.0 or settings.reached_orientation <= 0.0:
        return False
    for term, e, _ in evaluated:
        limit = settings.reached_orientation if isinstance(term, ROTATIONAL) else settings.reached_position
        if np.max(part_metric(term, e)[0]) > limit:  # each hand's distance or angle
            return False
    return True


def secondary(
    criteria: Sequence[tuple[Term, float]],
    state: RobotState,
    frame: Sample,
    jla: np.ndarray,
    settings: JVSettings,
) -> np.ndarray:
    """Gradient (n,) of the null-space cost sum_i w_i h_i + w_H H; ``criteria`` the (term, w_i)
    pairs, ``jla`` dH/dq (n,)."""
    grad = settings.criterion_cost * settings.jla_gamma * jla
    for term, weight in criteria:
        grad = grad + weight * gradient(term, state, frame)[1]
    return grad


def _state(robot: Robot, q: np.ndarray, data: mujoco.MjData, terms: Sequence[Term]) -> RobotState:
    """The kinematics at ``q`` with the site Jacobians ``terms`` read."""
    sites = tuple(sorted({i for t in terms for i in t.sites}))
    return robot_state(robot, q, jacobians=True, data=data, jacobian_sites=sites)


def _null_step(
    held: np.ndarray, start: np.ndarray, *, q: np.ndarray, free: np.ndarray, grad: np.ndarray,
    box: JointBox, settings: JVSettings,
) -> np.ndarray:  # fmt: skip
    """The null-space step of the rows ``held`` (k, n) over the ``free`` joints, scaled into the
    box from ``q + start``."""
    null = np.zeros(len(q))
    null[free] = settings.k * (null_space_projector(held[:, free], settings.rcond) @ grad[free])
    return null * _fraction_inside(q + start, null, box)


def _bounded(null: np.ndarray, memory: Memory) -> tuple[np.ndarray, float]:
    """``null`` within the null-space bound, halved whenever the null-space step reverses (turns
    back by more than rounding: the sign of two rounding-sized steps' dot product halved the bound
    in a take and not in its mirror image)."""
    size, before = np.linalg.norm(null), np.linalg.norm(memory.null)
    # steps of rounding's size (1e-16: a null space with nothing left to do) have no direction
    reverses = min(size, before) > AT_BOUND and null @ memory.null < -1e-6 * size * before
    null_bound = memory.null_bound * (0.5 if reverses else 1.0)
    return bound(null, null_bound), null_bound


def _step_tries(
    box: JointBox,
    q: np.ndarray,
    max_step: float,
    data: mujoco.MjData,
    collision: SelfCollisionLimit | None,
    hard: tuple[np.ndarray, np.ndarray] | None,
) -> list[StepConstraints]:
    """:func:`constrained_steps` of the frame's box with the collision rows at ``q`` (its
    kinematics in ``data``) and the caller's ``hard`` rows."""
    a_col, b_col = np.zeros((0, len(q))), np.zeros(0)
    if collision is not None:
        a_col, b_col = collision.rows(data)
    a_hard, b_hard = hard if hard is not None else (None, None)
    return constrained_steps(box, q, max_step, a_col, b_col, a_hard=a_hard, b_hard=b_hard)


def step(
    robot: Robot,
    targets: Sequence[Term],
    criteria: Sequence[tuple[Term, float]],
    q: np.ndarray,
    frame: Sample,
    settings: JVSettings,
    memory: Memory,
    data: mujoco.MjData | None = None,
    box: JointBox | None = None,
    collision: SelfCollisionLimit | None = None,
    stop_if_reached: bool = False,
    hard: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, Memory]:
    """One JV step from ``q`` (n,) within ``box`` (default: the joint limits), keeping the rows of
    ``collision`` (if given; the QP's :class:`~hlik.solvers.mink_tasks.SelfCollisionLimit`, its
    frame's box set): the joint change dq (n,), before clipping, and the new memory.
    ``stop_if_reached``: no step (zeros) where :func:`targets_reached`. ``hard``: a caller's limit
    rows on the step, (k, n), (k,) (:func:`~hlik.solvers.frames.limit_rows`), kept as
    :func:`constrained_steps` says.

    The null-space bound halves whenever the null-space step reverses: the steep H (and the
    criteria) make bounded gradient steps of a fixed size zig-zag across their minimum, so a frame
    would never converge.
    """
    data = mujoco.MjData(robot.model) if data is None else data
    state = _state(robot, q, data, (*targets, *(c for c, _ in criteria)))
    evaluated = evaluate_targets(targets, state, frame)
    if stop_if_reached and targets_reached(evaluated, settings):
        return np.zeros(robot.dof), memory
    e, jac = primary(evaluated, settings.orientation_cost)
    _, jla = chan_dubey(q, robot.lower, robot.upper)
    damping = np.hypot(settings.damping, np.linalg.norm(e)) if settings.error_damping else settings.damping
    box = box or JointBox(robot.lower, robot.upper)
    xdot, weights = -settings.step * e, limit_weights(jla, memory.jla)
    task = clamped_least_norm(jac, xdot, weights, damping, q, box)
    grad = secondary(criteria, state, frame, jla, settings)
    # joints at a bound of the frame's box are held: the null space is that of the others, and the
    # step is scaled (not clipped) into the box, since a clipped null-space step moves the targets;
    # within AT_BOUND counts as at it, so that rounding (a step scaled to end on the bound) does not
    # decide which joints the null space may use (a take and its mirror image took different ones)
    free = (q > box.lower + AT_BOUND) & (q < box.upper - AT_BOUND)

    null_step = partial(_null_step, q=q, free=free, grad=grad, box=box, settings=settings)
    null, null_bound = _bounded(null_step(jac, task), memory)
    # clipped here, not only by iterate: the collision rows are checked on the step taken
    dq = box.clip(q + bound(task + null, settings.max_step)) - q
    tries = _step_tries(box, q, settings.max_step, data, collision, hard)
    rows, rhs = tries[0].rows, tries[0].bound  # every row: the torque limits and the collision rows
    constrained, missed = memory.constrained, memory.missed
    if len(rhs) and np.all(np.isfinite(dq)) and (constrained or np.any(rows @ dq > rhs + 1e-9)):
        constrained = True
        task, null, taken = _avoiding_step(jac, xdot, weights, damping, tries, null_step)
        missed = missed or (taken is not None and taken.misses_limits)
        null, null_bound = _bounded(null, memory)
        dq, null = _null_within(task, null, rows, rhs, settings.max_step, memory.null)
    if not np.all(np.isfinite(dq)):
        dq, null = np.zeros(robot.dof), np.zeros(robot.dof)  # a failed step stays put: nothing NaN
    return dq, Memory(jla, null, null_bound, constrained, missed)


def solve(
    problem: Problem,
    settings: JVSettings = JVSettings(),
    progress: Callable[[int], None] | None = None,
    limits: Sequence[mink.Limit] = (),
) -> SolverResult:
    """Retarget frame by frame; diagnostics count the JV steps per frame. ``limits``: a caller's
    ``mink.Limit``\\ s, their rows kept at each step as the QP keeps them (the last fallback gives way
    on them, and the frame is then reported failed)."""
    robot, learned = problem.robot, problem.learned
    config = mink.Configuration(robot.model) if limits else None
    tasks, first = list(target_terms(settings.scenario)), list(target_terms(FIRST_FRAME_SCENARIO))
    # each criterion with its null-space weight w_i
    criteria = unified.weighted_criteria(
        settings.criteria, robot, learned, settings.criterion_cost, settings.gamma
    )
    first_criteria = first_frame_terms(criteria)
    data = mujoco.MjData(robot.model)
    margins = (settings.collision_margin, settings.collision_detect, settings.collision_gain)
    collision = SelfCollisionLimit(robot, *margins) if settings.self_collision else None
    memory: Memory | None = None

    def solve_frame(k: int, frame: Sample, q: np.ndarray, box: JointBox) -> FrameResult:
        nonlocal memory
        if memory is None or k == 0:  # the first frame may be solved more than once (frames.track)
            memory = Memory(
                chan_dubey(q, robot.lower, robot.upper)[1], np.zeros(robot.dof), settings.max_null
            )
        # the null-space bound carries over, doubled: set back to max_null each frame, the null
        # space ended each frame wherever its halvings stopped (a 3 mrad dither where the targets
        # held still); floored, since halved per reversal and doubled per frame it could fall to
        # 1e-6 rad for whole takes
        bound_now = min(settings.max_null, max(2.0 * memory.null_bound, NULL_FLOOR * settings.max_null))
        memory = replace(memory, null_bound=bound_now, constrained=False, missed=False)

        taken = 0
        if collision is not None:
            collision.set_box(box)

        def jv_step(x: np.ndarray) -> np.ndarray:
            nonlocal memory, taken
            assert memory is not None
            stack, secondary = (first, first_criteria) if k == 0 else (tasks, criteria)
            hard = None
            if config is not None:
                config.update(x)
                hard = limit_rows(limits, config, frame.dt, robot.dof)
            # the first step is always taken, so that the hands follow a target that moves by less
            # than the thresholds, and the null space acts once per frame
            args = (settings, memory, data, box, collision, taken > 0, hard)
            dq, memory = step(robot, stack, secondary, x, frame, *args)
            taken += 1
            return dq

        result = iterate(
            jv_step, q, box, step_budget(k, settings.max_iter), settings.tol, damp_reversals=True
        )
        assert memory is not None
        return replace(result, converged=False, failed=True) if memory.missed else result

    return track(problem, solve_frame, progress, MotionLimits.of(robot, settings))


def jv_solver(
    settings: JVSettings = JVSettings(),
    progress: Callable[[int], None] | None = None,
    limits: Sequence[mink.Limit] = (),
) -> ConfiguredSolver:
    """The JV solver with the given settings (and a caller's ``mink.Limit``\\ s), for
    :func:`hlik.retarget.retarget`."""
    return ConfiguredSolver("jv", partial(solve, limits=limits) if limits else solve, settings, progress)
