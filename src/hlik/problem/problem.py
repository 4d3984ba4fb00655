"""The retargeting problem: one motion on one robot, everything a solver needs, built once."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from hlik.criteria import registry
from hlik.criteria.learned import Learned, learn
from hlik.human.kinematics import HumanKinematics, forward_kinematics
from hlik.human.motion import HumanMotion, frame_period
from hlik.problem.placement import Placement, placement_from_spec
from hlik.problem.reference import HumanReference, human_reference
from hlik.problem.targets import HandTargets, hand_targets, within_reach
from hlik.robot.model import Robot
from hlik.robot.reach import arm_reach


@dataclass(frozen=True, eq=False)
class Problem:
    """Retargeting ``motion`` to ``robot``; arrays over the T frames of the motion.

    Attributes:
        robot: The robot.
        motion: The human motion (MMM joint angles, root, objects).
        human: Its forward kinematics on the MMM model, world frame.
        placement: Pose of the robot base in the human's world.
        targets: The human hand poses as TCP targets, robot base frame.
        reference: The human reference of the reference criteria (mapped pose, Ψ, manipulability).
        dt: Median frame period, s.
        learned: The pieces the criteria learn from human motion (synergies, Ψ regressor,
            λ_R); None where no criterion of the run needs them.
    """

    robot: Robot
    motion: HumanMotion
    human: HumanKinematics
    placement: Placement
    targets: HandTargets
    reference: HumanReference
    dt: float
    learned: Learned | None = None

    @property
    def n_frames(self) -> int:
        return self.motion.n_frames

    @cached_property
    def tracked(self) -> HandTargets:
        """What the solvers track: ``targets`` with each position beyond its arm's reach moved
        onto it (:func:`~hlik.problem.targets.within_reach`); ``targets`` is what is scored."""
        return within_reach(self.targets, arm_reach(self.robot))


def build_problem(
    motion: HumanMotion,
    robot: Robot,
    placement: Placement | None = None,
    learned: Learned | None = None,
    criteria: Sequence[str] = (),
    corpus: Path | None = None,
) -> Problem:
    """The problem of ``motion`` on ``robot``, placed at ``placement`` (default: the robot's own
    rule, ``Robot.placement``: reachability as the paper, or the joint mapping's fit).

    ``learned``: the learned pieces; if None, they are learned here from ``corpus``
    (:func:`~hlik.criteria.learned.learn`, cached on disk) when one of ``criteria`` needs them,
    so that a solver never reads a corpus or the cache.
    """
    if learned is None and registry.learns(criteria):
        learned = learn(robot, corpus)
    human = forward_kinematics(motion)
    placement = placement or placement_from_spec(robot.placement, robot, motion, human)
    return Problem(
        robot=robot,
        motion=motion,
        human=human,
        placement=placement,
        targets=hand_targets(human, placement),
        reference=human_reference(robot, motion, placement, human),
        dt=frame_period(motion.times),
        learned=learned,
    )
