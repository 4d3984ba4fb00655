"""The frame loop the optimising solvers share: warm start, the previous solutions, diagnostics.

Every frame is solved from the previous frame's solution (the first from the clipped mapped human
pose, as JM gives it), with the frame's targets and human reference in a one-row
:class:`hlik.criteria.base.Sample`, inside the frame's joint box: the joint limits intersected with
what the speed and acceleration limits allow since the previous frames, braking before the stops,
and the torque rows (:mod:`hlik.solvers.limits`), so no frame jumps; a frame whose target lies
farther lags behind it. The first frame, where the robot starts from the mapped human pose, is
bounded by the joint limits moved in by their margin only; where it leaves a hand off, it is
solved again from the hands' own IK (:func:`hand_miss`, :func:`hands_ik`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from hlik.criteria.base import Sample, Term
from hlik.criteria.functional import fORI, fORI_off, fPOS, fPOS_off, rotation_angle
from hlik.problem.problem import Problem
from hlik.problem.reference import HumanReference, reference_sample
from hlik.problem.targets import HandTargets
from hlik.robot.collision import CollisionPairs, DistanceBounds, near_pairs, pair_shift, velocity_damper
from hlik.robot.model import SIDES, Robot, self_contacts, tcp_poses
from hlik.solvers.base import Diagnostics, SolverResult
from hlik.solvers.limits import JointBox as JointBox  # re-exported: the solvers' frame box
from hlik.solvers.limits import MotionLimits
from hlik.solvers.qp_backend import solve_qp
from hlik.solvers.settings import LimitSettings as LimitSettings


@dataclass(frozen=True)
class FrameResult:
    """One frame's solution (n,) and how it was reached."""

    q: np.ndarray
    iterations: int
    converged: bool = True
    failed: bool = False


FrameSolver = Callable[[int, Sample, np.ndarray, JointBox], FrameResult]


def joint_box(robot: Robot, q_previous: np.ndarray | None, dt: float) -> JointBox:
    """The joint limits, intersected with the speed limits' reach from ``q_previous`` if given: the
    box of :meth:`MotionLimits.box` without the margin, the acceleration and the torque limits."""
    speed_only = LimitSettings(stop_margin=0.0, acceleration_limits=False, torque_limits=False)
    return MotionLimits.of(robot, speed_only).box(q_previous, q_previous, dt)


def sample_at(ref: HumanReference, targets: HandTargets, k: int, history: np.ndarray, dt: float) -> Sample:
    """The one-row :class:`Sample` of frame ``k``; ``history`` (3, n): previous solutions, newest first."""
    return reference_sample(ref, targets, slice(k, k + 1), history[None], dt)


def track(
    problem: Problem,
    solve_frame: FrameSolver,
    progress: Callable[[int], None] | None = None,
    limits: MotionLimits | None = None,
) -> SolverResult:
    """Solve frame by frame with ``solve_frame(k, sample, q_start, box) -> FrameResult``, each
    frame inside the box of ``limits`` (default: the robot's, :class:`LimitSettings`' defaults),
    from the previous solution moved on at its speed (the first frame: the clipped mapped pose)."""
    robot, n_frames = problem.robot, problem.n_frames
    limits = limits or MotionLimits.of(robot)
    data = mujoco.MjData(robot.model)
    q = np.clip(problem.reference.q_map[0], robot.lower, robot.upper)
    history = np.tile(q, (3, 1))
    out = np.empty((n_frames, robot.dof))
    iterations = np.zeros(n_frames, dtype=int)
    converged, failed = np.ones(n_frames, dtype=bool), np.zeros(n_frames, dtype=bool)
    seconds = np.zeros(n_frames)
    for k in range(n_frames):
        start = time.perf_counter()
        sample = sample_at(problem.reference, problem.tracked, k, history, problem.dt)
        box = limits.box(q if k else None, history[1], problem.dt, data, history[2])
        # from the constant-speed prediction: the previous configuration lies outside the
        # acceleration box whenever a joint moves faster than a_max dt, and clipped into it, it
        # starts the frame on the box's corner (JV's steps then chattered between corners)
        q_start = box.clip(2.0 * q - history[1]) if k else q
        result = solve_frame(k, sample, q_start, box)
        if k == 0:
            result = _first_frame(problem, solve_frame, sample, box, q, result)
        seconds[k] = time.perf_counter() - start
        q = result.q
        iterations[k], converged[k], failed[k] = result.iterations, result.converged, result.failed
        # RelaxedIK resets the history to the first solution
        history = np.tile(q, (3, 1)) if k == 0 else np.vstack([q, history[:2]])
        out[k] = q
        if progress is not None:
            progress(k)
    return SolverResult(out, Diagnostics(iterations, converged, failed, seconds))


