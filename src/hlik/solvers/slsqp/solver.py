"""SLSQP per frame with NLopt: the optimizer, the frame's solve (band first, then relaxed), the
frame loop, and which NLopt exceptions fail a frame rather than the run."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from functools import partial
from types import MappingProxyType

import mink
import nlopt
import numpy as np

from hlik.criteria.base import Sample
from hlik.problem.problem import Problem
from hlik.robot.collision import collision_pairs
from hlik.robot.model import Robot
from hlik.solvers.base import ConfiguredSolver, SolverResult
from hlik.solvers.frames import FrameResult, JointBox, box_with_limits, track
from hlik.solvers.limits import MotionLimits
from hlik.solvers.preview import PathTerm, solve_with_look_ahead
from hlik.solvers.settings import SLSQPSettings
from hlik.solvers.slsqp.constraints import (
    BAND_TOLERANCE,
    BOX_TOLERANCE,
    COLLISION_TOLERANCE,
    BandConstraint,
    BoxConstraint,
    CollisionConstraint,
)
from hlik.solvers.slsqp.objective import Chart, Loss, Objective, build_losses

# NLopt exceptions that end one frame, not the run, and the result code each stands for. NLopt's
# generic failure also comes as a plain RuntimeError("nlopt failure"): only that message counts, so
# that a RuntimeError raised by hlik's own code in a callback (a bug) stops the run instead of
# passing for a failed frame.
NLOPT_ERRORS: Mapping[type[Exception], int] = MappingProxyType(
    {
        nlopt.RoundoffLimited: nlopt.ROUNDOFF_LIMITED,
        nlopt.ForcedStop: nlopt.FORCED_STOP,
        nlopt.runtime_error: nlopt.FAILURE,
        RuntimeError: nlopt.FAILURE,
    }
)
NLOPT_FAILURE_MESSAGE = "nlopt failure"
# A roundoff-limited frame is usable (unconverged, not failed) where the point kept misses the body's
# constraints by at most this beyond their tolerances (m for collision, rad or N m for the box's
# rows): as the QP's soft rows give way a little. 2-Panda's arm braking before its chest (a target
# there) stopped SLSQP roundoff-limited 1.3e-3 past its constraints on one machine, 9.9 mm from its
# body (margin 1 cm), in contact nowhere.
ROUNDOFF_MISS = 2e-3


def _nlopt_code(err: Exception) -> int | None:
    """NLopt's result code for an exception NLopt raised, None for any other."""
    for kind, code in NLOPT_ERRORS.items():
        if isinstance(err, kind):
            if kind is RuntimeError and str(err) != NLOPT_FAILURE_MESSAGE:
                return None
            return code
    return None


def make_optimizer(robot: Robot, settings: SLSQPSettings) -> nlopt.opt:
    """NLopt's SLSQP over ``robot``'s joints; unlimited joints keep their infinite bounds."""
    opt = nlopt.opt(nlopt.LD_SLSQP, robot.dof)
    opt.set_lower_bounds(np.asarray(robot.lower, dtype=float))
    opt.set_upper_bounds(np.asarray(robot.upper, dtype=float))
    opt.set_ftol_rel(settings.ftol_rel)
    return opt


