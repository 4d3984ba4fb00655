"""The QP backend the solvers share: one convex QP with box bounds, inequality rows and optional
soft rows, solved by daqp directly or by any solver qpsolvers has installed.
"""

from __future__ import annotations

import daqp
import numpy as np
import qpsolvers


def qp_backends() -> tuple[str, ...]:
    """QP solvers :func:`solve_qp` can use: daqp (called directly) and qpsolvers' installed ones."""
    return tuple(dict.fromkeys(("daqp", *qpsolvers.available_solvers)))


def solve_qp(
    hessian,
    gradient,
    lb,
    ub,
    solver: str,
    a_ineq: np.ndarray,
    b_ineq: np.ndarray,
    soft: np.ndarray | None = None,
) -> np.ndarray | None:
    """min 1/2 x'Hx + g'x subject to lb <= x <= ub and a_ineq x <= b_ineq; None if the solver
    fails (infeasible). ``soft`` (k,): the rows with a positive entry may be missed by a slack
    s_i >= 0 that costs ``soft_i max(diag H) s_i^2`` (:class:`~hlik.solvers.frames.StepConstraints`);
    with a soft row, the problem is feasible wherever the bounds are."""
    if soft is not None and np.any(soft > 0):
        n, picked = len(lb), np.flatnonzero(soft > 0)
        k = len(picked)
        scale = float(np.max(np.diag(hessian), initial=1.0))
        hessian = np.block([[hessian, np.zeros((n, k))], [np.zeros((k, n)), np.diag(scale * soft[picked])]])
        gradient = np.concatenate([gradient, np.zeros(k)])
        slack = np.zeros((len(b_ineq), k))
        slack[picked, np.arange(k)] = -1.0
        a_ineq = np.hstack([a_ineq, slack])
        lb, ub = np.concatenate([lb, np.zeros(k)]), np.concatenate([ub, np.full(k, np.inf)])
        x = solve_qp(hessian, gradient, lb, ub, solver, a_ineq, b_ineq)
        return None if x is None else x[:n]
    if solver != "daqp":
        g = a_ineq if len(b_ineq) else None
        h = b_ineq if len(b_ineq) else None
        return qpsolvers_solve(hessian, gradient, G=g, h=h, lb=lb, ub=ub, solver=solver)
    # daqp directly: qpsolvers' wrapping costs as much as the solve itself at this size
    sense = np.zeros(len(lb) + len(b_ineq), dtype=np.int32)
    upper = np.concatenate([ub, b_ineq])
    lower = np.concatenate([lb, np.full(len(b_ineq), -1e30)])
    x, _, exitflag, _ = daqp.solve(hessian, gradient, a_ineq, upper, lower, sense)
    return np.asarray(x) if exitflag > 0 else None


def qpsolvers_solve(*args, **kwargs) -> np.ndarray | None:
    """``qpsolvers.solve_qp``, None where the solver fails to build the problem. Clarabel's wrapper
    turns every exception into a ``ProblemError``, Ctrl-C and SIGTERM's exit among them (a
    traceback instead of "interrupted"): those are raised again as they came."""
    try:
        return qpsolvers.solve_qp(*args, **kwargs)
    except qpsolvers.ProblemError as e:
        if isinstance(e.__cause__, KeyboardInterrupt | SystemExit):
            raise e.__cause__ from None
        return None
