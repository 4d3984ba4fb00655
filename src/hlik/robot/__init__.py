"""Stage 2, the robot: its model, kinematics and the MMM -> robot joint mapping.

- :mod:`~hlik.robot.model`: :class:`Robot` from ``robots/<name>.toml`` + MJCF; limits, speed limits,
  sites, self-contacts; the mapped human pose (:func:`joint_mapping`).
- :mod:`~hlik.robot.state`: forward kinematics and site Jacobians at many configurations.
- :mod:`~hlik.robot.mapping`: the joint mapping of paper Sec. III-A (Table I).
- :mod:`~hlik.robot.calibrate`: deriving that mapping from a model (``hlik calibrate``).
- :mod:`~hlik.robot.collision`: self-collision pairs and their distances with Jacobians.
- :mod:`~hlik.robot.reachability`: oriented reachability maps of the hands (placement).
"""

from hlik.robot.model import SIDES, SITES, Robot, available_robots, joint_mapping, load_robot, tcp_poses
from hlik.robot.state import RobotState, robot_state

__all__ = [
    "SIDES",
    "SITES",
    "Robot",
    "RobotState",
    "available_robots",
    "joint_mapping",
    "load_robot",
    "robot_state",
    "tcp_poses",
]
