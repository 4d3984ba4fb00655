"""``hlik run``: retarget a motion (:func:`hlik.pipeline.run`), write the recording and the
trajectory, print the summary and the warnings."""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hlik.util.errors import HlikError
from hlik.util.paths import DEMO, no_shared_takes

if TYPE_CHECKING:  # imported where used: `hlik --help` stays quick
    from hlik.pipeline import RunResult
    from hlik.run_spec import RunSpec

from hlik.cli.app import (
    DEMO_CORPUS_WARNING,
    FLAG,
    TERMINATED,
    CorpusOpt,
    MetricOpt,
    MotionArg,
    Said,
    console,
    one_line,
    print_error,
    print_table,
    progress_bar,
    resolve_corpus,
    stopped_by,
    warn,
)
from hlik.cli.outputs import check_outputs, file_stem, write_outputs
from hlik.cli.summary import PRIORITY, run_summary
from hlik.robot.files import RobotDefaults, robot_defaults

RobotOpt = Annotated[
    str, typer.Option("--robot", "-r", help="Robot name (see `hlik robots`) or path of a robot .toml.")
]
SolverOpt = Annotated[
    str,
    typer.Option(
        "--solver",
        "-s",
        help="Retargeting solver: qp (per-frame QP: hands on target within every limit, the stack's "
        "criteria), jm (the paper's joint mapping), jv, slsqp, or mink (the QP on mink, with a stack's "
        "\\[mink] tasks and limits).",
    ),
]
OutOpt = Annotated[
    Path | None,
    typer.Option(
        "--out",
        "-o",
        help="Output .rrd (default: recordings/<motion>_<robot>_<solver>.rrd, the options that "
        "differ from the defaults added to the name).",
        show_default=False,
    ),
]
ForceOpt = Annotated[
    bool,
    typer.Option(
        "--force", "-f", help="Replace an existing output (.rrd, .npz).", metavar=FLAG, show_default=False
    ),
]
RateOpt = Annotated[float, typer.Option(help="Resample the motion to this rate (Hz); 0 keeps it.")]
LayoutOpt = Annotated[str, typer.Option(help="side: robot beside the human; overlay: on the human.")]
StackOpt = Annotated[
    str, typer.Option(help="Task stack: a .toml file, or a bundled one (ee_pose, relative_pose).")
]
CriteriaOpt = Annotated[
    str | None,
    typer.Option(
        help="Human-likeness criteria to add (jv, qp, slsqp, mink), e.g. SYN,HJA_r, or none; replaces "
        "the stack's (ee_pose: SYN,HJA_r)."
    ),
]
RunScenarioOpt = Annotated[
    str | None, typer.Option(help="Functional score: pose or relative (default: the stack's scenario).")
]
GradientsOpt = Annotated[
    str, typer.Option(help="slsqp: analytic gradients, or fd (finite differences, as the paper).")
]
PlacementOpt = Annotated[
    str | None,
    typer.Option(
        help="Where the robot stands: reach (reachability maps, the paper's), mapped (where "
        "the mapped joint angles reach the hands), working (within the maps, the hands at the "
        "subject's distance from the shoulders), optimize (the best of reach, mapped and others "
        "by m_hl,f of a fast QP run), shoulders (on the human's), or X,Y,YAW (world m, m, deg); "
        "each stands the robot on the floor. X,Y,YAW,Z also sets the base height (m; off the "
        "floor, warned). Default: the robot's (robots/<name>.toml; ARMAR-III reach, ARMAR-6 and "
        "2-Panda mapped).",
        show_default=False,
    ),
]
ScaleOpt = Annotated[
    str | None,
    typer.Option(
        help="Scale the subject before retargeting: auto (to the robot's arm length, about the "
        "shoulders) or a factor. Default: the robot's (ARMAR-III, 2-Panda 1, as in the paper; ARMAR-6 auto).",
        show_default=False,
    ),
]


ExportOpt = Annotated[
    str | None,
    typer.Option(
        help="Also export the trajectory for a robot's software (as `hlik export`): csv, mcap or lerobot; "
        "beside the .npz. A trajectory a controller would reject is not exported (a warning says why).",
        show_default=False,
    ),
]
SpanOpt = Annotated[
    str | None,
    typer.Option(
        help="Retarget only START:END seconds after the take's first frame (e.g. 2:5; END at most the "
        "take's end). Default: the whole take.",
        show_default=False,
    ),
]

