"""Stage 2, the robot: its model, kinematics and the MMM -> robot joint mapping.

- :mod:`~hlik.robot.model`: :class:`Robot` from ``robots/<name>.toml`` + MJCF; limits, speed limits,
  sites, self-contacts; the mapped human pose (:func:`joint_mapping`).
- :mod:`~hlik.robot.state`: forward kinematics and site Jacobians at many configurations.
- :mod:`~hlik.robot.mapping`: the joint mapping of paper Sec. III-A (Table I).
- :mod:`~hlik.robot.calibrate`: deriving that mapping from a model (``hlik calibrate``).
- :mod:`~hlik.robot.collision`: self-collision pairs and their distances with Jacobians.
- :mod:`~hlik.robot.reachability`: oriented reachability maps of the hands (placement).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hlik.util.lazy import lazy_getattr

if TYPE_CHECKING:
    from hlik.robot.files import available_robots
    from hlik.robot.model import SIDES, SITES, Robot, joint_mapping, load_robot, tcp_poses
    from hlik.robot.state import RobotState, robot_state

# Imported on first use (PEP 562), so that importing one module of the package stays cheap.
_WHERE = {
    "SIDES": "hlik.robot.model",
    "SITES": "hlik.robot.model",
    "Robot": "hlik.robot.model",
    "available_robots": "hlik.robot.files",
    "joint_mapping": "hlik.robot.model",
    "load_robot": "hlik.robot.model",
    "tcp_poses": "hlik.robot.model",
    "RobotState": "hlik.robot.state",
    "robot_state": "hlik.robot.state",
}

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


__getattr__ = lazy_getattr(__name__, _WHERE, globals())
