"""JM: the naive joint mapping baseline (paper Sec. III-A), blind to the hand targets.

The mapping itself lives with the robot (:func:`hlik.robot.model.joint_mapping`): JM is the mapped
human pose clipped into the joint limits, as a robot controller would.
"""

from __future__ import annotations

from hlik.robot.model import joint_mapping

__all__ = ["joint_mapping"]
