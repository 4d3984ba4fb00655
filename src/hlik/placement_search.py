"""``--placement optimize``: the placement whose retargeted motion scores best.

Beyond the paper. Reachability (``reach``) places the robot where every hand pose is reachable;
the joint mapping (``mapped``) where the human's own joint angles would put the hands on target.
The first favours tracking, the second human likeness. This search retargets a short subsample of
the motion from candidates on the line between the two (and the shoulder placement) with a fast
solver and keeps the candidate with the highest unified metric m_hl,f. Every candidate stands the
robot on its floor (:func:`~hlik.robot.floor.floor_height`): the search is over x, y and yaw.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hlik.criteria.learned import Learned
from hlik.human.kinematics import forward_kinematics
from hlik.human.motion import HumanMotion
from hlik.metrics import evaluate
from hlik.problem.placement import (
    Placement,
    mapped_placement,
    reach_placement,
    shoulder_placement,
)
from hlik.retarget import retarget
from hlik.robot.model import Robot
from hlik.solvers.base import Solver
from hlik.util.spatial import yaw_rotation


@dataclass(frozen=True)
class Candidate:
    """A placement tried by :func:`optimize_placement` and the m_hl,f it scored."""

    name: str
    placement: Placement
    m_hl_f: float


def optimize_placement(
    motion: HumanMotion,
    robot: Robot,
    solver: Solver,
    learned: Learned,
    scenario: str = "pose",
    frames: int = 40,
    steps: int = 3,
) -> tuple[Placement, list[Candidate]]:
    """The best of ``reach``, ``mapped``, ``steps - 1`` placements between them (yaw and position
    interpolated) and ``shoulders``, scored by m_hl,f of ``solver`` on ``frames`` frames of the
    motion resampled evenly over its whole duration.

    Returns:
        The winning placement (method ``optimize``) and every candidate with its score.
    """
    human = forward_kinematics(motion)
    reach, mapped = reach_placement(robot, human), mapped_placement(robot, motion, human)
    named = [("reach", reach)]
    named += [(f"reach+{k}/{steps}", _between(reach, mapped, k / steps)) for k in range(1, steps)]
    named += [("mapped", mapped), ("shoulders", shoulder_placement(robot, human))]
    short = motion.resample(max(frames - 1, 1) / motion.duration) if motion.n_frames > frames else motion
    candidates = []
    for name, placement in named:
        traj = retarget(short, robot, solver, placement, learned)
        candidates.append(Candidate(name, placement, evaluate(traj, robot, learned, scenario).m_hl_f))
    best = max(candidates, key=lambda c: c.m_hl_f)
    return Placement(best.placement.rotation, best.placement.translation, "optimize"), candidates


def _between(a: Placement, b: Placement, t: float) -> Placement:
    """The upright placement a fraction ``t`` of the way from ``a`` to ``b`` (shortest yaw), at
    ``a``'s height (the floor's)."""
    yaw = a.yaw + t * np.angle(np.exp(1j * (b.yaw - a.yaw)))
    translation = (1 - t) * a.translation + t * b.translation
    translation[2] = a.translation[2]
    return Placement(yaw_rotation(yaw), translation, "between")
