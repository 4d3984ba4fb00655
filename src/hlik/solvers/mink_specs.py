"""mink's own tasks and limits named in a stack file (``{type = "PostureTask", cost = 0.05}``):
checked against mink's classes (:func:`check_specs`) and built for a robot (:func:`build`)."""

from __future__ import annotations

import inspect
from collections.abc import Mapping

import mink
import numpy as np

from hlik.robot.model import SIDES, Robot
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
        if issubclass(cls, mink.PostureTask) and not issubclass(cls, mink.DampingTask):
            params.add("target")  # the configuration it pulls toward (default: the robot's home)
        extra = set(spec) - params - {"type"}
        if extra:
            raise SettingsError(
                f"{kind}: {name} takes no {sorted(extra)[0]!r}; it takes: {', '.join(sorted(params))}"
            )
    return tuple(dict(s) for s in specs)


def build(robot: Robot, spec: Mapping[str, object]) -> mink.Task | mink.Limit:
    """The mink task or limit of ``spec`` (:func:`check_specs`) for ``robot``.

    Raises:
        SettingsError: a value mink refuses (a negative cost, a gain past 1, a target of the wrong
            shape, a missing parameter), or a task that needs a target a stack file cannot give.
    """
    params = {k: v for k, v in spec.items() if k not in ("type", "target")}
    cls = getattr(mink, str(spec["type"]))
    if "model" in inspect.signature(cls).parameters:
        params["model"] = robot.model
    if cls is mink.VelocityLimit and "velocities" not in params:  # mink's default limits nothing
        finite = np.isfinite(robot.velocity_limit)
        params["velocities"] = dict(zip(np.asarray(robot.joint_names)[finite], robot.velocity_limit[finite]))
    try:
        obj = cls(**params)
        if isinstance(obj, mink.PostureTask) and not isinstance(obj, mink.DampingTask):  # damping: no target
            target = spec.get("target")
            obj.set_target(robot.home if target is None else np.asarray(target, dtype=float))
    except (TypeError, ValueError, KeyError, IndexError, mink.exceptions.MinkError) as e:
        # mink names an unknown joint in a KeyError (VelocityLimit's velocities): its text, unquoted
        raise SettingsError(f"{spec['type']}: {e.args[0] if isinstance(e, KeyError) else e}") from None
    if isinstance(obj, mink.Task) and not on_a_tcp(obj):  # the solver aims those every frame
        try:
            obj.compute_error(mink.Configuration(robot.model, robot.home))
        except mink.exceptions.TargetNotSet:
            raise SettingsError(
                f"{spec['type']} needs a target, which a stack file cannot give: only PostureTask "
                "takes target = [...], and a FrameTask on left_tcp or right_tcp follows the hands"
            ) from None
    return obj


def build_all(
    robot: Robot, settings: object, where: str | None = None
) -> tuple[list[mink.Task], list[mink.Limit]]:
    """The ``tasks`` and ``limits`` of ``settings`` (a :class:`~hlik.solvers.settings.MinkSettings`)
    built for ``robot``; ``where`` (the stack file), if given, begins each error.

    Raises:
        SettingsError: as :func:`build`, naming ``where``, ``[mink]`` and the list.
    """
    prefix = f"{where}: " if where is not None else ""
    built: dict[str, list] = {}
    for kind in KINDS:
        built[kind] = []
        for spec in getattr(settings, kind, ()):
            try:
                built[kind].append(build(robot, spec))
            except SettingsError as e:
                raise SettingsError(f"{prefix}[mink] {kind}: {e}") from None
    return built["tasks"], built["limits"]


def on_a_tcp(task: mink.Task) -> bool:
    """A mink ``FrameTask`` on a TCP site (``left_tcp``, ``right_tcp``): one the solvers aim at the
    hands' targets every frame."""
    return isinstance(task, mink.FrameTask) and task.frame_name in {f"{s}_tcp" for s in SIDES}
