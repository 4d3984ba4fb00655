"""Stage 1, the human: recorded motion, its files and its kinematics on the MMM model.

- :mod:`~hlik.human.motion`: :class:`HumanMotion` (joint angles, root, markers, objects;
  resampling, mirroring).
- :mod:`~hlik.human.mmm_format`: reading and writing MMM 2.0 and legacy files.
- :mod:`~hlik.human.load`: :func:`load_motion`, any supported file to a ``HumanMotion``.
- :mod:`~hlik.human.kinematics`: the MMM model scaled to the subject, forward kinematics, body frame.
- :mod:`~hlik.human.demo`: the bundled demonstration motion.
"""

from hlik.human.kinematics import HumanKinematics, forward_kinematics, human_model
from hlik.human.load import load_motion
from hlik.human.motion import ARM_JOINTS, HumanMotion, ObjectMotion

__all__ = [
    "ARM_JOINTS",
    "HumanKinematics",
    "HumanMotion",
    "ObjectMotion",
    "forward_kinematics",
    "human_model",
    "load_motion",
]