def solve_frame(
    opt: nlopt.opt,
    objective: Objective,
    frame: Sample,
    q0: np.ndarray,
    max_eval: int,
    box: JointBox,
    collision: CollisionConstraint | None = None,
    band: BandConstraint | None = None,
) -> tuple[np.ndarray, int]:
    """Minimise ``objective`` at ``frame`` from ``q0`` (n,) within ``box`` (and clear of
    ``collision``, the hands inside ``band``), in the objective's chart when it sets one. With a
    band, the frame is solved with the hands inside it first and, where that ends outside it (the
    band cannot be met from here), again with them no worse than as near as the frame can bring
    them (:func:`_nearest_band`): a hand held at its start's error, a criterion weighed above the
    hands kept ARMAR-6's 3.8 cm off its reachable target for a whole stretch after a first frame
    that NLopt ended roundoff-limited.

    Returns:
        (n,) the solution and NLopt's result code; on failure (negative code) the configuration
        evaluated that missed the body's constraints least, of those the lowest finite objective
        (:class:`Evaluated`), else ``q0``.
    """
    if band is None or not len(band):
        return _solve_once(opt, objective, frame, q0, max_eval, box, collision, None)
    q, status = _solve_once(opt, objective, frame, q0, max_eval, box, collision, band, strict=True)
    if status > 0 and band.met(q):
        return q, status
    near = _nearest_band(band, frame, q0, max_eval, box, collision)
    q, status = _solve_once(
        opt, objective, frame, q0, max_eval, box, collision, band, strict=False, near=near
    )
    # a failed run's fallback ignores the band: where it left a hand further out than ``near``,
    # the frame keeps ``near`` (hands first; still counted failed)
    return (q, status) if status > 0 or band.holds(q) else (near, status)


def _nearest_band(
    band: BandConstraint,
    frame: Sample,
    q0: np.ndarray,
    max_eval: int,
    box: JointBox,
    collision: CollisionConstraint | None,
) -> np.ndarray:
    """(n,) the configuration within ``box`` (and clear of ``collision``) nearest the band from
    ``q0``: the hands' squared misses (:meth:`BandConstraint.misses`) minimised alone; ``q0`` where
    NLopt finds none better."""
    band.reset(frame, q0, None, strict=True)
    opt = nlopt.opt(nlopt.LD_SLSQP, len(q0))
    opt.set_ftol_rel(1e-8)
    opt.set_maxeval(max_eval)
    seen = Evaluated()
    _add_collision(opt, collision, None, seen)
    _add_box(opt, box, None, seen)
    opt.set_min_objective(band.misses)
    start = band.misses(q0, np.zeros(0))
    try:
        q = opt.optimize(q0)
    except tuple(NLOPT_ERRORS) as err:
        if _nlopt_code(err) is None:
            raise
        return q0
    fine = np.all(np.isfinite(q)) and band.misses(q, np.zeros(0)) <= start
    return np.asarray(q, dtype=float) if fine else q0


def _solve_once(
    opt: nlopt.opt,
    objective: Objective,
    frame: Sample,
    q0: np.ndarray,
    max_eval: int,
    box: JointBox,
    collision: CollisionConstraint | None,
    band: BandConstraint | None,
    strict: bool = False,
    near: np.ndarray | None = None,
) -> tuple[np.ndarray, int]:
    """One NLopt run of :func:`solve_frame`; ``strict``: the band as it is, else relaxed to the
    hands' errors at ``near`` (``q0`` if None).
    Where NLopt stops roundoff-limited and the point kept misses the body's constraints by more than
    :data:`ROUNDOFF_MISS`, the frame fails (a restart from that point, tried, ended the same)."""
    objective.reset(frame, q0)
    chart = objective.chart
    opt.remove_inequality_constraints()
    seen = Evaluated()
    _add_collision(opt, collision, chart, seen)
    if band is not None:
        band.reset(frame, q0 if near is None else near, chart, strict)
        # not recorded: a fallback keeps the body's constraints, and the hands as near as it can
        opt.add_inequality_mconstraint(band, np.full(len(band), BAND_TOLERANCE))
    _add_box(opt, box, chart, seen)
    x0 = q0 if chart is None else np.zeros(len(q0))
    opt.set_min_objective(seen.objective(objective))
    opt.set_maxeval(max_eval)
    try:
        x = opt.optimize(x0)
        status = opt.last_optimize_result()
        q = x if chart is None else chart.q(x)
        if not (np.all(np.isfinite(q)) and np.isfinite(opt.last_optimum_value())):
            q, status = None, nlopt.FAILURE
    except tuple(NLOPT_ERRORS) as err:
        code = _nlopt_code(err)
        if code is None:
            raise
        q, status = None, code
    if q is None:
        q, status = _fallback(seen, chart, q0, status)
    return np.asarray(q, dtype=float), int(status)


