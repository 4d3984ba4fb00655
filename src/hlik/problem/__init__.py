"""Stage 3, the problem: everything a solver needs about one motion on one robot.

- :mod:`~hlik.problem.placement`: where the robot stands in the human's world.
- :mod:`~hlik.problem.targets`: the human hand poses as robot TCP targets.
- :mod:`~hlik.problem.reference`: the human reference the reference criteria compare to.
- :mod:`~hlik.problem.problem`: :class:`Problem`, all of the above for one motion on one robot.
"""

from hlik.problem.placement import Placement, placement_from_spec, reach_placement, shoulder_placement
from hlik.problem.problem import Problem, build_problem
from hlik.problem.reference import HumanReference, human_reference
from hlik.problem.targets import HandTargets, hand_targets

__all__ = [
    "Problem",
    "build_problem",
    "HandTargets",
    "HumanReference",
    "Placement",
    "hand_targets",
    "human_reference",
    "placement_from_spec",
    "reach_placement",
    "shoulder_placement",
]
