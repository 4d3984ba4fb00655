"""One retargeting run, from a motion file to its scores: the pipeline that ``hlik run``, the
study's cells and ``bench/quality.py`` share.

    read (resample, crop) -> scale -> learn -> place -> solve (-> the whole take) -> evaluate

:class:`RunSpec` says what to run and :func:`run` runs it into a :class:`RunResult`. The spec is
checked whole (:meth:`RunSpec.check`) before anything is read, so a bad setting costs no solve.
A caller running several specs on one take and robot (the study's approaches) hands the shared
stage outputs to :func:`run` instead of recomputing them.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from hlik.criteria.learned import Learned, learn
from hlik.criteria.unified import load_metric
from hlik.findings import run_warnings
from hlik.human.load import load_motion
from hlik.human.motion import HumanMotion
from hlik.metrics import Evaluation, evaluate
from hlik.placement_search import Candidate, optimize_placement
from hlik.problem.placement import Placement, placement_from_spec, placement_notes
from hlik.problem.scale import scale_subject
from hlik.retarget import retarget
from hlik.robot.model import Robot, load_robot
from hlik.robot.reachability import reachability_map
from hlik.run_spec import RunSpec
from hlik.solvers import SPECS, get_solver
from hlik.solvers.stack_file import STAGE_TABLE, Stack
from hlik.trajectory import Trajectory
from hlik.util.errors import SettingsError

if TYPE_CHECKING:
    from hlik.solvers.whole_take import Refinement

# (stage, done, total): what the run is doing, and how far (None, None: no count)
Progress = Callable[[str, int | None, int | None], None]


@dataclass(frozen=True, eq=False)
class RunResult:
    """A finished run.

    Attributes:
        spec: What was run.
        robot: The robot.
        motion: The motion as retargeted (resampled, cropped, the subject scaled).
        learned: The learned pieces the criteria and scores used.
        trajectory: The retargeted trajectory.
        evaluation: Its costs, scores, controller checks and posture.
        scenario: The functional scenario scored (the spec's or the stack's).
        tried: The placements ``optimize`` compared (empty for another rule).
        notes: One-line warnings from reading, learning and placing (each names its source);
            :attr:`warnings` adds those about the result.
        solve_seconds: Wall time of the solve, s.
        solve_cpu: CPU time of the solve, s.
        whole_take: What the whole-take stage did (``spec.whole_take``, or the stack's choice
            for the solver and robot; None without it).
    """

    spec: RunSpec
    robot: Robot
    motion: HumanMotion
    learned: Learned
    trajectory: Trajectory
    evaluation: Evaluation
    scenario: str
    tried: tuple[Candidate, ...]
    notes: tuple[str, ...]
    solve_seconds: float
    solve_cpu: float
    whole_take: Refinement | None = None

    @property
    def warnings(self) -> list[str]:
        """The notes, then what the result itself shows (:func:`hlik.findings.run_warnings`)."""
        return [*self.notes, *run_warnings(self.trajectory, self.motion, self.evaluation, self.spec.rate)]


def read_motion(spec: RunSpec, robot: Robot) -> HumanMotion:
    """The spec's motion: read, resampled to ``spec.rate``, cropped to ``spec.span``, played
    ``spec.time_scale`` times as long, the subject scaled by ``spec.scale`` (the robot's rule if
    None)."""
    motion = load_motion(spec.motion_path, rate=spec.rate or None)
    if spec.span is not None:
        (start, stop), full = spec.span, motion.duration
        if start >= full:  # another span than asked for would be retargeted
            raise SettingsError(
                f"{spec.motion_path}: motion: --span {start:g}:{stop:g} starts after the take ends "
                f"({full:.2f} s)"
            )
        motion = motion.crop(start, min(stop, full))
        if stop > full:
            kept = f"{start:g}-{full:.2f} s"
            note = f"{spec.motion_path}: span {start:g}-{stop:g} s cut to {kept} (the take is shorter)"
            motion = replace(motion, notes=(*motion.notes, note))
    if walks := motion.walking():  # on the span retargeted, before scaling: the subject's own metres
        motion = replace(motion, notes=(*motion.notes, walks))
    return scale_subject(motion.retimed(spec.time_scale), robot, spec.scale)


def place(
    spec: RunSpec,
    robot: Robot,
    motion: HumanMotion,
    learned: Learned,
    scenario: str,
    progress: Progress | None = None,
) -> tuple[Placement, tuple[Candidate, ...], list[str]]:
    """Where the robot stands for the spec's placement rule, the candidates ``optimize`` tried and
    the notes (a reachability map's, a base off its floor)."""
    rule = spec.placement or robot.placement
    notes: list[str] = []
    if rule in ("reach", "optimize"):  # sampled or read once; placement reads the cache
        notes += reachability_map(
            robot, progress=_counter(progress, f"reachability map of {robot.title}")
        ).notes
    _say(progress, f"placing {robot.title} ({rule})")
    tried: tuple[Candidate, ...] = ()
    if rule == "optimize":
        # the spec's own settings where it is a QP run; the stack's QP weights otherwise
        qp = spec if spec.solver == "qp" else replace(spec, solver="qp", gradients="analytic", settings={})
        fast = get_solver("qp", solver_settings(qp, spec.task_stack(), robot.name))
        where, candidates = optimize_placement(motion, robot, fast, learned, scenario)
        tried = tuple(candidates)
    else:
        where = placement_from_spec(rule, robot, motion)
    return where, tried, notes + placement_notes(robot, where)


def solver_settings(spec: RunSpec, stack: Stack, robot: str | None = None) -> object | None:
    """The solver's settings: the stack's (for the robot named ``robot``, its table in the stack
    if any), with the spec's gradients and overrides (None for jm)."""
    if SPECS[spec.solver].settings is None:
        return None
    settings = stack.settings(spec.solver, robot)
    if spec.solver == "slsqp":
        settings = replace(settings, gradients=spec.gradients)
    return replace(settings, **spec.settings) if spec.settings else settings


def run(
    spec: RunSpec,
    progress: Progress | None = None,
    *,
    robot: Robot | None = None,
    motion: HumanMotion | None = None,
    learned: Learned | None = None,
    placement: Placement | None = None,
    limits: Sequence[object] = (),
) -> RunResult:
    """Run ``spec``: read, scale, learn, place, solve, evaluate.

    ``robot``, ``motion`` (already read and scaled: :func:`read_motion`), ``learned`` and
    ``placement``: stage outputs a caller shares between runs, used instead of computing them.
    ``limits``: a caller's ``mink.Limit``\\ s, kept by the solver (QP, mink, JV, SLSQP) beside its own.
    ``progress(stage, done, total)`` is told each stage, and each solved frame.

    Raises:
        HlikError: a bad setting (:meth:`RunSpec.check`), or an input that cannot be read, placed
            or retargeted (one line naming the file and the part).
    """
    stack = spec.check()
    scenario = spec.scenario or stack.scenario
    metric = load_metric(spec.metric) if spec.metric is not None else None
    robot = robot or load_robot(str(spec.robot))
    settings = solver_settings(spec, stack, robot.name)
    if spec.solver == "mink":  # mink's own objects built now: a value mink refuses, before the work
        from hlik.solvers.mink_specs import build_all

        build_all(robot, settings, stack.where)
    if motion is None:
        _say(progress, f"reading {spec.motion_path.name}")
        motion = read_motion(spec, robot)
    if learned is None:
        learned = learn(robot, spec.corpus, progress=_counter(progress, f"learning {robot.title}'s criteria"))
    notes = [*motion.notes, *learned.notes, *stack.near_misses(spec.solver, robot.name)]
    tried: tuple[Candidate, ...] = ()
    if placement is None:
        placement, tried, placed = place(spec, robot, motion, learned, scenario, progress)
        notes += placed
    stage = f"retargeting to {robot.title} ({spec.solver})"
    step = (lambda k: progress(stage, k + 1, motion.n_frames)) if progress else None
    _say(progress, stage, 0, motion.n_frames)
    wall, cpu = time.perf_counter(), time.process_time()
    solver = get_solver(spec.solver, settings, step, limits)
    refined: list[Refinement] = []
    if spec.follows_whole_take(robot.name, stack):
        from hlik.solvers.whole_take import WholeTake, settings_for

        announce = lambda stage: _say(progress, stage)  # noqa: E731
        stage_settings = settings_for(settings, stack.settings(STAGE_TABLE, robot.name))
        solver = WholeTake(solver, stage_settings, announce=announce, report=refined.append, limits=limits)
    traj = retarget(motion, robot, solver, placement, learned)
    traj = replace(traj, scenario=scenario)  # what hlik evaluate scores it by, unless told
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    _say(progress, "evaluating the criteria")
    ev = evaluate(traj, robot, learned, scenario=scenario, metric=metric)
    whole = refined[0] if refined else None
    return RunResult(spec, robot, motion, learned, traj, ev, scenario, tried, tuple(notes), wall, cpu, whole)


def _say(progress: Progress | None, stage: str, done: int | None = None, total: int | None = None) -> None:
    if progress is not None:
        progress(stage, done, total)


def _counter(progress: Progress | None, stage: str) -> Callable[[int, int], None] | None:
    """A ``(k, n)`` callback reporting ``stage``'s count to ``progress``."""
    if progress is None:
        return None
    progress(stage, None, None)
    return lambda k, n: progress(stage, k, n)


__all__ = ["Progress", "RunResult", "RunSpec", "place", "read_motion", "run", "solver_settings"]
