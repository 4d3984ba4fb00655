"""The whole take at once: a frame-by-frame solution improved over every frame together.

A frame-by-frame solver (JV, the QP, SLSQP) sees its own frame and, with its look-ahead, a path
fitted in joint space; where a turn of the hand needs the joints to start early, it lags. Here the
solved motion q (T, n) is the start of a sequential convex programme over all T frames at once.
Each iteration linearises, at the current motion, both TCP poses (``mj_jacSite``), the joint
torques (``mujoco.mjd_inverseFD`` on the controller check's inverse dynamics,
:mod:`hlik.robot.dynamics`) and the collision pairs closer than ``collision_detect``
(:func:`hlik.robot.collision.near_pairs`), and solves one sparse QP (Clarabel, through qpsolvers)
for every frame's step dq:

    min  sum_t sum_hands |e_o (1 - band / |e_o|) + J_o dq_t|^2   (hands turned beyond the band)
         + position_cost |e_p + J_p dq_t|^2   (Huber: linear beyond the band's corner)
         + pull_j (q_t + dq_t - q_run,t)^2 + smoothness |D2 (q + dq - q_run)|^2
         + sum_i w_i |e_i + J_i dq_t|^2   (the run's criteria, w_i = gamma_i criterion_cost / k,
                                            and the trunk toward home at ``trunk_upright``)
    s.t. the stops less ``stop_margin``; |dq_t| <= the trust region; the last two frames kept;
         speed, acceleration (and jerk) limits as the controller check differences them
         (:mod:`hlik.executable`: at rest before the first frame), times ``headroom``;
         each hand within ``position_band`` m per axis of its target (or as far as the run left it);
         torques above ``torque_watch`` of their efforts within ``torque_fraction`` of them;
         each near pair at least ``collision_margin`` apart;
         a caller's ``mink.Limit`` rows at each frame, ``G dq_t <= h`` (as the frame-by-frame
         solvers keep them, :func:`hlik.solvers.frames.limit_rows`),

with e_o the rotation vector of R R*^T (rad), e_p the TCP's offset (m), e_i a criterion's
residual at frame t (:class:`~hlik.criteria.base.Term`; those of one frame's pose: the criteria of
motion, MJE and MIS, are left to the smoothness term). A row the start already breaks is moved to
where the start is. Within their bands the hands cost nothing and the criteria the solver added
shape the arm; beyond, the criteria are weighed against the hands' orientation (a weighted trade:
``criterion_cost``, per robot in a stack's ``[whole_take]``); ``pull`` keeps the rest of the
posture. The take ends in
the solver's own last two frames, from which the solvers keep the joints able to brake before their
stops' margins. A step is kept only if the merit (the objective's terms as they are at the step)
falls, no hand ends further off than its rows' box corner and a band more (the curvature the rows
do not see), no torque ends above ``torque_fraction`` of its effort (or above what the solver's
run asked) by more than :data:`TORQUE_TOLERANCE` of it, no pair closer than half the margin (or
than it was), and every frame inside a caller's limits (their room ``h`` at least 0, or what the
run left); else the trust region halves, but a step refused for its torques alone is first
solved again with the torque rows shifted by what they missed (a second-order correction). The
rows are kept to Clarabel's tolerance; ``headroom`` leaves 1 % for it. A solver's motion that
breaks a limit (JM) keeps breaking it no more than it did: :func:`hlik.run_spec.RunSpec.check`
refuses JM.

The figures behind the defaults are in the README ("The whole take at once").
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np
import scipy.sparse as sp

from hlik.criteria import unified
from hlik.criteria.base import Term
from hlik.criteria.joints import TrunkUpright
from hlik.problem.problem import Problem
from hlik.problem.reference import HumanReference, reference_sample
from hlik.problem.targets import HandTargets
from hlik.robot.collision import CollisionPairs, collision_pairs, near_pairs
from hlik.robot.dynamics import inverse_model, motion_rates
from hlik.robot.model import SIDES, Robot
from hlik.robot.state import robot_state
from hlik.solvers.base import Solver, SolverResult
from hlik.solvers.catalog import WHOLE_TAKE
from hlik.solvers.frames import limit_rows
from hlik.solvers.limits import MotionLimits
from hlik.solvers.qp_backend import qpsolvers_solve
from hlik.solvers.settings import LimitSettings, WholeTakeSettings, settings_for
from hlik.util.spatial import rotation_vector

_EPS = 1e-6  # rad^2: damping of every step, so that the QP is strictly convex
# a step's torques may end this share of the effort beyond what is allowed: the feasibility
# tolerance of the torque rows, which are linear in a step and the torques are not. With the
# second-order correction what they miss is 1e-5 to 3e-3 N m (2-Panda, Peel take), against 0.09
# N m here on the Panda's largest joints; exactly at the allowed torque, steps that kept the
# hands' orientation were refused until the trust region was gone
TORQUE_TOLERANCE = 1e-3
CALLER_TOLERANCE = 1e-6  # a caller's limit's room a trial may end below 0 by (its rows' units)


@dataclass(frozen=True, eq=False)
class Linearisation:
    """A motion's TCP errors, torques and near pairs with their derivatives.

    Attributes:
        position: (T, 2, 3) TCP position minus target, m, base frame (left, right).
        orientation: (T, 2, 3) rotation vectors of R R*^T, rad.
        position_jacobian, orientation_jacobian: (T, 2, 3, n).
        torque: (T, n) joint torques, N m (the controller check's, :mod:`hlik.executable`).
        torque_jacobian: (T, 3, n, n) d tau_t / d q_{t-1}, d q_t, d q_{t+1}.
        pairs: Per frame, the near pairs' distances (k,), m, and gradients (k, n).
        criteria: Per criterion its weight, residuals (T, m) and their Jacobians (T, m, n).
    """

    position: np.ndarray
    orientation: np.ndarray
    position_jacobian: np.ndarray
    orientation_jacobian: np.ndarray
    torque: np.ndarray
    torque_jacobian: np.ndarray
    pairs: list[tuple[np.ndarray, np.ndarray]] = field(repr=False)
    criteria: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list, repr=False)

    @property
    def closest(self) -> float:
        """The least near-pair distance over the take, m (inf: none near)."""
        return min((float(d.min()) for d, _ in self.pairs if len(d)), default=math.inf)


class Take:
    """A robot and its TCP targets over a take: what each iteration linearises.

    ``pos`` (T, 2, 3), m, and ``rot`` (T, 2, 3, 3): the targets in the base frame; ``dt``: the
    frame period, s; ``detect``: pairs closer than this get rows, m; ``terms``: the criteria with
    their weights, evaluated against ``reference`` (the human's, T frames).
    """

    def __init__(
        self,
        robot: Robot,
        pos: np.ndarray,
        rot: np.ndarray,
        dt: float,
        detect: float,
        terms: Sequence[tuple[Term, float]] = (),
        reference: HumanReference | None = None,
    ) -> None:
        self.robot, self.pos, self.rot, self.dt, self.detect = robot, pos, rot, dt, detect
        self.terms, self.reference = tuple(terms), reference
        self.data = mujoco.MjData(robot.model)
        self.inverse = inverse_model(robot.model)
        self.inverse_data = mujoco.MjData(self.inverse)
        self.sites = [robot.site_id(side, "tcp") for side in SIDES]
        self.pairs: CollisionPairs = collision_pairs(robot)

    def linearise(self, q: np.ndarray) -> Linearisation:
        """The :class:`Linearisation` of the motion ``q`` (T, n)."""
        model, data = self.robot.model, self.data
        t_n, n = q.shape
        ep, eo = np.zeros((t_n, 2, 3)), np.zeros((t_n, 2, 3))
        jp, jo = np.zeros((t_n, 2, 3, model.nv)), np.zeros((t_n, 2, 3, model.nv))
        pairs = []
        for t in range(t_n):
            data.qpos[:] = q[t]  # the models' qpos are the joints, in order (robots/README.md)
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            for a, site in enumerate(self.sites):
                mujoco.mj_jacSite(model, data, jp[t, a], jo[t, a], site)
                ep[t, a] = data.site_xpos[site] - self.pos[t, a]
                eo[t, a] = rotation_vector(data.site_xmat[site].reshape(3, 3) @ self.rot[t, a].T)
            _, dist, grad = near_pairs(self.robot, data, self.pairs, self.detect)
            pairs.append((dist, grad[:, :n]))
        torque, tjac = self.torques(q)
        return Linearisation(ep, eo, jp[..., :n], jo[..., :n], torque, tjac, pairs, self.criteria(q))

    def criteria(self, q: np.ndarray) -> list[tuple[float, np.ndarray, np.ndarray]]:
        """Each term's weight, residuals (T, m) and Jacobians (T, m, n) at the motion ``q`` (T, n)."""
        if not self.terms or self.reference is None:
            return []
        # only the site Jacobians the terms read (SYN and HJA_r none), as the solvers compute them
        sites = tuple(sorted({i for t, _ in self.terms for i in (*t.sites, *t.value_sites)}))
        state = robot_state(self.robot, q, jacobians=bool(sites), data=self.data, jacobian_sites=sites)
        # the three frames before each, newest first (the first frame's are itself); the terms
        # here read one frame's pose, so only their Sample needs it
        before = np.clip(np.arange(len(q))[:, None] - np.arange(1, 4)[None], 0, None)
        sample = reference_sample(
            self.reference, HandTargets(self.pos, self.rot), slice(None), q[before], self.dt
        )
        return [(w, t.residual(state, sample), t.jacobian(state, sample)) for t, w in self.terms]

    def torques(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T, n) the torques of ``q`` as :func:`hlik.executable.controller_checks` computes them
        (velocity into frame t ``v_t = (q_t - q_t-1) / dt``, 0 into the first; acceleration
        ``(v_t+1 - v_t) / dt``, 0 at the last; torque at the central velocity), and (T, 3, n, n)
        their derivatives by q_t-1, q_t and q_t+1."""
        model, data, dt = self.inverse, self.inverse_data, self.dt
        t_n, n = q.shape
        _, qvel, qacc = motion_rates(np.diff(q, axis=0), dt, t_n)  # unlimited joints unwrapped
        torque, jac = np.empty((t_n, n)), np.zeros((t_n, 3, n, n))
        dfdq, dfdv, dfda = (np.empty((model.nv, model.nv)) for _ in range(3))
        for t in range(t_n):
            data.qpos[:], data.qvel[:], data.qacc[:] = q[t], qvel[t], qacc[t]
            mujoco.mj_inverse(model, data)
            torque[t] = data.qfrc_inverse[:n]
            mujoco.mjd_inverseFD(model, data, 1e-6, 0, dfdq, dfdv, dfda, None, None, None, None)
            dq, dv, da = dfdq.T[:n, :n], dfdv.T[:n, :n], dfda.T[:n, :n]  # MuJoCo's are transposed
            if t < t_n - 1:
                jac[t, 0] = da / dt**2 - dv / (2.0 * dt)
                jac[t, 1] = dq - 2.0 * da / dt**2
                jac[t, 2] = da / dt**2 + dv / (2.0 * dt)
            else:
                jac[t, 0], jac[t, 1] = -dv / dt, dq + dv / dt
        if t_n > 1:  # the first frame's q_t-1 is q_0 itself
            jac[0, 1] += jac[0, 0]
            jac[0, 0] = 0.0
        return torque, jac


@dataclass(frozen=True, eq=False)
class Refinement:
    """What :func:`refine` did.

    Attributes:
        q: (T, n) the refined motion, rad.
        iterations: QPs solved; ``accepted`` the steps kept.
        merit: The merit before and after.
        seconds: Wall time, s.
        capped: True where it stopped at ``iterations`` QPs, its merit still falling.
    """

    q: np.ndarray
    iterations: int
    accepted: int
    merit: tuple[float, float]
    seconds: float
    capped: bool = False


def difference_rows(t_n: int, order: int) -> sp.csr_matrix:
    """(T - 1, T) the ``order``-th differences of a take at rest before its first frame, as the
    controller check takes them: speed (1) into frames 1..T-1, acceleration (2) of frames 0..T-2,
    jerk (3) into frames 1..T-2 (its first row 0, as the check's first jerk)."""
    first = sp.diags([-1.0, 1.0], [0, 1], shape=(t_n - 1, t_n), format="csr")
    if order == 1:
        return first
    # velocities into frames 0..T-1 (the first 0), then their differences
    vel = sp.vstack([sp.csr_matrix((1, t_n)), first]).tocsr()
    acc = (sp.diags([-1.0, 1.0], [0, 1], shape=(t_n - 1, t_n)) @ vel).tocsr()
    if order == 2:
        return acc
    acc_full = sp.vstack([acc, sp.csr_matrix((1, t_n))]).tocsr()  # 0 at the last frame
    jerk = sp.diags([-1.0, 1.0], [0, 1], shape=(t_n - 1, t_n)) @ acc_full
    return sp.vstack([sp.csr_matrix((1, t_n)), jerk[:-1]]).tocsr()


@dataclass(frozen=True, eq=False)
class _Fixed:
    """What stays the same over a take's iterations.

    Attributes:
        run: (T, n) the solver's motion (unlimited joints unwrapped), rad.
        pull: (n,) each joint's pull toward it, per rad^2.
        lower, upper: (n,) the stops less the margin, rad.
        rates: The speed, acceleration and jerk rows on the flattened motion (T n,) and their
            bounds, rad per frame (those with a finite limit).
        effort: (n,) the effort limits, N m; ``limited`` the joints with one.
        strength: (T, k) the torques a step may end at, N m, on the ``limited`` joints: their
            fraction of the effort, or what the run asked where it asked more (not where the last
            step ended: that let a take creep over); refine allows :data:`TORQUE_TOLERANCE` of the
            effort more.
        band: (T, 2, 3) each hand's box per axis, m: the band, or as far off as the run left it.
        reach: (T, 2) how far off each hand may end, m.
        smooth: (T n, T n) the smoothness term's Hessian on the change to the run.
    """

    run: np.ndarray
    pull: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    rates: list[tuple[sp.csr_matrix, np.ndarray]]
    effort: np.ndarray
    limited: np.ndarray
    strength: np.ndarray
    band: np.ndarray
    reach: np.ndarray
    smooth: sp.csr_matrix


def refine(
    problem: Problem, q: np.ndarray, settings: WholeTakeSettings | None = None, limits: Sequence = ()
) -> Refinement:
    """The motion ``q`` (T, n) of ``problem`` improved over the whole take (module docstring),
    inside ``limits`` (a caller's ``mink.Limit`` objects, as the frame-by-frame solver kept them).

    Returns ``q`` itself (no step kept) where no step lowers the merit within the limits.
    """
    s = settings or WholeTakeSettings()
    start = time.perf_counter()
    robot = problem.robot
    t_n, n = q.shape
    if t_n < 2:
        return Refinement(q.copy(), 0, 0, (0.0, 0.0), time.perf_counter() - start)
    targets = problem.tracked
    terms = criterion_terms(problem, s)
    take = Take(robot, targets.pos, targets.rot, problem.dt, s.collision_detect, terms, problem.reference)
    unlimited = np.isinf(robot.lower)
    given = q
    q = q.copy()
    q[:, unlimited] = np.unwrap(q[:, unlimited], axis=0)  # a 2 pi jump is no step
    turns = q - given  # multiples of 2 pi, given back at the end
    lin = take.linearise(q)
    fixed = _fixed(robot, q, lin, problem.dt, s)
    caller = CallerLimits(robot, limits, problem.dt) if limits else None
    rows = caller.at(q) if caller else None  # the caller's rows at the current motion
    # (T,) what the run left of each frame's room: a start below 0 may stay so, no lower
    floor = np.minimum(rows.room, 0.0) - CALLER_TOLERANCE if rows else np.zeros(t_n)
    cost = first = _merit(lin, q, fixed, s)
    region, iterations, accepted, settled = s.trust_region, 0, 0, False
    miss = None  # what the torque rows' linearisation missed at the last trial, N m
    if cost == 0.0:  # every hand within its bands already
        region = 0.0
    while iterations < s.iterations and region >= s.min_trust_region:
        iterations += 1
        step = _step(lin, q, fixed, region, s, miss, rows)
        if step is None:
            region, miss = region / 2.0, None
            continue
        trial = q + step
        at_trial = take.linearise(trial)
        # no hand beyond its reach, no torque above the fraction of its effort (or above what the
        # run asked), no pair closer than half the margin (or than it was)
        limited = fixed.limited
        tolerance = TORQUE_TOLERANCE * fixed.effort[limited]
        strong = np.all(np.abs(at_trial.torque[:, limited]) <= fixed.strength + tolerance)
        within = np.all(np.linalg.norm(at_trial.position, axis=-1) <= fixed.reach)
        trial_cost = _merit(at_trial, trial, fixed, s)
        safe = strong and within and at_trial.closest >= min(0.5 * s.collision_margin, lin.closest)
        rows_at_trial = caller.at(trial) if safe and caller else None
        if rows_at_trial is not None:
            safe = bool(np.all(rows_at_trial.room >= floor))
        if safe and trial_cost < cost:
            settled = cost - trial_cost < s.tolerance * cost
            q, lin, cost, accepted, miss = trial, at_trial, trial_cost, accepted + 1, None
            rows = rows_at_trial  # computed where there is a caller: the step was safe
            region = min(1.5 * region, s.max_trust_region)
            if settled:
                break
        elif not strong and within and trial_cost < cost and miss is None:
            # a second-order correction (Nocedal & Wright, Numerical Optimization, 18.3): the same
            # region again, the torque rows shifted by what their linearisation missed at the
            # trial. Torques held at their fraction end a step over it by the rows' curvature
            # (2-Panda, Peel take: by 0.003-0.6 N m), and halving the region alone shrank it to
            # nothing (16 QPs, 4 steps kept)
            miss = _torque_miss(lin, at_trial, step, fixed)
        else:
            region, miss = region / 2.0, None
    capped = not settled and iterations == s.iterations and region >= s.min_trust_region
    return Refinement(q - turns, iterations, accepted, (first, cost), time.perf_counter() - start, capped)


def criterion_terms(problem: Problem, s: WholeTakeSettings) -> list[tuple[Term, float]]:
    """The criteria of ``s`` that read one frame's pose, each with its weight per squared
    residual, ``gamma_i * criterion_cost / len(criteria)`` (the criteria of motion, MJE and MIS,
    are left out: the smoothness term keeps the run's motion), and the trunk upright at
    ``trunk_upright`` (robots with extra joints)."""
    weighted = unified.weighted_criteria(
        s.criteria, problem.robot, problem.learned, s.criterion_cost, s.gamma
    )
    terms: list[tuple[Term, float]] = [(term, weight) for term, weight in weighted if not term.motion]
    if s.trunk_upright > 0 and problem.robot.extra_joints:
        terms.append((TrunkUpright(problem.robot), s.trunk_upright))
    return terms


def _fixed(robot: Robot, run: np.ndarray, lin: Linearisation, dt: float, s: WholeTakeSettings) -> _Fixed:
    """The :class:`_Fixed` of the motion ``run`` (T, n), linearised in ``lin``."""
    t_n, n = run.shape
    inner = MotionLimits.of(robot, LimitSettings(stop_margin=s.stop_margin))  # a fifth of a range at most
    pull = np.full(n, s.pull)
    pull[[robot.joint_names.index(j) for j in robot.extra_joints]] = s.trunk_pull
    eye = sp.identity(n, format="csr")
    limits = [robot.velocity_limit * dt, robot.acceleration_limit * dt**2, robot.jerk_limit * dt**3]
    rates = [
        (sp.kron(difference_rows(t_n, order), eye).tocsr(), np.tile(limit * s.headroom, t_n - 1))
        for order, limit in enumerate(limits, start=1)
        if np.any(np.isfinite(limit))
    ]
    # each axis of each hand within the band or as far off as the run left it; a step may end a
    # hand a band beyond that box's corner, for the curvature the rows do not see (a step of the
    # trust region on every joint bends a hand's path by millimetres), added, not scaled: a hand
    # the solver left 4 cm off may not end 6 cm off
    band = np.maximum(np.abs(lin.position), s.position_band)  # (T, 2, 3)
    limited = np.flatnonzero(np.isfinite(robot.effort_limit))
    effort = robot.effort_limit[limited]
    second = sp.kron(sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(t_n - 2, t_n)), eye)
    return _Fixed(
        run=run.copy(),
        pull=pull,
        lower=inner.inner_lower,
        upper=inner.inner_upper,
        rates=rates,
        effort=robot.effort_limit,
        limited=limited,
        strength=np.maximum(s.torque_fraction * effort, np.abs(lin.torque[:, limited])),
        band=band,
        reach=np.linalg.norm(band, axis=-1) + s.position_band,
        smooth=(s.smoothness * (second.T @ second)).tocsr(),
    )


def _near(s: WholeTakeSettings) -> float:
    """The distance, m, beyond which a hand's distance from its target costs linearly, not
    quadratically (the corner of its band)."""
    return math.sqrt(3.0) * s.position_band


def _merit(lin: Linearisation, q: np.ndarray, fixed: _Fixed, s: WholeTakeSettings) -> float:
    dist, near = np.linalg.norm(lin.position, axis=-1), _near(s)
    off = s.position_cost * np.sum(np.where(dist <= near, dist**2, 2.0 * near * dist - near**2))
    turned = np.maximum(np.linalg.norm(lin.orientation, axis=-1) - s.orientation_band, 0.0)
    change = q - fixed.run
    return float(
        off
        + sum(w * np.sum(e**2) for w, e, _ in lin.criteria)
        + np.sum(turned**2)
        + np.sum(fixed.pull * change**2)
        + s.smoothness * np.sum(np.diff(change, 2, axis=0) ** 2)
    )


def _torque_miss(lin: Linearisation, trial: Linearisation, step: np.ndarray, fixed: _Fixed) -> np.ndarray:
    """(T, k) the torques of the effort-limited joints at the trial ``step`` less their
    linearisation's prediction in ``lin``, N m."""
    t_n, n = step.shape
    limited = fixed.limited
    rows = _torque_rows(lin.torque_jacobian[:, :, limited], t_n, n)
    predicted = lin.torque[:, limited] + (rows @ step.reshape(-1)).reshape(t_n, len(limited))
    return trial.torque[:, limited] - predicted


def _step(
    lin: Linearisation,
    q: np.ndarray,
    fixed: _Fixed,
    region: float,
    s: WholeTakeSettings,
    miss: np.ndarray | None = None,
    caller: CallerRows | None = None,
) -> np.ndarray | None:
    """(T, n) the QP's step from ``q`` within the trust ``region``, rad, or None where it has no
    solution; ``miss`` (T, k), N m, shifts the torque rows by what their linearisation missed at
    the last trial (:func:`_torque_miss`); ``caller``: a caller's limit rows ``G dq <= h``
    at ``q`` (:meth:`CallerLimits.at`)."""
    t_n, n = q.shape
    jo, jp = lin.orientation_jacobian, lin.position_jacobian
    change = q - fixed.run
    # each hand turned beyond the band: the least squares of its rotation vector shortened by the band
    angle = np.linalg.norm(lin.orientation, axis=-1, keepdims=True)  # (T, 2, 1)
    weight = (angle > s.orientation_band).astype(float)
    residual = lin.orientation * (1.0 - s.orientation_band / np.maximum(angle, 1e-12)) * weight
    jw = jo * weight[..., None]
    hessian = np.einsum("tacn,tacm->tnm", jw, jw) + np.diag(fixed.pull + _EPS)
    gradient = np.einsum("tacn,tac->tn", jw, residual) + fixed.pull * change
    for w, e, j in lin.criteria:  # Gauss-Newton on each criterion's residual
        hessian += w * np.einsum("tmn,tmk->tnk", j, j)
        gradient += w * np.einsum("tmn,tm->tn", j, e)
    if s.position_cost > 0.0:
        # the hands as near their targets as the rest allows: the square of the distance within
        # the band's corner, beyond it linear (Huber; as reweighted least squares), so that a hand
        # out of reach is not pulled in at its orientation's cost
        dist = np.linalg.norm(lin.position, axis=-1)
        weight = np.sqrt(s.position_cost * np.minimum(1.0, _near(s) / np.maximum(dist, 1e-12)))
        jn = jp * weight[..., None, None]
        hessian += np.einsum("tacn,tacm->tnm", jn, jn)
        gradient += np.einsum("tacn,tac->tn", jn, lin.position * weight[..., None])
    rows, upper = [], []

    def keep(a: sp.spmatrix, value: np.ndarray, lower: np.ndarray, high: np.ndarray) -> None:
        # lower <= a @ (x + dq) <= high with a @ x = value; a bound the start breaks moves to it
        rows.extend([a, -a])
        upper.extend([np.maximum(high - value, 0.0), np.maximum(value - lower, 0.0)])

    flat = q.reshape(-1)
    for a, bound in fixed.rates:
        finite = np.isfinite(bound)
        keep(a[finite], a[finite] @ flat, -bound[finite], bound[finite])
    hands = sp.block_diag(list(jp.reshape(t_n, 6, n)), format="csr")
    keep(hands, lin.position.reshape(-1), -fixed.band.reshape(-1), fixed.band.reshape(-1))
    limited = fixed.limited
    if len(limited):
        # rows for the torques above torque_watch of their efforts only (a step that takes another
        # over its effort is refused by refine)
        effort = np.tile(fixed.effort[limited], t_n)
        value = lin.torque[:, limited].reshape(-1)
        watched = np.abs(value) > s.torque_watch * effort
        if miss is not None:  # and those the last trial took there
            watched |= np.abs(value + miss.reshape(-1)) > s.torque_watch * effort
        torque_rows = _torque_rows(lin.torque_jacobian[:, :, limited], t_n, n)[watched]
        allowed = s.torque_fraction * effort[watched]
        if miss is None:
            keep(torque_rows, value[watched], -allowed, allowed)
        else:  # what refine allows without its tolerance, less the miss
            cap, shift = fixed.strength.reshape(-1)[watched], miss.reshape(-1)[watched]
            rows.extend([torque_rows, -torque_rows])
            upper.extend([cap - value[watched] - shift, cap + value[watched] + shift])
    if caller is not None and caller.g.shape[0]:
        rows.append(caller.g)
        upper.append(np.maximum(caller.h, 0.0))  # a row the start breaks moves to it
    near = [(t, d, g) for t, (d, g) in enumerate(lin.pairs) if len(d)]
    if near:  # each near pair's distance d + g dq_t at least the margin (or d)
        frames = np.concatenate([np.full(len(d), t) for t, d, _ in near])
        gradients = np.concatenate([g for _, _, g in near])  # (k, n)
        k = len(frames)
        cols = (frames[:, None] * n + np.arange(n)).reshape(-1)
        placed = sp.csr_matrix(
            (gradients.reshape(-1), (np.repeat(np.arange(k), n), cols)), shape=(k, t_n * n)
        )
        dist = np.concatenate([d for _, d, _ in near])
        rows.append(-placed)
        upper.append(np.maximum(dist - np.minimum(s.collision_margin, dist), 0.0))
    box_lo = np.minimum(np.maximum(np.tile(fixed.lower, t_n) - flat, -region), 0.0)
    box_hi = np.maximum(np.minimum(np.tile(fixed.upper, t_n) - flat, region), 0.0)
    # the take ends as the solver ended it: its last two frames, from which it can brake before
    # the stops' margins (the solvers keep that; the rows here do not)
    box_lo[-2 * n :], box_hi[-2 * n :] = 0.0, 0.0
    with warnings.catch_warnings(record=True) as said:  # Clarabel short of its tolerances
        warnings.simplefilter("always")
        x = qpsolvers_solve(
            (sp.block_diag(list(hessian)) + fixed.smooth).tocsc(),
            gradient.reshape(-1) + fixed.smooth @ change.reshape(-1),
            sp.vstack(rows).tocsc(),
            np.concatenate(upper),
            lb=box_lo,
            ub=box_hi,
            solver="clarabel",
        )
    if said or x is None or not np.all(np.isfinite(x)):  # the rows kept only roughly: no step
        return None
    return np.clip(x, box_lo, box_hi).reshape(t_n, n)


@dataclass(frozen=True, eq=False)
class CallerRows:
    """A caller's limit rows over the whole take at one motion: ``g @ dq <= h``, (K, T n) and
    (K,), every frame's stacked; ``room`` (T,) each frame's least ``h`` (0 on the limit, inf where
    no row is active)."""

    g: sp.csr_matrix
    h: np.ndarray
    room: np.ndarray


class CallerLimits:
    """A caller's ``mink.Limit`` objects over the whole take: each frame's rows ``G dq_t <= h`` at its
    configuration (:func:`hlik.solvers.frames.limit_rows`, the frame-by-frame solvers' own), placed
    in the take's step."""

    def __init__(self, robot: Robot, limits: Sequence, dt: float):
        import mink  # the caller's limits are mink's: it is there

        self.limits, self.dt, self.n = tuple(limits), dt, robot.dof
        self.config = mink.Configuration(robot.model, robot.home)

    def at(self, q: np.ndarray) -> CallerRows:
        """The :class:`CallerRows` at the motion ``q`` (T, n)."""
        frames = []
        for q_t in q:
            self.config.update(q_t)
            frames.append(limit_rows(self.limits, self.config, self.dt, self.n))
        return CallerRows(
            sp.block_diag([g for g, _ in frames], format="csr"),
            np.concatenate([h for _, h in frames]),
            np.array([h.min(initial=np.inf) for _, h in frames]),
        )


def _torque_rows(jac: np.ndarray, t_n: int, n: int) -> sp.csr_matrix:
    """(T k, T n) the torque rows from (T, 3, k, n) derivatives by q_t-1, q_t, q_t+1."""
    k = jac.shape[2]
    t = np.arange(t_n)[:, None, None, None]
    neighbour = np.clip(t + np.arange(-1, 2)[None, :, None, None], 0, t_n - 1)
    row = np.broadcast_to(t * k + np.arange(k)[None, None, :, None], jac.shape)
    col = np.broadcast_to(neighbour * n + np.arange(n)[None, None, None, :], jac.shape)
    return sp.csr_matrix((jac.reshape(-1), (row.reshape(-1), col.reshape(-1))), shape=(t_n * k, t_n * n))


@dataclass(frozen=True)
class WholeTake:
    """A solver whose frame-by-frame result is then optimised over the whole take (:func:`refine`);
    its name is the inner solver's with ``+whole``. ``settings`` None: the defaults with the inner
    solver's limits and criteria (:func:`settings_for` of its ``settings``, where it has them: the
    solvers of :func:`hlik.solvers.get_solver`); given, they are used as they are.
    ``announce(stage)``, if given, is told when the whole-take stage starts, ``report(refinement)``
    what it did."""

    inner: Solver
    settings: WholeTakeSettings | None = None
    announce: Callable[[str], None] | None = None
    report: Callable[[Refinement], None] | None = None
    limits: Sequence = ()  # a caller's mink.Limits, kept as the inner solver keeps them

    @property
    def name(self) -> str:
        return f"{self.inner.name}{WHOLE_TAKE}"

    @property
    def stage(self) -> WholeTakeSettings:
        """The settings the stage runs with."""
        return self.settings or settings_for(getattr(self.inner, "settings", None))

    @property
    def criteria(self) -> tuple[str, ...]:
        """The inner solver's criteria, then the stage's own (what the problem learns pieces for)."""
        inner = tuple(getattr(self.inner, "criteria", ()))
        return inner + tuple(c for c in self.stage.criteria if c not in inner)

    def __call__(self, problem: Problem) -> SolverResult:
        result = self.inner(problem)
        if self.announce is not None:
            self.announce(f"optimising the whole take ({problem.n_frames} frames)")
        done = refine(problem, result.q, self.stage, self.limits)
        if self.report is not None:
            self.report(done)
        diagnostics = replace(
            result.diagnostics,
            solve_time=result.diagnostics.solve_time + done.seconds / max(problem.n_frames, 1),
        )
        info = {**result.info, "whole_take": done}
        return SolverResult(done.q, diagnostics, info)


__all__ = [
    "Linearisation",
    "Refinement",
    "Take",
    "WholeTake",
    "WholeTakeSettings",
    "criterion_terms",
    "difference_rows",
    "refine",
    "settings_for",
]
