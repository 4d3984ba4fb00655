"""Look-ahead for the frame-by-frame solvers (QP, SLSQP): a joint path that starts each motion early
enough.

Solved frame by frame, a solver accelerates only once the target has moved, and brakes only once it
is there: where the hands turn faster than the joints' acceleration limits follow, the hand lags,
and what the QP's weights then give away first is the orientation. Measured on four KIT takes × 5 s
without criteria (plain QP, every limit on), 2-Panda's hands are turned a median 8.0° off their
targets at the takes' speed, 2.2° with the acceleration and torque limits off, 0.8° at half the
speed: its datasheet accelerations, not its joint ranges, hold the hand back.

The look-ahead sees the whole take at once. The QP first retargets it without the acceleration
and torque limits (what the arm would do if it could), then :func:`feasible_path` finds, joint by
joint, the path nearest to that one which keeps the stops (with their margin), speed, acceleration
and jerk limits: a least-squares fit over all frames, which starts a swing
before the target does and brakes before it stops. The QP then retargets the take again, with
every limit and a :class:`PathTask` pulling toward that path beside its own terms, so the hands,
the criteria and the limits of every frame (torques, self-collision) still decide. SLSQP does the
same with its own passes and a groove loss on :class:`PathTerm`, the distance to the path's frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import mink
import numpy as np
import osqp
import scipy.sparse as sp
from scipy.interpolate import BSpline

from hlik.criteria.angles import joint_difference
from hlik.criteria.base import Term, block_norm_cost, block_norm_gradient
from hlik.problem.problem import Problem
from hlik.solvers.base import SolverResult
from hlik.solvers.limits import MotionLimits

# OSQP takes bounds this large as none (unlimited joints, robots without acceleration limits)
_NONE = 1e20
# the share of the speed, acceleration and jerk limits the path may use: a path at the limits is
# bang-bang, and a tracker a little off it could never catch up (2-Panda's QP drifted 0.2 rad off a
# full-limit path and turned its hands 14 deg where the path had 1). Two KIT takes x 5 s, plain QP,
# weight 3: median fORI 7.2 deg at 1.0, 5.6 at 0.8, 2.3 at 0.5, 2.9 at 0.4 (without the path: 7.2)
HEADROOM = 0.5
# the path's knots this far apart, s: 25 Hz, a quarter of the unknowns of one per 100 Hz frame,
# where a fit of every frame took 4 s for a take of 5 s (OSQP), and smooth enough for a human's
# motion (a slow sine is fitted to 1e-4 rad)
KNOT_PERIOD = 0.04


# the fewest frames a take is looked ahead on: with one or two there is no motion to start early
LOOK_AHEAD_FRAMES = 3


def solve_with_look_ahead(
    problem: Problem,
    settings: Any,
    solve_pass: Callable[[Any, Callable[[int], None] | None, np.ndarray | None], SolverResult],
    progress: Callable[[int], None] | None = None,
    **first: Any,
) -> SolverResult:
    """A take solved with the look-ahead, for any solver whose frozen ``settings`` have the
    :class:`~hlik.solvers.settings.LimitSettings` switches and a ``preview_cost``.

    ``solve_pass(settings, progress, path)`` solves the take once. Where ``settings.preview_cost``
    is 0 or the take has fewer than :data:`LOOK_AHEAD_FRAMES` frames, that is all, without a path.
    Else it runs twice: first with the acceleration and torque limits off, no pull and the changes
    ``first`` (the QP's hands first), without a path; then with ``settings`` and the path (T, n),
    rad, that :func:`feasible_path` fits to the first pass within every limit, ``progress(k)``
    seeing each pass as half the frames. Returns the last pass's result.
    """
    n = problem.n_frames
    if settings.preview_cost <= 0 or n < LOOK_AHEAD_FRAMES:
        return solve_pass(settings, progress, None)
    half = (lambda k: progress(k // 2)) if progress else None
    free = replace(settings, acceleration_limits=False, torque_limits=False, preview_cost=0.0, **first)
    unlimited = solve_pass(free, half, None)
    path = feasible_path(unlimited.q, MotionLimits.of(problem.robot, settings), problem.dt)
    second = (lambda k: progress((n + k) // 2)) if progress else None
    return solve_pass(settings, second, path)


def feasible_path(q: np.ndarray, limits: MotionLimits, dt: float, headroom: float = HEADROOM) -> np.ndarray:
    """The joint path nearest to ``q`` (T, n), rad, that keeps ``limits``, at frame period ``dt``, s.

    Per joint: a uniform cubic B-spline r(t) with knots :data:`KNOT_PERIOD` apart, its control
    points c fitted by least squares to the frames, ``argmin_c Σ_t (r(t) − q_t)²``, subject to the
    stops moved in by their margin, and the speed, acceleration and jerk limits (the last two where
    given) times ``headroom``, so that a tracker a little off the path can catch up with it; it
    starts at the first frame at rest (``c0 = c1 = c2 = q_0``), as the solvers do: a span of a take
    starts mid-motion, and a path already moving there had the QP swing the hand about a still
    target while it caught up (2-Panda, Cut take 2–6 s: up to 2 cm for a second). The
    bounds are linear rows on c: a B-spline and its derivatives are convex combinations of the
    control points and their divided differences, so ``|Δ^k c| ≤ headroom · limit · h^k`` (h the
    knot period) bounds r's k-th derivative everywhere between the knots, not only at them. A sparse
    QP (OSQP) of T / 4 unknowns per joint at 100 Hz.

    Returns:
        (T, n) the path; ``q`` itself where the take spans fewer than two knot periods.

    Raises:
        RuntimeError: OSQP finds no solution (the limits contradict: a stop margin wider than the
            range).
    """
    q = np.asarray(q, dtype=float)
    frames, n = q.shape
    every = max(1, int(round(KNOT_PERIOD / dt)))
    spans = -(-(frames - 1) // every)  # knot intervals covering the frames
    if spans < 2:
        return q.copy()
    knots = (np.arange(spans + 7) - 3) * float(every)  # uniform, in frames; the take in [knots[3], knots[-4]]
    basis = BSpline.design_matrix(np.arange(frames, dtype=float), knots, 3).tocsc()  # (T, spans + 3)
    step = every * dt
    path = np.empty_like(q)
    for j in range(n):
        largest = np.array(
            [limits.velocity[j] * step, limits.acceleration[j] * step**2, limits.jerk[j] * step**3]
        )
        stops = (limits.inner_lower[j], limits.inner_upper[j])
        path[:, j] = basis @ _control_points(basis, q[:, j], stops, headroom * largest)
    return np.clip(path, limits.inner_lower, limits.inner_upper)


def _control_points(
    basis: sp.csc_matrix, q: np.ndarray, stops: tuple[float, float], steps: np.ndarray
) -> np.ndarray:
    """One joint of :func:`feasible_path`: the control points (K,) whose spline ``basis`` (T, K) is
    nearest ``q`` (T,), within ``stops`` and with their first, second and third differences within
    ``steps``."""
    count = basis.shape[1]
    rows = [sp.eye(count, format="csc")]
    bounds = [np.clip(stops, -_NONE, _NONE)]
    for order, step in enumerate(steps, start=1):
        if np.isfinite(step) and count > order:
            rows.append(_difference(count, order))
            bounds.append(np.array([-step, step]))
    lower = np.concatenate([np.full(r.shape[0], b[0]) for r, b in zip(rows, bounds, strict=True)])
    upper = np.concatenate([np.full(r.shape[0], b[1]) for r, b in zip(rows, bounds, strict=True)])
    if count > 2:  # at the first frame at rest, as the solvers start there: c0 = c1 = c2 = q_0
        start = sp.eye(3, count, format="csc")
        rows.append(start)
        lower = np.concatenate([lower, np.full(3, np.clip(q[0], *stops))])
        upper = np.concatenate([upper, np.full(3, np.clip(q[0], *stops))])
    hessian = (basis.T @ basis + 1e-9 * sp.eye(count)).tocsc()  # the end points touch few frames
    solver = osqp.OSQP()
    solver.setup(
        P=sp.csc_matrix(sp.triu(hessian)),  # OSQP takes scipy's csc_matrix, not its sparse arrays
        q=-(basis.T @ q),
        A=sp.csc_matrix(sp.vstack(rows)),
        l=lower,
        u=upper,
        verbose=False,
        eps_abs=1e-7,
        eps_rel=1e-7,
        max_iter=50000,
        polishing=False,  # OSQP prints to stdout where polishing finds no active set
    )
    result = solver.solve(raise_error=False)  # the status is checked below
    if result.x is None or not np.all(np.isfinite(result.x)):
        raise RuntimeError(f"no joint path within the limits (OSQP: {result.info.status})")
    return np.clip(result.x, *stops)


def _difference(frames: int, order: int) -> sp.csc_matrix:
    """(T − order, T) the ``order``-th forward difference."""
    coefficients = np.array([1.0])
    for _ in range(order):
        coefficients = np.convolve(coefficients, [-1.0, 1.0])
    diagonals = [np.full(frames - order, c) for c in coefficients]
    return sp.diags(diagonals, list(range(order + 1)), shape=(frames - order, frames), format="csc")


class PathTask(mink.PostureTask):
    """mink's ``PostureTask`` toward a joint path, one configuration per frame: its target is frame
    k's row once :meth:`at` is called (:class:`~hlik.solvers.mink_ik.MinkSolver` calls it with each
    frame's index). ``path`` (T, n), rad; ``cost`` per rad, as ``PostureTask``'s."""

    def __init__(self, model, path: np.ndarray, cost: float):
        super().__init__(model, cost)
        self.path = np.asarray(path, dtype=float)

    def at(self, k: int) -> None:
        """Aim at frame ``k``'s configuration."""
        self.set_target(self.path[k])


class PathTerm(Term):
    """The look-ahead as a term, for SLSQP's groove losses: the distance (rad) of the configuration
    from frame k's on a joint path, once :meth:`at` is called with the frame's index. Its cost is
    the norm of ``q − path[k]`` (angular differences on unlimited joints), as RelaxedIK's
    smoothness terms are the norm of theirs. ``path`` (T, n), rad."""

    name, sites, part_form, needs_sample = "path", (), "norm", False

    def __init__(self, robot, path: np.ndarray):
        self.path = np.asarray(path, dtype=float)
        self.unlimited = np.isinf(robot.lower)
        self.constant_jacobian = np.eye(robot.dof)
        self.target = self.path[0]

    def at(self, k: int) -> None:
        """Aim at frame ``k``'s configuration."""
        self.target = self.path[k]

    def residual(self, state, sample):
        return joint_difference(state.q, self.target, self.unlimited)

    def cost(self, e):
        return block_norm_cost(e, 1)

    def cost_gradient(self, e):
        return block_norm_gradient(e, 1)