def hand_miss(problem: Problem, q: np.ndarray) -> float:
    """How far ``q`` (n,) leaves the hands off their first-frame TCP targets, in
    :data:`FIRST_FRAME_TOLERANCE`: the largest of each hand's position error over its metres and
    angle over its radians (at most 1: both hands within both)."""
    pos, rot = tcp_poses(problem.robot, q[None])
    targets = problem.tracked
    dp = np.linalg.norm(pos[0] - targets.pos[0], axis=-1)
    da = rotation_angle(rot[0], targets.rot[0])
    tol_p, tol_a = FIRST_FRAME_TOLERANCE
    return float(max(np.max(dp) / tol_p, np.max(da) / tol_a))


def hands_ik(problem: Problem, q: np.ndarray, box: JointBox, steps: int = 300) -> np.ndarray:
    """(n,) joint angles inside ``box`` that put both TCPs on their first-frame targets as near as
    it lets them, from ``q`` (n,): the hands alone, by mink's differential IK (two ``FrameTask`` tasks,
    ``ConfigurationLimit``), each step clipped into the box, to a standstill or ``steps``."""
    import mink  # the solvers' IK; light imports for the Python API that never solves

    robot, targets = problem.robot, problem.tracked
    config = mink.Configuration(robot.model, box.clip(q))
    tasks = []
    for i, side in enumerate(SIDES):
        task = mink.FrameTask(f"{side}_tcp", "site", position_cost=1.0, orientation_cost=HANDS_IK_METRES)
        frame = mink.SO3.from_matrix(targets.rot[0, i])
        task.set_target(mink.SE3.from_rotation_and_translation(frame, targets.pos[0, i]))
        tasks.append(task)
    limits = [mink.ConfigurationLimit(robot.model)]
    for _ in range(steps):
        try:
            v = mink.solve_ik(config, tasks, 1.0, "daqp", 1e-3, limits=limits)
        except mink.exceptions.NoSolutionFound:
            break
        before = config.q.copy()
        config.integrate_inplace(v, 1.0)
        config.update(box.clip(config.q))
        if np.max(np.abs(config.q - before)) < 1e-5:
            break
    return config.q.copy()


def _first_frame(
    problem: Problem,
    solve_frame: FrameSolver,
    sample: Sample,
    box: JointBox,
    start: np.ndarray,
    result: FrameResult,
) -> FrameResult:
    """The first frame, solved from ``start`` (n,) into ``result``, solved again where that left a
    hand off (:func:`hand_miss` above 1): from the hands' own IK (:func:`hands_ik`) from where it
    ended or from home, whichever lands the hands nearer. The second solution is kept where it
    leaves the hands at most :data:`FIRST_FRAME_SWITCH` as far, touches itself no more and did not
    fail where the first did not; else the frame is solved from ``start`` once more, which puts
    back what a solver carries from frame to frame (JV's null-space memory). Iterations count
    every solve."""
    miss = hand_miss(problem, result.q)
    if miss <= 1.0:
        return result
    robot = problem.robot
    starts = [hands_ik(problem, q, box) for q in (result.q, robot.home)]
    again = solve_frame(0, sample, min(starts, key=lambda q: hand_miss(problem, q)), box)
    iterations = result.iterations + again.iterations
    if (
        hand_miss(problem, again.q) <= FIRST_FRAME_SWITCH * miss
        and (result.failed or not again.failed)
        and len(self_contacts(robot, again.q)) <= len(self_contacts(robot, result.q))
    ):
        return replace(again, iterations=iterations)
    first = solve_frame(0, sample, start, box)
    return replace(first, iterations=iterations + first.iterations)


# The first frame starts from the clipped mapped human pose, often far from its targets, and has no
# past: it gets this many times a frame's steps (SLSQP: its own ``first_eval`` evaluations), the
# TCP pose targets in ``relative`` (paper Sec. V-B) and no term of motion (first_frame_terms).
FIRST_FRAME_STEPS = 10
FIRST_FRAME_SCENARIO = "pose"
# From the clipped mapped pose, joints clipped onto their stops, the first frame's local steps can
# end on a branch with joints at their stops that the whole take then keeps (2-Panda's left arm on
# the bundled demo: 7.5 cm and 50 deg off in 87 % of the frames; from home, 0.0 cm and 0.0 deg).
# Where the first frame leaves a hand farther off than this (m, rad), it is solved again from the
# hands' own IK, and that is kept where it leaves them at most this share as far (a robot at its
# home, one of the IK's starts, is where a real trajectory begins)
FIRST_FRAME_TOLERANCE = (0.02, np.radians(10.0))
FIRST_FRAME_SWITCH = 0.5
# hands_ik's orientation weight, m per rad: 10 deg off weighs as 1.7 cm (FIRST_FRAME_TOLERANCE's ratio)
HANDS_IK_METRES = 0.1