TimeScaleOpt = Annotated[
    float,
    typer.Option(
        help="Play the motion this many times as long (time scaling): 2 at half its speed, for a "
        "robot whose speed or acceleration limits cannot follow the person (0.1 to 10).",
    ),
]
WholeTakeOpt = Annotated[
    bool | None,
    typer.Option(
        "--whole-take/--no-whole-take",
        help="Then optimise the solver's motion over the whole take at once (hlik.solvers.whole_take): "
        "the hands turned toward their targets where the frame-by-frame solver left them off, the "
        "solver's criteria weighed against them (the stack's \\[whole_take] table), within every limit "
        "the solver keeps; tens of ms a frame. Not with a relative-pose stack or --solver jm. "
        "Default: as the stack chooses for the solver and robot (\\[whole_take] after; ee_pose: after "
        "qp and slsqp on ARMAR-III and 2-Panda).",
        metavar=FLAG,
        show_default=False,
    ),
]


def _span(text: str | None) -> tuple[float, float] | None:
    """``START:END`` -> (start, end) s.

    Raises:
        HlikError: not two numbers, or not 0 <= START < END.
    """
    if text is None:
        return None
    try:
        start, end = (float(v) for v in text.split(":"))
    except ValueError:
        raise HlikError(f"--span {text}: expected START:END in seconds, e.g. 2:5") from None
    if not (0.0 <= start < end < float("inf")):
        raise HlikError(f"--span {text}: START and END must be finite with 0 <= START < END (s)")
    return start, end


def run(
    motion: MotionArg = None,
    robot: RobotOpt = "armar6",
    solver: SolverOpt = "qp",
    out: OutOpt = None,
    force: ForceOpt = False,
    rate: RateOpt = 100.0,
    layout: LayoutOpt = "side",
    corpus: CorpusOpt = None,
    stack: StackOpt = "ee_pose",
    criteria: CriteriaOpt = None,
    scenario: RunScenarioOpt = None,
    gradients: GradientsOpt = "analytic",
    placement: PlacementOpt = None,
    scale: ScaleOpt = None,
    metric: MetricOpt = None,
    span: SpanOpt = None,
    time_scale: TimeScaleOpt = 1.0,
    export: ExportOpt = None,
    whole_take: WholeTakeOpt = None,
) -> None:
    """Retarget a motion to a robot; write a Rerun recording and the trajectory (.npz) beside it."""
    from hlik.recording.layout import LAYOUTS
    from hlik.run_spec import EXPORT_FORMATS, RunSpec

    with one_line():
        corpus, corpus_source = resolve_corpus(corpus)
        chosen = None if criteria is None else _criteria(criteria)
        spec = RunSpec(
            motion=motion,
            robot=robot,
            solver=solver,
            stack=stack,
            criteria=chosen,
            scenario=scenario,
            placement=placement,
            scale=scale,
            rate=rate,
            corpus=corpus,
            metric=metric,
            gradients=gradients,
            span=_span(span),
            time_scale=time_scale,
            whole_take=whole_take,
        )
        if layout not in LAYOUTS:
            raise HlikError(f"unknown layout {layout!r}; choose one of: {', '.join(LAYOUTS)}")
        spec.check()  # names, numbers and files before the heavy imports below
        if export is not None and export not in EXPORT_FORMATS:
            raise HlikError(f"unknown --export format {export!r}; choose one of: {', '.join(EXPORT_FORMATS)}")
        # the outputs before the heavy imports too: the default name needs the robot's description only
        defaults = robot_defaults(robot)
        rrd, npz = _outputs(spec, defaults, out, force, _tag(spec, defaults, layout, corpus_source))
        result = _run_and_write(spec, rrd, npz, layout)
    try:
        _report(result, rrd, npz, corpus_source)
        if export is not None:
            _export(result, npz, export)
    except (KeyboardInterrupt, SystemExit) as stop:  # the outputs are written: say so
        code = stopped_by(stop)
        if code is None:
            raise
        how = "terminated" if code == TERMINATED else "interrupted"
        cut = " (an export is written whole or not at all)" if export is not None else ""
        print_error(f"{how} after writing {rrd} and {npz}; what followed was cut short{cut}")
        raise Said(code) from None


def _motion_stem(path: Path) -> str:
    """The motion's part of a default file name: its stem, and its format where it is not MMM
    (``demo_pour_wipe.bvh`` -> ``demo_pour_wipe_bvh``), so that takes differing only in format do not
    share files."""
    suffix = path.suffix.lower().lstrip(".")
    return path.stem if suffix in ("xml", "") else f"{path.stem}_{suffix}"


