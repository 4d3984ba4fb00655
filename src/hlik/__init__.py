"""hlik: human-like bimanual motion retargeting and human-likeness metrics.

Data flow: motion -> human kinematics -> placement and hand targets -> solver -> trajectory ->
metrics -> recording.
"""

from __future__ import annotations

import sys
from types import ModuleType
from typing import TYPE_CHECKING, Any

from hlik.util.lazy import lazy_getattr
from hlik.util.version import __version__ as __version__

if TYPE_CHECKING:
    from hlik.human.kinematics import HumanKinematics
    from hlik.human.load import load_motion
    from hlik.human.motion import HumanMotion, ObjectMotion
    from hlik.pipeline import RunResult, RunSpec, run
    from hlik.recording import write_recording
    from hlik.retarget import retarget
    from hlik.robot.files import available_robots
    from hlik.robot.model import Robot, load_robot
    from hlik.trajectory import Trajectory, load_trajectory
    from hlik.util.errors import HlikError, MotionFormatError, RobotError, TrajectoryFormatError
    from hlik.util.paths import demo_motion_path

# Imported on first use (PEP 562): `import hlik.cli` must not pay for rerun, mink, scipy, MuJoCo.
_WHERE = {
    "HlikError": "hlik.util.errors",
    "MotionFormatError": "hlik.util.errors",
    "RobotError": "hlik.util.errors",
    "TrajectoryFormatError": "hlik.util.errors",
    "HumanKinematics": "hlik.human.kinematics",
    "load_motion": "hlik.human.load",
    "HumanMotion": "hlik.human.motion",
    "ObjectMotion": "hlik.human.motion",
    "RunResult": "hlik.pipeline",
    "RunSpec": "hlik.pipeline",
    "run": "hlik.pipeline",
    "write_recording": "hlik.recording",
    "retarget": "hlik.retarget",
    "Robot": "hlik.robot.model",
    "available_robots": "hlik.robot.files",
    "load_robot": "hlik.robot.model",
    "Trajectory": "hlik.trajectory",
    "load_trajectory": "hlik.trajectory",
    "demo_motion_path": "hlik.util.paths",
}

__all__ = [
    "HlikError",
    "HumanKinematics",
    "HumanMotion",
    "MotionFormatError",
    "ObjectMotion",
    "Robot",
    "RobotError",
    "RunResult",
    "RunSpec",
    "Trajectory",
    "TrajectoryFormatError",
    "available_robots",
    "demo_motion_path",
    "load_motion",
    "load_robot",
    "load_trajectory",
    "retarget",
    "run",
    "write_recording",
]


class _Package(ModuleType):
    # Importing the submodule hlik.retarget sets the package attribute `retarget` to that module
    # (after its code ran), which would hide the function of the same name: keep the function.
    def __setattr__(self, name: str, value: Any) -> None:
        if name in _WHERE and isinstance(value, ModuleType) and value.__name__ == _WHERE[name]:
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


__getattr__ = lazy_getattr(__name__, _WHERE, globals())


def __dir__() -> list[str]:
    return sorted([*globals(), *_WHERE])
