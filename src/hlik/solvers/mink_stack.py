"""``--solver mink``: the QP's stack solved by mink, with a stack file's own mink tasks and limits.

A stack file's ``[mink]`` table takes every ``[qp]`` setting (it starts from the ``[qp]`` table)
and two lists naming mink's classes with their parameters::

    [mink]
    tasks = [{ type = "PostureTask", cost = 0.05 }]        # pulled toward home (or target = [...])
    limits = [{ type = "ConfigurationLimit", gain = 0.5 }]

A class whose constructor takes the model gets the robot's; a ``PostureTask`` aims at the robot's
home unless ``target`` gives the configuration. hlik's own terms and limits
come from :func:`hlik.solvers.qp.build_solver`: without extra tasks and limits, the QP itself.
With ``hands_first = true`` the tasks act after the hands, in their null space, as the criteria do.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial

import mink

from hlik.problem.problem import Problem
from hlik.solvers.base import ConfiguredSolver, SolverResult
from hlik.solvers.mink_specs import build_all
from hlik.solvers.qp import solve as solve_qp
from hlik.solvers.settings import MinkSettings


def solve(
    problem: Problem,
    settings: MinkSettings = MinkSettings(),
    progress: Callable[[int], None] | None = None,
    limits: Sequence[mink.Limit] = (),
) -> SolverResult:
    """Retarget frame by frame with the QP's stack, the settings' mink objects and a caller's
    ``limits`` on mink."""
    tasks, own = build_all(problem.robot, settings)
    return solve_qp(problem, settings, progress, tasks, [*own, *limits])


def mink_solver(
    settings: MinkSettings = MinkSettings(),
    progress: Callable[[int], None] | None = None,
    limits: Sequence[mink.Limit] = (),
) -> ConfiguredSolver:
    """The QP's stack on mink with ``settings``' own tasks and limits (and a caller's), for
    :func:`hlik.retarget.retarget`."""
    return ConfiguredSolver("mink", partial(solve, limits=limits) if limits else solve, settings, progress)
