"""Stage 4, the solvers: a :class:`~hlik.problem.problem.Problem` in, a
:class:`~hlik.solvers.base.SolverResult` (joint angles and per-frame diagnostics) out.

- ``jm``: the paper's joint mapping (Table I), clipped to the limits (:mod:`~hlik.solvers.jm`).
- ``jv``: the paper's Jacobian velocity controller, criteria in the null space (:mod:`~hlik.solvers.jv`).
- ``qp``: a stack of convex QPs per frame, criteria as least-squares terms (:mod:`~hlik.solvers.qp`).
- ``slsqp``: the paper's OPT, RelaxedIK groove losses with NLopt's SLSQP (:mod:`~hlik.solvers.slsqp`).

Beside them: :mod:`~hlik.solvers.mink_tasks` (criteria as mink tasks and limits),
:mod:`~hlik.solvers.mink_ik` (a solver from any mink stack), :mod:`~hlik.solvers.stack_file`
(``tasks/*.toml``), :mod:`~hlik.solvers.frames` (the frame loop they share).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

from hlik.errors import UnknownNameError
from hlik.solvers import jm, jv, qp, slsqp
from hlik.solvers.base import Diagnostics, Solver, SolverResult

# name -> factory(settings, learned, progress); a new solver adds one line here.
SOLVERS: Mapping[str, Callable[..., Solver]] = MappingProxyType(
    {"jm": jm.jm_solver, "jv": jv.jv_solver, "qp": qp.qp_solver, "slsqp": slsqp.slsqp_solver}
)
SOLVER_NAMES = tuple(SOLVERS)


def get_solver(
    name: str,
    settings: object | None = None,
    learned: object | None = None,
    progress: Callable[[int], None] | None = None,
) -> Solver:
    """The solver called ``name`` with ``settings`` (its settings class; default: the defaults).

    ``learned`` supplies the learned criteria (learned on demand otherwise); ``progress(k)`` is
    called after each frame ``k``.

    Raises:
        UnknownNameError: unknown name.
    """
    if name not in SOLVERS:
        raise UnknownNameError(f"unknown solver {name!r}; choose one of: {', '.join(SOLVERS)}")
    factory = SOLVERS[name]
    return (
        factory(settings, learned, progress)
        if settings is not None
        else factory(learned=learned, progress=progress)
    )


__all__ = ["SOLVERS", "SOLVER_NAMES", "Diagnostics", "Solver", "SolverResult", "get_solver"]
