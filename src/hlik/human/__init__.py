"""Stage 1, the human: recorded motion, its files and its kinematics on the MMM model.

- :mod:`~hlik.human.motion`: :class:`HumanMotion` (joint angles, root, markers, objects;
  resampling, mirroring).
- :mod:`~hlik.human.mmm_format`: reading and writing MMM 2.0 and legacy files.
- :mod:`~hlik.human.load`: :func:`load_motion`, any supported file to a ``HumanMotion``.
- :mod:`~hlik.human.kinematics`: the MMM model scaled to the subject, forward kinematics, body frame.
- :mod:`~hlik.human.demo`: the bundled demonstration motion.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hlik.util.lazy import lazy_getattr

if TYPE_CHECKING:
    from hlik.human.kinematics import HumanKinematics, forward_kinematics, human_model
    from hlik.human.load import load_motion
    from hlik.human.motion import ARM_JOINTS, HumanMotion, ObjectMotion

# Imported on first use (PEP 562), so that importing one module of the package stays cheap.
_WHERE = {
    "HumanKinematics": "hlik.human.kinematics",
    "forward_kinematics": "hlik.human.kinematics",
    "human_model": "hlik.human.kinematics",
    "load_motion": "hlik.human.load",
    "ARM_JOINTS": "hlik.human.motion",
    "HumanMotion": "hlik.human.motion",
    "ObjectMotion": "hlik.human.motion",
}

__all__ = [
    "ARM_JOINTS",
    "HumanKinematics",
    "HumanMotion",
    "ObjectMotion",
    "forward_kinematics",
    "human_model",
    "load_motion",
]


__getattr__ = lazy_getattr(__name__, _WHERE, globals())
