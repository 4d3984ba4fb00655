"""hlik: human-like bimanual motion retargeting and human-likeness metrics."""

from hlik.errors import HlikError, MotionFormatError, RobotError
from hlik.human import HumanKinematics
from hlik.motion import HumanMotion, ObjectMotion, load_motion

__all__ = [
    "HlikError",
    "HumanKinematics",
    "HumanMotion",
    "MotionFormatError",
    "ObjectMotion",
    "RobotError",
    "load_motion",
]
__version__ = "0.1.0"
