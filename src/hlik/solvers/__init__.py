"""Stage 4, the solvers: a :class:`~hlik.problem.problem.Problem` in, a
:class:`~hlik.solvers.base.SolverResult` (joint angles and per-frame diagnostics) out.

- ``jm``: the paper's joint mapping (Table I), clipped to the limits (:mod:`~hlik.solvers.jm`).
- ``jv``: the paper's Jacobian velocity controller, criteria in the null space (:mod:`~hlik.solvers.jv`).
- ``qp``: a stack of convex QPs per frame, criteria as least-squares terms, solved by
  :class:`~hlik.solvers.mink_ik.MinkSolver` (:mod:`~hlik.solvers.qp`).
- ``slsqp``: the paper's OPT, RelaxedIK groove losses with NLopt's SLSQP (:mod:`~hlik.solvers.slsqp`).
- ``mink``: the QP's stack solved by mink, with a stack file's own mink tasks and limits
  (:mod:`~hlik.solvers.mink_stack`).

Beside them: :mod:`~hlik.solvers.settings` (what each solver is told, checked without loading
a solver), :mod:`~hlik.solvers.mink_tasks` (criteria as mink tasks and limits),
:mod:`~hlik.solvers.mink_specs` (a stack file's own mink tasks and limits),
:mod:`~hlik.solvers.mink_ik` (a solver from any mink stack), :mod:`~hlik.solvers.stack_file`
(``tasks/*.toml``), :mod:`~hlik.solvers.frames` (the frame loop they share),
:mod:`~hlik.solvers.gradients` (a term's cost and gradient of one sample, for JV and SLSQP).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hlik.solvers.catalog import SOLVER_NAMES, SPECS, SolverSpec, check_solver, get_solver, solver_spec
from hlik.util.lazy import lazy_getattr

if TYPE_CHECKING:
    from hlik.solvers.base import Diagnostics, Solver, SolverResult
    from hlik.solvers.settings import SolverSettings

# Imported on first use (PEP 562): the catalogue answers a solver name without loading a solver.
_WHERE = {
    "Diagnostics": "hlik.solvers.base",
    "Solver": "hlik.solvers.base",
    "SolverResult": "hlik.solvers.base",
    "SolverSettings": "hlik.solvers.settings",
}
__getattr__ = lazy_getattr(__name__, _WHERE, globals())

__all__ = [
    "SOLVER_NAMES",
    "SPECS",
    "Diagnostics",
    "Solver",
    "SolverResult",
    "SolverSettings",
    "SolverSpec",
    "check_solver",
    "get_solver",
    "solver_spec",
]
