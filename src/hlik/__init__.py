"""hlik: human-like bimanual motion retargeting and human-likeness metrics.

Data flow: motion -> human kinematics -> placement and hand targets -> solver -> trajectory ->
metrics -> recording.
"""

from hlik.errors import HlikError, MotionFormatError, RobotError, TrajectoryFormatError
from hlik.human.kinematics import HumanKinematics
from hlik.human.load import load_motion
from hlik.human.motion import HumanMotion, ObjectMotion
from hlik.recording import write_recording
from hlik.retarget import retarget
from hlik.robot.model import Robot, available_robots, load_robot
from hlik.trajectory import Trajectory, load_trajectory

__all__ = [
    "HlikError",
    "HumanKinematics",
    "HumanMotion",
    "MotionFormatError",
    "ObjectMotion",
    "Robot",
    "RobotError",
    "Trajectory",
    "TrajectoryFormatError",
    "available_robots",
    "load_motion",
    "load_robot",
    "load_trajectory",
    "retarget",
    "write_recording",
]
__version__ = "0.1.0"
