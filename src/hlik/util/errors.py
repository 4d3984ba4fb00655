"""Typed errors. Each message names the file (or robot) and the problem in one line."""

from __future__ import annotations

from pathlib import Path


class HlikError(Exception):
    """Base class of every error hlik raises on bad input; the CLI prints it in one line."""


class MotionFormatError(HlikError, ValueError):
    """A motion file is unreadable, malformed or inconsistent."""

    def __init__(self, path: str | Path | None, problem: str):
        self.path = None if path is None else Path(path)
        self.problem = problem
        where = "<motion>" if path is None else str(path)
        super().__init__(f"{where}: {problem}")


class RobotError(HlikError, ValueError):
    """An unknown robot name, or a robot description that is inconsistent."""


class TrajectoryFormatError(HlikError, ValueError):
    """A saved trajectory file is unreadable or inconsistent."""


class SettingsError(HlikError, ValueError):
    """A setting, option or argument outside what it may be (a scenario, a rate, a criterion name)."""


class UnknownNameError(HlikError, KeyError):
    """A name (criterion, solver, joint) that is not known; the message lists what is."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""
