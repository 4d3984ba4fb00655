"""hlik: human-like bimanual motion retargeting and human-likeness metrics."""

from hlik.errors import HlikError, MotionFormatError, RobotError
from hlik.human import HumanKinematics
from hlik.motion import HumanMotion, ObjectMotion, load_motion
from hlik.robot import Robot, available_robots, load_robot

__all__ = [
    "HlikError",
    "HumanKinematics",
    "HumanMotion",
    "MotionFormatError",
    "ObjectMotion",
    "Robot",
    "RobotError",
    "available_robots",
    "load_motion",
    "load_robot",
]
__version__ = "0.1.0"