def _add_collision(
    opt: nlopt.opt, collision: CollisionConstraint | None, chart: Chart | None, seen: Evaluated
) -> None:
    """``collision``'s rows on ``opt``, in ``chart``'s variables (q if None), recorded in ``seen``."""
    if collision is not None:
        collision.chart = chart
        tolerance = np.full(collision.settings.collision_pairs, COLLISION_TOLERANCE)
        opt.add_inequality_mconstraint(seen.constraint(collision, COLLISION_TOLERANCE), tolerance)


def _add_box(opt: nlopt.opt, box: JointBox, chart: Chart | None, seen: Evaluated) -> None:
    """The joint box on ``opt``: NLopt's bounds in q (none in a chart's variables, where it is
    rows), and its rows (:class:`BoxConstraint`), recorded in ``seen``."""
    n = len(box.lower)
    opt.set_lower_bounds(box.lower if chart is None else np.full(n, -np.inf))
    opt.set_upper_bounds(box.upper if chart is None else np.full(n, np.inf))
    bounds = BoxConstraint(chart, box)
    if len(bounds):
        # a joint starting on its limit starts on the row: with no tolerance, rounding in A x
        # made SLSQP's line search fail (ROUNDOFF_LIMITED) on 7 % of ARMAR-6's Cut frames
        opt.add_inequality_mconstraint(
            seen.constraint(bounds, BOX_TOLERANCE), np.full(len(bounds), BOX_TOLERANCE)
        )


def _fallback(seen: Evaluated, chart: Chart | None, q0: np.ndarray, status: int) -> tuple[np.ndarray, int]:
    """Where NLopt stopped without a result: the point it evaluated that misses the body's
    constraints least, the lowest objective among equals (``q0`` if none), as the QP's soft rows
    give way; the lowest objective alone had put 2-Panda's arm 4 cm into its chest (a target there,
    on a machine whose rounding stopped SLSQP ROUNDOFF_LIMITED 16 frames running). A
    roundoff-limited stop stays one (usable) only where that point misses them by at most
    :data:`ROUNDOFF_MISS`; else the frame failed."""
    best = seen.best()
    q = q0 if best is None else (best[0] if chart is None else chart.q(best[0]))
    if status == nlopt.ROUNDOFF_LIMITED and (best is None or best[1] > ROUNDOFF_MISS):
        status = nlopt.FAILURE
    return q, status


class Evaluated:
    """The points NLopt evaluated in one run, with their objective and by how much they missed the
    body's constraints (collision, the box's rows; beyond their tolerance), to fall back on where
    NLopt stops without a result."""

    def __init__(self) -> None:
        self.values: dict[bytes, tuple[float, np.ndarray]] = {}
        self.violation: dict[bytes, float] = {}

    def objective(self, f: Callable[[np.ndarray, np.ndarray], float]) -> Callable:
        def recorded(x: np.ndarray, grad: np.ndarray) -> float:
            value = f(x, grad)
            self.values[x.tobytes()] = (float(value), x.copy())
            return value

        return recorded

    def constraint(
        self, c: Callable[[np.ndarray, np.ndarray, np.ndarray], None], tolerance: float
    ) -> Callable:
        def recorded(result: np.ndarray, x: np.ndarray, grad: np.ndarray) -> None:
            c(result, x, grad)
            key, worst = x.tobytes(), float(np.max(result - tolerance, initial=0.0))
            self.violation[key] = max(self.violation.get(key, 0.0), worst)

        return recorded

    def best(self) -> tuple[np.ndarray, float] | None:
        """The evaluated point that misses the constraints least (the most any misses by, beyond
        its tolerance), of those the lowest finite objective, and that miss; None if none."""
        points = [(self.violation.get(k, 0.0), v, x) for k, (v, x) in self.values.items() if np.isfinite(v)]
        if not points:
            return None
        miss, _, x = min(points, key=lambda item: item[:2])
        return x, miss


