"""The frame loop the optimising solvers share: warm start, the previous solutions, progress.

Every frame is solved from the previous frame's solution (the first from the clipped mapped human
pose, as JM gives it), with the frame's targets and human reference in a
:class:`hlik.criteria.base.Sample` of one row.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hlik.criteria.base import Sample
from hlik.human.motion import HumanMotion
from hlik.problem.placement import Placement
from hlik.problem.reference import HumanReference, human_reference
from hlik.problem.targets import HandTargets
from hlik.robot.model import Robot

FrameSolver = Callable[[int, Sample, np.ndarray], np.ndarray]


def sample_at(ref: HumanReference, targets: HandTargets, k: int, history: np.ndarray, dt: float) -> Sample:
    """The one-row :class:`Sample` of frame ``k``; ``history`` (3, n): previous solutions, newest first."""
    s = slice(k, k + 1)
    return Sample(targets.pos[s], targets.rot[s], ref.q_map[s], ref.psi[s], ref.manip[s], history[None], dt)


def track(
    robot: Robot,
    motion: HumanMotion,
    targets: HandTargets,
    placement: Placement,
    solve_frame: FrameSolver,
    progress: Callable[[int], None] | None = None,
) -> np.ndarray:
    """Solve frame by frame with ``solve_frame(k, frame, q_previous) -> q``.

    Returns:
        (T, n) joint angles.
    """
    ref = human_reference(robot, motion, placement)
    dt = float(np.median(np.diff(motion.times))) if motion.n_frames > 1 else 0.01
    q = np.clip(ref.q_map[0], robot.lower, robot.upper)
    history = np.tile(q, (3, 1))
    out = np.empty((motion.n_frames, robot.dof))
    for k in range(motion.n_frames):
        q = solve_frame(k, sample_at(ref, targets, k, history, dt), q)
        # RelaxedIK resets the history to the first solution
        history = np.tile(q, (3, 1)) if k == 0 else np.vstack([q, history[:2]])
        out[k] = q
        if progress is not None:
            progress(k)
    return out


def iterate(
    step: Callable[[np.ndarray], np.ndarray], q: np.ndarray, robot: Robot, max_iter: int, tol: float
) -> tuple[np.ndarray, int]:
    """Repeat ``q <- clip(q + step(q))`` until no joint moves more than ``tol`` or ``max_iter`` steps
    (the paper's stopping rule for JV). Returns the configuration and the steps taken."""
    steps = 0
    while steps < max_iter:
        new = np.clip(q + step(q), robot.lower, robot.upper)
        moved, q, steps = np.max(np.abs(new - q)), new, steps + 1
        if moved < tol:
            break
    return q, steps


def as_solver(name: str, solve: Callable, settings, learned, progress) -> Callable:
    """``solve(robot, motion, targets, placement, settings, learned, progress)[0]`` as a solver
    for :func:`hlik.retarget.retarget`, named ``name``."""

    def solver(robot: Robot, motion: HumanMotion, targets: HandTargets, placement: Placement) -> np.ndarray:
        return solve(robot, motion, targets, placement, settings, learned, progress)[0]

    solver.__name__ = solver.__qualname__ = name
    return solver