def _run_and_write(spec: RunSpec, rrd: Path, npz: Path, layout: str) -> RunResult:
    """The robot loaded, the pipeline's run with a progress line on stderr, then the recording
    and the trajectory. The line starts before the heavy imports: a cold first run is heard from
    its first seconds when piped."""
    with progress_bar(spinner=True) as bar:
        task = bar.add_task(f"loading {spec.robot}", total=None)
        from hlik.pipeline import run as run_pipeline
        from hlik.robot.model import load_robot

        robot = load_robot(str(spec.robot))

        def show(stage: str, done: int | None, total: int | None) -> None:
            bar.update(task, description=stage, completed=done or 0, total=total)

        result = run_pipeline(spec, show, robot=robot)
        bar.update(task, description=f"writing {rrd}", total=None)
        info = _settings(result, layout)
        write_outputs(npz, rrd, result.trajectory, robot, layout, evaluation=result.evaluation, info=info)
    return result


def _outputs(
    spec: RunSpec, robot: RobotDefaults, out: Path | None, force: bool, tag: str
) -> tuple[Path, Path]:
    """The recording and trajectory files of a run, checked: ``--out`` or the default name under
    ``recordings/`` (created), refused where they exist without ``--force`` or name an input."""
    rrd = out or Path("recordings") / f"{file_stem(_motion_stem(spec.motion_path), robot.name, tag)}.rrd"
    npz = rrd.with_suffix(".npz")
    check_outputs(rrd, npz, _inputs(spec), create=out is None, force=force)
    return rrd, npz


def _report(result: RunResult, rrd: Path, npz: Path, corpus_source: str) -> None:
    """The summary, the scores, the warnings and the commands to go on with."""
    from hlik.robot.reach import arm_reach
    from hlik.solvers.catalog import solver_spec

    traj, ev, spec = result.trajectory, result.evaluation, result.spec
    # Lines naming a file or a command are printed whole, each on its own line: a table cell would
    # break a path at the console's width (80 columns when piped).
    criteria = spec.task_stack().criteria
    how = traj.solver + (f" + {', '.join(criteria)}" if criteria else "")
    how += ", no criteria" if not criteria and solver_spec(spec.solver).takes_criteria else ""
    console.print(f"{spec.motion_path.stem} -> {result.robot.name} ({how})", soft_wrap=True)
    beyond = arm_reach(result.robot).beyond(traj.targets.pos)
    print_table(run_summary(traj, result.motion, result.solve_seconds, ev, _solver_note(result), beyond))
    size = lambda path: f"{path.stat().st_size / 1e6:.1f} MB"  # noqa: E731
    console.print(f"recording: {rrd} ({size(rrd)})", soft_wrap=True)
    console.print(f"trajectory: {npz} ({size(npz)})", soft_wrap=True)
    label = _corpus_label(spec.corpus, result.learned.corpus, corpus_source)
    console.print(f"criteria learned from: {label}", soft_wrap=True)
    if result.tried:
        scores = ", ".join(f"{c.name} {c.m_hl_f:.3f}" for c in result.tried)
        console.print(f"placement optimize (m_hl,f of a short qp run): {scores}", soft_wrap=True)
    console.print(
        f"human likeness m_hl = {ev.m_hl:.3f}, functional m_f = {ev.m_f:.3f} ({result.scenario}), "
        f"m_hl,f = {ev.m_hl_f:.3f}, weights and x0: {ev.metric.source}",
        soft_wrap=True,
    )
    fallback = spec.corpus is None and not corpus_source  # the demo, chosen by no one
    warn([*result.warnings, *([DEMO_CORPUS_WARNING] if fallback else [])])  # at the end, where seen
    # the same scores again: everything that changed them here is passed on
    details = ["hlik", "evaluate", str(npz), "--scenario", result.scenario]
    details += ["--corpus", str(spec.corpus) if spec.corpus is not None else DEMO]
    details += ["--metric", str(spec.metric)] if spec.metric is not None else []
    # Commands to copy: each on its own line, never wrapped inside a path.
    console.print(f"details: {shlex.join(details)}", soft_wrap=True)
    console.print(f"open with: rerun {shlex.quote(str(rrd))}", soft_wrap=True)


def _export(result: RunResult, npz: Path, fmt: str) -> None:
    """``hlik export NPZ --format FMT --force`` of the run just written (a run's default names are
    its own, so an export of an earlier run of the same name is replaced with it); a refusal is a
    warning, the run's own files stand, with the command that writes it anyway."""
    from hlik.cli.export import braked
    from hlik.export import default_path, export

    path = default_path(npz, fmt)
    with one_line():  # a failed write (full disk) is an error
        try:
            written = export(result.trajectory, result.robot, path, fmt)
        except HlikError as refused:
            command = shlex.join(
                ["hlik", "export", str(npz), "--format", fmt, "--allow-violations", "--force"]
            )
            warn([f"{refused}; to write it anyway: {command}"])
            return
    traj = result.trajectory
    added = braked(traj, result.robot)
    console.print(f"exported: {written} ({fmt}, {traj.n_frames} frames{added})", soft_wrap=True)