def first_frame_terms(weighted: Sequence[tuple[Term, float]]) -> list[tuple[Term, float]]:
    """The first frame's share of a stack of (term, weight): every term but those of motion
    (``Term.motion``: MIS, MJE, the minimum velocity, acceleration and jerk). Nothing moved before
    the first frame; they would hold the robot at the pose it starts from (SLSQP on 2-Panda's Cut
    take: 12 cm and 21 deg off the hand targets, 30 frames to catch up)."""
    return [(t, w) for t, w in weighted if not t.motion]


def step_budget(k: int, max_iter: int) -> int:
    """Steps frame ``k`` may take: :data:`FIRST_FRAME_STEPS` times ``max_iter`` for the first."""
    return max_iter * (FIRST_FRAME_STEPS if k == 0 else 1)


def iterate(
    step: Callable[[np.ndarray], np.ndarray | None],
    q: np.ndarray,
    box: JointBox,
    max_iter: int,
    tol: float,
    damp_reversals: bool = False,
) -> FrameResult:
    """Repeat ``q <- clip(q + step(q))`` into ``box`` until no joint moves more than ``tol``
    (converged) or ``max_iter`` steps (the paper's stopping rule for JV). A step of None (no step
    the QP solver could find) ends the frame where it is, failed: standing still is then not
    convergence.

    ``damp_reversals``: a step that turns back on the previous one (cosine below -1/2) halves the
    scale of this and every later step. A Gauss-Newton step can flip a joint between the ends of
    its speed box where the linearisation is poor (ARMAR-III's elbow near a stretched arm: the same
    +-0.01 rad step every iteration until the cap), and a step that misses soft collision rows
    (:func:`constrained_steps`) between the sides of a mesh's hull (the G1's arm against its torso:
    +-0.2 rad until the cap, in 137 of 201 JV frames); halving settles it between them.
    """
    steps, converged, scale = 0, False, 1.0
    q = box.clip(q)
    previous: np.ndarray | None = None
    while steps < max_iter:
        delta = step(q)
        if delta is None:
            return FrameResult(q, steps + 1, False, True)
        if damp_reversals and previous is not None:
            dot = float(delta @ previous)
            if dot < -0.5 * np.linalg.norm(delta) * np.linalg.norm(previous):
                scale *= 0.5
        previous = delta
        new = box.clip(q + scale * delta)
        moved, q, steps = np.max(np.abs(new - q)), new, steps + 1
        if moved < tol:
            converged = True
            break
    return FrameResult(q, steps, converged)


# the slack penalties of the rows a step may miss where no step meets them all, per unit of the
# largest diagonal entry of the step's Hessian: a collision row missed by 0.1 mm costs as much as a
# tenth of a radian of the costliest joint, a torque row missed by 0.1 N m as much as 0.1 rad
COLLISION_PENALTY = 1e6  # per m^2
TORQUE_PENALTY = 1.0  # per (N m)^2


@dataclass(frozen=True, eq=False)
class StepConstraints:
    """What a step ``dq`` (n,) must keep: ``lower <= dq <= upper`` (n,) and ``rows @ dq <= bound``
    ((k, n), (k,)); ``soft`` (k,) the slack penalty of each row a step may miss (0: hard; None:
    every row hard), per unit of the largest diagonal entry of the step's Hessian
    (:func:`hlik.solvers.qp_backend.solve_qp`). ``misses_limits``: a caller's hard rows are among
    the soft ones (the last resort; the frame is reported failed)."""

    lower: np.ndarray
    upper: np.ndarray
    rows: np.ndarray
    bound: np.ndarray
    soft: np.ndarray | None = None
    misses_limits: bool = False


