"""Robot descriptions by name: the bundled ``robots/<name>.toml`` files, found without loading a
model (the CLI checks a robot name before MuJoCo is imported)."""

from __future__ import annotations

import re
from pathlib import Path

from hlik.util.errors import RobotError
from hlik.util.paths import robots_dir

# A robot's name names its files (caches, recordings): no separators, no "..".
NAME = re.compile(r"[A-Za-z0-9_-]+")


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