def _priority(settings: object) -> str:
    """How a run's solver ``settings`` rank the hands (``QPSettings.priority``; others weigh them)."""
    return getattr(settings, "priority", "weighted")


def _solver_note(result: RunResult) -> str:
    """What the summary's solver row adds: the priority unless weighted, and the look-ahead's pull
    (the QP's, mink's and SLSQP's; it differs per robot in ``ee_pose``)."""
    from hlik.solvers.preview import LOOK_AHEAD_FRAMES
    from hlik.solvers.settings import SLSQPSettings

    settings = _solver_settings(result)
    priority = _priority(settings)
    notes = [] if priority == "weighted" else [PRIORITY[priority]]
    own = [*getattr(settings, "tasks", ()), *getattr(settings, "limits", ())]  # --solver mink's
    if own:
        notes.append(f"mink's own {', '.join(str(spec['type']) for spec in own)} ([mink])")
    pull = getattr(settings, "preview_cost", None)
    if pull is not None and result.motion.n_frames >= LOOK_AHEAD_FRAMES:
        # the QP's pull is a least-squares weight per rad, SLSQP's a groove loss's weight
        unit = "" if isinstance(settings, SLSQPSettings) else " per rad"
        said = f"look-ahead pulled at {pull:g}{unit}" if pull > 0 else "one pass, no look-ahead"
        notes.append(f"{said} (preview_cost)")
    done = result.whole_take
    if done is not None:
        merit = f"merit {done.merit[0]:.3g} -> {done.merit[1]:.3g}" if done.accepted else "no step kept"
        why = _whole_take_chooser(result) + ("" if result.spec.whole_take else "; off: --no-whole-take")
        notes.append(
            f"then the whole take at once: {done.iterations} QPs{' (its cap)' if done.capped else ''}, "
            f"{done.accepted} steps kept, {merit}, "
            f"{done.seconds:.1f} s ({why})"
        )
    return "; ".join(notes)


def _solver_settings(result: RunResult) -> object:
    """The settings the run's solver ran with (its stack's table for the robot, and the spec's)."""
    from hlik.pipeline import solver_settings

    return solver_settings(result.spec, result.spec.task_stack(), result.robot.name)


def _settings(result: RunResult, layout: str) -> dict[str, str]:
    """The settings the recording's result panel shows (setting -> text)."""
    spec = result.spec
    return {
        "stack": str(spec.stack),
        "criteria": ", ".join(spec.task_stack().criteria) or "-",
        "priority": PRIORITY[_priority(_solver_settings(result))],
        "scenario": result.scenario,
        "placement": spec.placement or result.robot.placement,
        "corpus": _corpus_label(spec.corpus, result.learned.corpus),
        "gradients": spec.gradients,
        "whole take": _whole_take_label(result),
    }


def _whole_take_label(result: RunResult) -> str:
    """Whether the whole-take stage followed the solver, and who chose it."""
    if result.whole_take is None:
        return "no (--no-whole-take)" if result.spec.whole_take is False else "no (the stack's choice)"
    return f"yes ({_whole_take_chooser(result)})"


def _whole_take_chooser(result: RunResult) -> str:
    """Who chose the whole-take stage that ran: the command line or the stack."""
    return "--whole-take" if result.spec.whole_take else "the stack's [whole_take] after"


def _inputs(spec: RunSpec) -> list:
    """The files a run reads, which its outputs must not replace."""
    from hlik.util.paths import tasks_dir

    return [spec.motion_path, spec.metric, spec.robot, spec.stack, tasks_dir() / f"{spec.stack}.toml"]