def solve(
    problem: Problem,
    settings: SLSQPSettings = SLSQPSettings(),
    progress: Callable[[int], None] | None = None,
    limits: Sequence[mink.Limit] = (),
) -> SolverResult:
    """Retarget frame by frame; ``limits``: a caller's ``mink.Limit``\\ s, their rows taken at
    each frame's start and kept as linear constraints with the box's
    (:func:`~hlik.solvers.frames.box_with_limits`; a frame that cannot keep them fails).

    With ``settings.preview_cost`` the take is solved twice, as the QP's look-ahead
    (:mod:`hlik.solvers.preview`): first without the acceleration and torque limits, then with
    every limit and a :class:`~hlik.solvers.preview.PathTerm` loss toward the nearest path that
    keeps them; the diagnostics are the second pass's.

    Diagnostics: ``iterations`` counts NLopt's objective evaluations (``fd``: each costs n + 1 FK
    passes), a frame has converged when NLopt stopped by its tolerance (not ``MAXEVAL_REACHED``) and
    failed when NLopt failed or returned a non-finite result; ``info["status"]`` (T,) holds NLopt's
    result codes.
    """

    def solve_pass(s: SLSQPSettings, progress, path: np.ndarray | None) -> SolverResult:
        toward = None if path is None else PathTerm(problem.robot, path)
        return _solve_pass(problem, s, progress, limits, toward)

    return solve_with_look_ahead(problem, settings, solve_pass, progress)


def _solve_pass(
    problem: Problem,
    settings: SLSQPSettings,
    progress: Callable[[int], None] | None,
    limits: Sequence[mink.Limit],
    path: PathTerm | None = None,
) -> SolverResult:
    """One pass of :func:`solve` over the take, with a loss toward ``path`` (weight
    ``settings.preview_cost``) if given."""
    robot, learned = problem.robot, problem.learned
    s = settings
    toward = [Loss(path, s.preview_cost, 1.0)] if path is not None else []
    losses, first_losses = ([*build_losses(robot, s, learned, first), *toward] for first in (False, True))
    objective = Objective(robot, losses, s.gradients, s.fd_step, s.precondition)
    first = Objective(robot, first_losses, s.gradients, s.fd_step, s.precondition)
    opt = make_optimizer(robot, settings)
    pairs = collision_pairs(robot) if settings.self_collision else None
    collision = CollisionConstraint(robot, pairs, settings) if pairs is not None and len(pairs) else None
    band, first_band = (BandConstraint(robot, o.losses, settings) for o in (objective, first))
    status = np.zeros(problem.n_frames, dtype=int)
    config = mink.Configuration(robot.model) if limits else None

    def solve_frame_k(k: int, frame: Sample, q: np.ndarray, box: JointBox) -> FrameResult:
        if config is not None:
            box = box_with_limits(box, limits, config, box.clip(q), frame.dt)
        if path is not None:
            path.at(k)
        obj, max_eval, hands = (
            (first, settings.first_eval, first_band) if k == 0 else (objective, settings.max_eval, band)
        )
        if collision is not None:
            collision.brake(box)
        q, status[k] = solve_frame(opt, obj, frame, box.clip(q), max_eval, box, collision, hands)
        converged = status[k] > 0 and status[k] != nlopt.MAXEVAL_REACHED
        # roundoff-limited (NLopt: "still typically returns a useful result"): unconverged, not failed
        failed = status[k] < 0 and status[k] != nlopt.ROUNDOFF_LIMITED
        return FrameResult(box.clip(q), obj.evaluations, converged, failed)

    result = track(problem, solve_frame_k, progress, MotionLimits.of(robot, settings))
    return replace(result, info=MappingProxyType({"status": status}))


def slsqp_solver(
    settings: SLSQPSettings = SLSQPSettings(),
    progress: Callable[[int], None] | None = None,
    limits: Sequence[mink.Limit] = (),
) -> ConfiguredSolver:
    """The SLSQP solver (the paper's OPT) with the given settings (and a caller's
    ``mink.Limit``\\ s), for :func:`hlik.retarget.retarget`."""
    return ConfiguredSolver("slsqp", partial(solve, limits=limits) if limits else solve, settings, progress)
