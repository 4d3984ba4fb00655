"""Stage 4, the solvers: a :class:`~hlik.problem.problem.Problem` in, a
:class:`~hlik.solvers.base.SolverResult` (joint angles and per-frame diagnostics) out.

- ``jm``: the paper's joint mapping (Table I), clipped to the limits (:mod:`~hlik.solvers.jm`).
- ``jv``: the paper's Jacobian velocity controller, criteria in the null space (:mod:`~hlik.solvers.jv`).
- ``qp``: a stack of convex QPs per frame, criteria as least-squares terms, solved by
  :class:`~hlik.solvers.mink_ik.MinkSolver` (:mod:`~hlik.solvers.qp`).
- ``slsqp``: the paper's OPT, RelaxedIK groove losses with NLopt's SLSQP (:mod:`~hlik.solvers.slsqp`).
- ``mink``: the QP's stack solved by mink, with a stack file's own mink tasks and limits
  (:mod:`~hlik.solvers.mink_stack`).

Beside them: :mod:`~hlik.solvers.mink_tasks` (criteria as mink tasks and limits),
:mod:`~hlik.solvers.mink_ik` (a solver from any mink stack), :mod:`~hlik.solvers.stack_file`
(``tasks/*.toml``), :mod:`~hlik.solvers.frames` (the frame loop they share),
:mod:`~hlik.solvers.gradients` (a term's cost and gradient of one sample, for JV and SLSQP).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

from hlik.solvers import jm, jv, mink_stack, qp, slsqp
from hlik.solvers.base import Diagnostics, Solver, SolverResult
from hlik.solvers.settings import SolverSettings, SolverSpec
from hlik.util.errors import UnknownNameError

# The solvers by name; a new solver adds one line here.
SPECS: Mapping[str, SolverSpec] = MappingProxyType(
    {
        s.name: s
        for s in (
            SolverSpec("jm", jm.jm_solver, None, takes_criteria=False, tracks_targets=False),
            SolverSpec("jv", jv.jv_solver, jv.JVSettings),
            SolverSpec("qp", qp.qp_solver, qp.QPSettings),
            SolverSpec("slsqp", slsqp.slsqp_solver, slsqp.SLSQPSettings),
            SolverSpec("mink", mink_stack.mink_solver, mink_stack.MinkSettings),
        )
    }
)
# name -> factory(settings, progress)
SOLVERS: Mapping[str, Callable[..., Solver]] = MappingProxyType({n: s.factory for n, s in SPECS.items()})
SOLVER_NAMES = tuple(SOLVERS)


def solver_spec(name: str) -> SolverSpec:
    """The :class:`SolverSpec` of solver ``name``; a solver hlik does not know by name (a user's
    function, a mink stack) is one that tracks the targets and takes no criteria of hlik's.

    Use it for what a solver can do, not its name."""
    return SPECS.get(name) or SolverSpec(name, _unknown(name), None, takes_criteria=False)


def _unknown(name: str) -> Callable[..., Solver]:
    def factory(*args: object, **kwargs: object) -> Solver:
        raise UnknownNameError(f"unknown solver {name!r}; choose one of: {', '.join(SOLVERS)}")

    return factory


def get_solver(
    name: str, settings: object | None = None, progress: Callable[[int], None] | None = None
) -> Solver:
    """The solver called ``name`` with ``settings`` (its settings class; default: the defaults);
    ``progress(k)`` is called after each frame ``k``. The learned pieces of its criteria come with
    the problem (:func:`hlik.problem.build_problem`).

    Raises:
        UnknownNameError: unknown name.
    """
    if name not in SOLVERS:
        raise UnknownNameError(f"unknown solver {name!r}; choose one of: {', '.join(SOLVERS)}")
    factory = SOLVERS[name]
    return factory(settings, progress) if settings is not None else factory(progress=progress)


__all__ = [
    "SOLVERS",
    "SOLVER_NAMES",
    "SPECS",
    "Diagnostics",
    "Solver",
    "SolverResult",
    "SolverSettings",
    "SolverSpec",
    "get_solver",
    "solver_spec",
]
