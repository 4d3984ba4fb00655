"""``--solver mink``: the QP's stack solved by mink, with a stack file's own mink tasks and limits.

A stack file's ``[mink]`` table takes every ``[qp]`` setting (it starts from the ``[qp]`` table)
and two lists naming mink's classes with their parameters::

    [mink]
    tasks = [{ type = "PostureTask", cost = 0.05 }]        # pulled toward home (or target = [...])
    limits = [{ type = "ConfigurationLimit", gain = 0.5 }]

A class whose constructor takes the model gets the robot's; a ``PostureTask`` aims at the robot's
home unless ``target`` gives the configuration. hlik's own terms and limits
come from :func:`hlik.solvers.qp.build_solver`: without extra tasks and limits, the QP itself.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import mink
import numpy as np

from hlik.problem.problem import Problem
from hlik.robot.model import Robot
from hlik.solvers.base import ConfiguredSolver, SolverResult
from hlik.solvers.qp import QPSettings, build_solver
from hlik.util.errors import SettingsError

KINDS = {"tasks": mink.Task, "limits": mink.Limit}


def check_specs(specs: object, kind: str) -> tuple[Mapping[str, object], ...]:
    """``specs``, a list of tables each naming a mink class of ``kind`` (``tasks``, ``limits``)
    by ``type`` with its constructor's parameters, checked against the class's signature.

    Raises:
        SettingsError: not a list of tables, an unknown type, or a parameter the class lacks.
    """
    if not isinstance(specs, list | tuple) or not all(isinstance(s, Mapping) for s in specs):
        raise SettingsError(
            f'{kind} must be a list of tables, e.g. [{{ type = "PostureTask", cost = 0.05 }}]'
        )
    base = KINDS[kind]
    for spec in specs:
        name = spec.get("type")
        cls = getattr(mink, str(name), None)
        if not (isinstance(cls, type) and issubclass(cls, base)):
            known = sorted(
                n
                for n in dir(mink)
                if isinstance(getattr(mink, n), type)
                and issubclass(getattr(mink, n), base)
                and n not in ("Task", "Limit")
            )
            raise SettingsError(
                f"{kind}: unknown mink {base.__name__} {name!r}; choose from: {', '.join(known)}"
            )
        params = set(inspect.signature(cls).parameters) - {"model"}
        extra = set(spec) - params - {"type", "target"}
        if extra:
            raise SettingsError(
                f"{kind}: {name} takes no {sorted(extra)[0]!r}; it takes: {', '.join(sorted(params))}"
            )
    return tuple(dict(s) for s in specs)


def build(robot: Robot, spec: Mapping[str, object]) -> mink.Task | mink.Limit:
    """The mink task or limit of ``spec`` (:func:`check_specs`) for ``robot``."""
    params = {k: v for k, v in spec.items() if k not in ("type", "target")}
    cls = getattr(mink, str(spec["type"]))
    if "model" in inspect.signature(cls).parameters:
        params["model"] = robot.model
    try:
        obj = cls(**params)
    except (TypeError, ValueError) as e:
        raise SettingsError(f"mink {spec['type']}: {e}") from None
    if isinstance(obj, mink.PostureTask) and not isinstance(obj, mink.DampingTask):  # damping: no target
        target = spec.get("target")
        obj.set_target(robot.home if target is None else np.asarray(target, dtype=float))
    return obj


@dataclass(frozen=True)
class MinkSettings(QPSettings):
    """The QP's settings (:class:`~hlik.solvers.qp.QPSettings`) and the stack's own mink objects.

    Attributes:
        tasks: mink tasks added beside hlik's, each ``{type = "<mink class>", <parameters>}``.
        limits: mink limits added beside hlik's frame box and collision rows, alike.
    """

    tasks: tuple[Mapping[str, object], ...] = ()
    limits: tuple[Mapping[str, object], ...] = ()

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "tasks", check_specs(self.tasks, "tasks"))
        object.__setattr__(self, "limits", check_specs(self.limits, "limits"))


def solve(
    problem: Problem, settings: MinkSettings = MinkSettings(), progress: Callable[[int], None] | None = None
) -> SolverResult:
    """Retarget frame by frame with the QP's stack and the settings' mink objects on mink."""
    robot = problem.robot
    tasks = [t for t in (build(robot, s) for s in settings.tasks) if isinstance(t, mink.Task)]
    limits = [lim for lim in (build(robot, s) for s in settings.limits) if isinstance(lim, mink.Limit)]
    return build_solver(robot, settings, problem.learned, tasks, limits, progress)(problem)


def mink_solver(
    settings: MinkSettings = MinkSettings(), progress: Callable[[int], None] | None = None
) -> ConfiguredSolver:
    """The QP's stack on mink with ``settings``' own tasks and limits, for :func:`hlik.retarget.retarget`."""
    return ConfiguredSolver("mink", solve, settings, progress)
