"""Retargeting solvers: ``(robot, motion, targets, placement) -> joint angles (T, n)``.

:func:`hlik.retarget.retarget` wraps any of them into a :class:`hlik.trajectory.Trajectory`.

- ``jm``: the paper's joint mapping (Table I), clipped to the limits.
- ``jv``: the paper's Jacobian velocity controller, criteria in the null space (baseline).
- ``qp``: a stack of convex QPs per frame, criteria as least-squares tasks (mink + daqp).
- ``slsqp``: the paper's OPT, RelaxedIK groove losses with NLopt's SLSQP and analytic gradients.

Solvers are imported on demand: the optimising ones need the learned criteria.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import import_module

import numpy as np

from hlik.criteria.learned import Learned
from hlik.human.motion import HumanMotion
from hlik.problem.placement import Placement
from hlik.problem.targets import HandTargets
from hlik.robot.model import Robot

Solver = Callable[[Robot, HumanMotion, HandTargets, Placement], np.ndarray]

SOLVER_NAMES = ("jm", "jv", "qp", "slsqp")


def get_solver(
    name: str,
    settings: object | None = None,
    learned: Learned | None = None,
    progress: Callable[[int], None] | None = None,
) -> Solver:
    """The solver called ``name``, with ``settings`` (its settings class; default: the defaults).

    ``learned`` supplies the learned criteria (learned on demand otherwise); ``progress(k)`` is
    called after each frame ``k``.
    """
    if name == "jm":
        from hlik.solvers.jm import joint_mapping

        return joint_mapping
    if name not in SOLVER_NAMES:
        raise KeyError(name)
    factory = getattr(import_module(f"hlik.solvers.{name}"), f"{name}_solver")
    return (
        factory(settings, learned, progress)
        if settings is not None
        else factory(learned=learned, progress=progress)
    )