def _tag(spec: RunSpec, robot: RobotDefaults, layout: str, corpus_source: str) -> str:
    """:func:`_run_tag` of a run: the spec's choices that differ from the defaults (the corpus
    folder where this command chose one: ``--corpus`` or ``$HLIK_CORPUS``; never the demo)."""
    from hlik.util.paths import tasks_dir

    stack = spec.task_stack()
    bundled = not Path(spec.stack).exists() and (tasks_dir() / f"{spec.stack}.toml").is_file()
    own = replace(spec, criteria=None).task_stack().criteria  # the stack file's (none for jm)
    return _run_tag(
        solver=spec.solver,
        stack=stack.name if bundled else _stack_label(Path(spec.stack).stem, stack.name),
        default_stack=bundled and stack.name == "ee_pose",
        criteria=stack.criteria,
        stack_criteria=own,
        gradients=spec.gradients,
        placement=spec.placement if spec.placement not in (None, robot.placement) else None,
        scale=str(spec.scale) if spec.scale not in (None, str(robot.subject_scale)) else None,
        scenario=spec.scenario if spec.scenario not in (None, stack.scenario) else None,
        metric=None if spec.metric is None else Path(spec.metric),
        rate=spec.rate,
        layout=layout,
        span=spec.span,
        time_scale=spec.time_scale,
        # named where it differs from what the stack does for the solver and robot
        whole_take=spec.whole_take,
        whole_take_default=stack.whole_take(spec.solver, robot.name),
        corpus=spec.corpus if corpus_source in ("--corpus", "HLIK_CORPUS") else None,
    )


def _run_tag(
    *,
    solver: str,
    stack: str,
    default_stack: bool,
    criteria: Sequence[str],
    stack_criteria: Sequence[str] = (),
    gradients: str,
    placement: str | None,
    scale: str | None = None,
    scenario: str | None,
    metric: Path | None,
    rate: float,
    layout: str,
    corpus: Path | None,
    span: tuple[float, float] | None = None,
    time_scale: float = 1.0,
    whole_take: bool | None = None,
    whole_take_default: bool = False,
) -> str:
    """The part of the default output name after motion and robot: every choice that changes the
    result, defaults left out, e.g. ``slsqp_SYN_fd``, ``qp_my_stack_at-0.4_1.2_90``: the
    criteria where they are not the default stack's own (``stack_criteria``), ``nocriteria`` where
    a stack's own are left out."""
    if default_stack and tuple(criteria) == tuple(stack_criteria):
        named: Sequence[str] = ()
    else:
        named = criteria or (("nocriteria",) if stack_criteria else ())
    whole = "" if whole_take in (None, whole_take_default) else ("-whole" if whole_take else "-alone")
    parts = [solver + whole, *(() if default_stack else (stack,)), *named]
    parts += ["fd"] if gradients == "fd" else []
    parts += [f"at-{placement}"] if placement is not None else []
    parts += [f"scale-{scale}"] if scale is not None else []
    parts += [scenario] if scenario is not None else []
    parts += [f"metric-{metric.stem}"] if metric is not None else []
    parts += [] if rate == 100.0 else ["native" if rate == 0 else f"{rate:g}Hz"]
    parts += [layout] if layout != "side" else []
    parts += [f"{span[0]:g}-{span[1]:g}s"] if span is not None else []
    parts += [f"x{time_scale:g}"] if time_scale != 1.0 else []
    parts += [f"corpus-{Path(corpus).resolve().name or 'root'}"] if corpus is not None else []
    return "_".join(parts)


def _criteria(text: str) -> tuple[str, ...]:
    """``--criteria``: names split at commas, or ``none`` (any case) for none.

    Raises:
        HlikError: nothing given (an empty shell variable must not drop the stack's criteria
            unsaid), or ``none`` beside names.
    """
    names = tuple(c.strip() for c in text.split(",") if c.strip())
    if not names:
        raise HlikError("--criteria is empty: give names (e.g. SYN,HJA_r), or none for no criteria")
    if any(n.lower() == "none" for n in names):
        if len(names) > 1:
            raise HlikError(f"--criteria {text}: none means no criteria and takes no names beside it")
        return ()
    return names


def _stack_label(stem: str, name: str) -> str:
    """A stack file in a default output name: its stem, and its ``name`` where that differs (a
    copied ``my.toml`` still named ``ee_pose`` must not write the bundled stack's file)."""
    return stem if name == stem else f"{stem}_{name}"


def _corpus_label(corpus: Path | None, files: Sequence[str], source: str = "") -> str:
    """``the bundled demo (demo_pour_wipe.xml, chosen by HLIK_CORPUS)``, ``... (demo_pour_wipe.xml,
    no corpus of recorded motion found)`` or ``DIR (n files, from HLIK_CORPUS)``."""
    if corpus is None:
        why = f"chosen by {source}" if source else no_shared_takes()
        return f"the bundled demo ({', '.join(files)}, {why})"
    count = f"{len(files)} file" + ("s" if len(files) != 1 else "")
    return f"{corpus} ({count}" + (f", from {source})" if source else ")")
