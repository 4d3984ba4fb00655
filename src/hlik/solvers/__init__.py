"""Retargeting solvers. Each maps (robot, human motion, hand targets) to joint angles (T, n).

:func:`hlik.retarget.retarget` wraps any of them into a :class:`hlik.trajectory.Trajectory`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

import numpy as np

from hlik.motion import HumanMotion
from hlik.robot import Robot
from hlik.solvers.jm import joint_mapping
from hlik.targets import HandTargets

Solver = Callable[[Robot, HumanMotion, HandTargets], np.ndarray]

SOLVERS: Mapping[str, Solver] = MappingProxyType({"jm": joint_mapping})

__all__ = ["SOLVERS", "Solver", "joint_mapping"]
