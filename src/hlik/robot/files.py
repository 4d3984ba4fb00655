"""Robot descriptions by name: the bundled ``robots/<name>.toml`` files, found without loading a
model (the CLI checks a robot name, and names a run's files, before MuJoCo is imported)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from hlik.util.errors import HlikError, RobotError
from hlik.util.paths import robots_dir
from hlik.util.tomlfile import read_toml

# A robot's name names its files (caches, recordings): no separators, no "..".
NAME = re.compile(r"[A-Za-z0-9_-]+")
# Placement rules a robot description may name as its default (hlik.problem.placement).
PLACEMENT_RULES = ("reach", "mapped", "shoulders")


@dataclass(frozen=True)
class RobotDefaults:
    """What a description says about a run without its model: the name its files carry, and the
    placement rule and subject scale used where a run names none (:class:`~hlik.robot.model.Robot`
    has the same fields)."""

    name: str
    placement: str = "reach"
    subject_scale: float | str = 1.0


def robot_defaults(name: str) -> RobotDefaults:
    """The :class:`RobotDefaults` of a bundled robot's name or a description's path, read from its
    TOML alone (no model is loaded).

    Raises:
        hlik.util.errors.RobotError: no such robot, an unreadable file or a bad value (naming the
            file and the key).
    """
    path = robot_toml(name)
    try:
        desc = read_toml(path, "robot")
    except HlikError as e:
        raise RobotError(str(e)) from None
    return description_defaults(path, desc)


def description_defaults(path: Path, desc: dict) -> RobotDefaults:
    """The :class:`RobotDefaults` of the description ``desc`` read from ``path``, checked."""
    name = desc.get("name", path.stem)
    if not isinstance(name, str) or not NAME.fullmatch(name):
        raise RobotError(f"{path}: name {name!r} must be letters, digits, '_' or '-' (it names files)")
    rule = str(desc.get("placement", "reach"))
    if rule not in PLACEMENT_RULES:
        raise RobotError(f"{path}: placement {rule!r} is not one of {', '.join(PLACEMENT_RULES)}")
    scale = desc.get("subject_scale", 1.0)
    if scale != "auto":
        number = isinstance(scale, int | float) and not isinstance(scale, bool)
        if not (number and math.isfinite(scale) and scale > 0):
            raise RobotError(f'{path}: subject_scale must be "auto" or a positive number, got {scale!r}')
        scale = float(scale)
    return RobotDefaults(name, rule, scale)


def available_robots() -> tuple[str, ...]:
    """Names of the bundled robots."""
    return tuple(sorted(p.stem for p in robots_dir().glob("*.toml")))


def robot_toml(name: str) -> Path:
    """The description file of a bundled robot's name, or of a path ending in ``.toml``.

    Raises:
        hlik.util.errors.RobotError: no such robot or file.
    """
    by_path = name.endswith(".toml")
    path = Path(name) if by_path else robots_dir() / f"{name}.toml"
    if not path.is_file() or not (by_path or NAME.fullmatch(name)):
        if by_path and path.exists():
            raise RobotError(f"{path}: is a folder, expected a robot .toml file")
        if by_path:
            raise RobotError(f"{path}: no such robot description")
        known = ", ".join(available_robots())
        raise RobotError(f"unknown robot {name!r}; choose one of: {known}")
    return path
