"""mink's own tasks and limits named in a stack file (``{type = "PostureTask", cost = 0.05}``):
checked against mink's classes (:func:`check_specs`) and built for a robot (:func:`build`)."""

from __future__ import annotations

import inspect
from collections.abc import Mapping

import mink
import numpy as np

from hlik.robot.model import Robot
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
