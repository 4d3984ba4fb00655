"""The retargeting pipeline: motion -> problem (human kinematics, placement, targets, reference)
-> solver -> trajectory."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from hlik.criteria.learned import Learned
from hlik.human.fit import keypoint_markers
from hlik.human.motion import HumanMotion
from hlik.problem.placement import Placement
from hlik.problem.problem import Problem, build_problem
from hlik.robot.model import Robot, tcp_poses
from hlik.solvers import Solver, get_solver
from hlik.solvers.base import Diagnostics, SolverResult
from hlik.trajectory import Trajectory
from hlik.util.errors import HlikError


def retarget(
    motion: HumanMotion,
    robot: Robot,
    solver: str | Solver = "jm",
    placement: Placement | None = None,
    learned: Learned | None = None,
) -> Trajectory:
    """Retarget ``motion`` to ``robot`` with ``solver``: a name in ``SOLVER_NAMES``, or a :class:`Solver`.

    The problem (human kinematics, placement, hand targets, human reference, the learned pieces
    of the solver's ``criteria``) is built once and handed to the solver; ``placement`` defaults
    to the robot's rule (``Robot.placement``), ``learned`` to the pieces learned from the bundled
    demo where a criterion needs them (the library's default corpus; ``hlik run``'s is the shared
    KIT takes where found, :func:`hlik.util.paths.corpus_setting`). ``solver`` defaults to JM, the
    baseline that needs no settings; ``hlik run`` and :class:`~hlik.run_spec.RunSpec` default to
    the QP.
    A custom solver may also return bare joint angles (T, n); its diagnostics are then unknown
    (one pass per frame, nothing failed).

    Raises:
        HlikError: unknown solver name, or joint angles of the wrong shape.
    """
    if isinstance(solver, str):
        solver = get_solver(solver)  # an unknown name: UnknownNameError, an HlikError
    criteria = tuple(getattr(solver, "criteria", ()))
    problem = build_problem(motion, robot, placement, learned, criteria)
    return trajectory_of(problem, solver(problem), getattr(solver, "name", type(solver).__name__))


def trajectory_of(problem: Problem, result: SolverResult | np.ndarray, solver: str) -> Trajectory:
    """The :class:`Trajectory` of a solved ``problem``."""
    if not isinstance(result, SolverResult):
        result = SolverResult(np.asarray(result, dtype=float), Diagnostics.trivial(problem.n_frames))
    robot = problem.robot
    q = np.asarray(result.q, dtype=float)
    if q.shape != (problem.n_frames, robot.dof):
        expected = (problem.n_frames, robot.dof)
        raise HlikError(f"solver {solver!r} returned joint angles of shape {q.shape}, expected {expected}")
    tcp_pos, tcp_rot = tcp_poses(robot, q)
    return Trajectory(
        robot=robot.reference,
        solver=solver,
        times=problem.motion.times,
        joint_names=robot.joint_names,
        q=q,
        tcp_pos=tcp_pos,
        tcp_rot=tcp_rot,
        targets=problem.targets,
        placement=problem.placement,
        # body markers are left out (a KIT take has 53); a fitted motion's keypoints stay, for the recording
        motion=replace(problem.motion, markers=keypoint_markers(problem.motion)),
        reference=problem.reference,
        diagnostics=result.diagnostics,
    )