def constrained_steps(
    box: JointBox,
    q: np.ndarray,
    max_step: float,
    a_col: np.ndarray,
    b_col: np.ndarray,
    a_band: np.ndarray | None = None,
    b_band: np.ndarray | None = None,
    a_hard: np.ndarray | None = None,
    b_hard: np.ndarray | None = None,
) -> list[StepConstraints]:
    """What a step from ``q`` (n,) inside ``box`` tries to keep, in order: (1) every row, the box's
    (torque), a caller's hard rows ``a_hard``, ``b_hard`` (a user's ``mink.Limit``), the collision
    rows ``a_col``, ``b_col`` (k, n), (k,) (:func:`collision_rows`) and the hands' band (below);
    where no step meets them, (2) every row but the band's (the body before the hands); then (3)
    the collision rows soft (missed as little as the box and the torque rows allow: a pair the
    limits cannot pull back to its floor in time brakes, or backs out of the margin, as hard as
    they let it), then (4) the torque rows soft too, at a lower penalty (the body before the
    torque). (4) is always feasible without hard rows; with them, (5) gives way on them too, at the
    collision rows' penalty, as the last resort: a joint that arrives at a caller's bound faster
    than its acceleration limit can stop it brakes as hard as the box allows and comes back,
    instead of coasting past it as a frame with no step did (a frame that takes it is reported
    failed). The QP and JV take the first their solver can meet. The box
    itself always holds: an acceleration limit given up for the margin was a jump of 40 times the
    limit, for a miss of the margin by 0.1 mm; and a collision row relaxed to "no worse than the
    step's start" let the arm coast into the body at its speed.

    The hands' band ``a_band``, ``b_band`` (k, n), (k,) (none where k = 0) is the first try's, as
    hard rows; where it is out of a step's reach, the QP moves its bound out by as little
    as the body's rows allow (:func:`nearest_band`). Soft rows at a penalty high enough to act as
    a priority had left daqp's problem so badly scaled that it called every step infeasible, and
    a robot started 0.6 m from its targets never moved."""
    lower, upper = box.step_bounds(q, max_step)
    a_box, b_box = box.step_rows(q)
    if a_hard is None or b_hard is None:
        a_hard, b_hard = np.zeros((0, len(q))), np.zeros(0)
    a, b = np.vstack([a_box, a_hard, a_col]), np.concatenate([b_box, b_hard, b_col])
    tries = []
    if a_band is not None and b_band is not None and len(b_band):
        tries.append(StepConstraints(lower, upper, np.vstack([a, a_band]), np.concatenate([b, b_band])))
    tries.append(StepConstraints(lower, upper, a, b))
    box_rows, hard = np.zeros(len(b_box)), np.zeros(len(b_hard))
    collision = np.full(len(b_col), COLLISION_PENALTY)
    if len(b_col):
        tries.append(StepConstraints(lower, upper, a, b, np.concatenate([box_rows, hard, collision])))
    if len(b_box):
        torque = np.full(len(b_box), TORQUE_PENALTY)
        tries.append(StepConstraints(lower, upper, a, b, np.concatenate([torque, hard, collision])))
    if len(b_hard):
        torque, limits = np.full(len(b_box), TORQUE_PENALTY), np.full(len(b_hard), COLLISION_PENALTY)
        tries.append(StepConstraints(lower, upper, a, b, np.concatenate([torque, limits, collision]), True))
    return tries


def solve_step(
    hessian: np.ndarray,
    gradient: np.ndarray,
    tries: list[StepConstraints],
    solver: str,
    band_rows: int = 0,
) -> tuple[np.ndarray | None, StepConstraints | None]:
    """The step dq (n,) minimising ``1/2 dq' H dq + g' dq`` under the first of ``tries``
    (:func:`constrained_steps`) the QP solver can meet, and that try; (None, None) where it meets
    none (the frame then stays where it is, failed: limits hold, nothing NaN). With ``band_rows`` >
    0 the first try ends in that many rows of the hands' band; where no step keeps them, the step
    keeps the band as near as the rest allows (:func:`nearest_band`), before the tries without it."""
    for k, c in enumerate(tries):
        dq = solve_qp(hessian, gradient, c.lower, c.upper, solver, c.rows, c.bound, c.soft)
        if dq is None and k == 0 and band_rows:
            nearest = nearest_band(c, band_rows, solver)
            if nearest is not None:
                dq = solve_qp(hessian, gradient, c.lower, c.upper, solver, c.rows, nearest)
        if dq is not None:
            return (dq, c) if np.all(np.isfinite(dq)) else (None, None)
    return None, None


def limit_rows(limits: Sequence, config, dt: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The inequality rows ``G dq <= h`` of ``limits`` (``mink.Limit``\\ s) at the configuration
    ``config`` (a ``mink.Configuration`` whose kinematics are current), stacked: (k, n), (k,)."""
    g: list[np.ndarray] = [np.zeros((0, n))]
    h: list[np.ndarray] = [np.zeros(0)]
    for limit in limits:
        c = limit.compute_qp_inequalities(config, dt)
        if c.G is not None and c.h is not None:  # mink's Constraint.inactive
            g.append(c.G)
            h.append(c.h)
    return np.vstack(g), np.concatenate(h)


def box_with_limits(box: JointBox, limits: Sequence, config, q: np.ndarray, dt: float) -> JointBox:
    """``box`` with a caller's ``mink.Limit`` rows at ``q`` (n,) among its rows, as rows on the
    configuration: ``G q' <= h + G q`` (exact for limits linear in q, such as a joint's bound;
    linearised at ``q`` otherwise). Overwrites ``config``'s configuration."""
    config.update(q)
    g, h = limit_rows(limits, config, dt, len(q))
    if not len(h):
        return box
    rows = g if box.rows is None else np.vstack([box.rows, g])
    bound = h + g @ q if box.bound is None else np.concatenate([box.bound, h + g @ q])
    return replace(box, rows=rows, bound=bound)


def hand_band(term: Term, settings) -> float:
    """The tolerance band of a target term under ``settings`` (``position_band`` for fPOS and
    fPOS^off in m, ``orientation_band`` for fORI and fORI^off in rad), 0 for every other term."""
    if isinstance(term, fORI | fORI_off):
        return float(settings.orientation_band)
    if isinstance(term, fPOS | fPOS_off):
        return float(settings.position_band)
    return 0.0


def nearest_band(c: StepConstraints, k: int, solver: str) -> np.ndarray | None:
    """The bound of ``c`` with its last ``k`` rows (the hands' band) moved out by as little as its
    other rows and bounds allow: each band row's least miss, from the QP that minimises the sum of
    the squared misses alone (its step regularised by 1e-6); None if the other rows cannot be met
    either. The first stage of a lexicographic step: the second minimises the step's own cost
    within the bound returned, which the first stage's step meets."""
    n, m = len(c.lower), len(c.bound)
    soft = np.concatenate([np.zeros(m - k), np.full(k, 1e6)])  # slack weight 1 against 1e-6 I
    dq = solve_qp(1e-6 * np.eye(n), np.zeros(n), c.lower, c.upper, solver, c.rows, c.bound, soft)
    if dq is None:
        return None
    miss = np.maximum(c.rows[m - k :] @ dq - c.bound[m - k :], 0.0)
    out = c.bound.copy()
    out[m - k :] += miss + 1e-9
    return out


def collision_rows(
    robot: Robot,
    data: mujoco.MjData,
    pairs: CollisionPairs,
    bounds: DistanceBounds | None,
    settings,
    floors: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The velocity-damper rows (k, n) and bounds (k,) of ``settings``' ``collision_margin``,
    ``collision_detect`` and ``collision_gain`` (the QP's and JV's), for the configuration whose
    kinematics ``data`` holds, no pair closer than its floor and each looked for as far as
    ``floors`` say (:func:`collision_floors`); ``bounds`` carried across steps."""
    margin, gain = settings.collision_margin, settings.collision_gain
    if floors is None:
        return velocity_damper(robot, data, pairs, margin, settings.collision_detect, gain, bounds)
    return velocity_damper(robot, data, pairs, margin, floors[1], gain, bounds, floors[0])


def collision_floors(
    robot: Robot,
    data: mujoco.MjData,
    pairs: CollisionPairs | None,
    box: JointBox,
    settings,
    bounds: DistanceBounds | None = None,
) -> tuple[np.ndarray, np.ndarray] | None:
    """Each pair's least distance, m, in the frame of ``box`` (:meth:`Braking.floors
    <hlik.solvers.limits.Braking.floors>` at the frame's start; ``-inf`` for the pairs not near)
    and how far to look for it, m (:meth:`~hlik.solvers.limits.Braking.horizon` of how fast it
    closed in the last frame): (p,) each, so that the solvers brake before the collision margin
    instead of stopping at it (the damper alone let hands closing at 1 m/s stop within a frame,
    and saw a pair only within ``collision_detect``, inside its braking distance). None without
    braking. Overwrites ``data``'s kinematics."""
    if pairs is None or not len(pairs) or box.braking is None:
        return None
    braking, model = box.braking, robot.model
    data.qpos[:] = braking.before
    mujoco.mj_kinematics(model, data)
    before = data.geom_xpos[pairs.unique].copy(), data.geom_xmat[pairs.unique].copy()
    data.qpos[:] = braking.previous
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    closing = pair_shift(pairs, *before, data.geom_xpos[pairs.unique], data.geom_xmat[pairs.unique])
    horizon = braking.horizon(closing, settings.collision_margin, settings.collision_detect)
    index, dist, grad = near_pairs(robot, data, pairs, horizon, bounds)
    floors = np.full(len(pairs), -np.inf)
    floors[index] = braking.floors(dist, grad, settings.collision_margin)
    return floors, horizon
