"""The ``hlik`` command line. Bad input ends in one line on stderr and exit code 2."""

from __future__ import annotations

import math
import os
import re
import shlex
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console
from rich.table import Table
from rich.text import Text
from typer.core import TyperGroup

from hlik.atomic import raising_on_sigterm
from hlik.errors import HlikError
from hlik.paths import corpus_setting, demo_motion_path

if TYPE_CHECKING:  # imported where used: `hlik --help` stays quick
    import numpy as np

    from hlik.metrics import Evaluation
    from hlik.robot.mapping import JointMap
    from hlik.robot.model import Robot
    from hlik.trajectory import Trajectory

_FLAG = ""  # metavar of an on/off option: typer would show it as `--json <bool>`, taking a value


def _warn(notes) -> None:
    """``warning: <note>`` on one line of stderr for each note (text, never markup)."""
    err = Console(stderr=True, soft_wrap=True, highlight=False)
    for note in notes:
        err.print(Text.assemble(("warning:", "yellow"), " ", " ".join(str(note).split())))


def _print_error(message: str) -> None:
    """``error: <message>`` on one line of stderr; the message is text, never markup ("[qp]")."""
    text = Text.assemble(("error:", "red"), " ", " ".join(message.split()))
    Console(stderr=True, soft_wrap=True, highlight=False).print(text)


INTERRUPTED = 130  # exit code of a command ended by Ctrl-C (128 + SIGINT)


class _OneLineErrors(TyperGroup):
    """Usage errors (unknown option, bad value) in one line and exit code 2, like hlik's own errors,
    instead of click's box; SIGTERM ends a command through ``finally`` blocks (temporaries removed)."""

    def main(
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        windows_expand_args: bool = True,
        **extra: Any,
    ) -> Any:
        try:
            with raising_on_sigterm():
                result = super().main(
                    args, prog_name, complete_var, False, windows_expand_args=windows_expand_args, **extra
                )
        except typer.TyperException as e:  # click's usage errors, as typer vendors them
            ctx = getattr(e, "ctx", None)
            if type(e).__name__ != "NoArgsIsHelpError":  # `hlik` alone: the help is printed
                see = f" (see: {ctx.command_path} --help)" if ctx is not None else ""
                _print_error(f"{e.format_message()}{see}")
            result = 2
        except typer.Abort:  # end of input at a prompt
            _print_error("aborted")
            result = 1
        if result == INTERRUPTED:  # typer turns Ctrl-C into this exit code, silently
            _print_error("interrupted; nothing written")
        if not standalone_mode:
            return result
        sys.exit(result if isinstance(result, int) else 0)


app = typer.Typer(
    cls=_OneLineErrors,
    help="hlik: human-like bimanual motion retargeting (MMM human -> ARMAR-III, ARMAR-6, 2-Panda).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
# Motion files a folder of takes may hold: MMM, BVH, keypoint descriptions (hlik.human.load_motion).
MOTION_FILES = ("*.xml", "*.bvh", "*.toml")
# Output is text, not markup: file, motion and object names print as written ("[red]take.xml").
console = Console(markup=False)

MotionArg = Annotated[
    Path | None,
    typer.Argument(
        help="Motion: MMM .xml, .bvh or a keypoint .toml (default: the bundled demo).", show_default=False
    ),
]

CorpusOpt = Annotated[
    Path | None,
    typer.Option(
        help="Folder of MMM motions to learn synergies and the swivel regressor from (default: "
        '$HLIK_CORPUS, else corpus = "DIR" in ./hlik.toml, else the bundled demo).',
        show_default=False,
    ),
]
ScenarioOpt = Annotated[
    str, typer.Option(help="Functional score: pose (hand poses) or relative (relative pose of the hands).")
]
MetricOpt = Annotated[
    Path | None,
    typer.Option(
        help="Weights and x0 of m_hl from a TOML file (e.g. study/metric.toml of `hlik study`); "
        "default: the paper's Table III.",
        show_default=False,
    ),
]


def _fail(err: HlikError) -> None:
    _print_error(str(err))
    raise typer.Exit(2)


@contextmanager
def _one_line() -> Iterator[None]:
    """Bad input and failed reads or writes end the command with one line and exit code 2."""
    try:
        yield
    except HlikError as e:
        _fail(e)
    except OSError as e:  # what the readers do not name themselves (permission, full disk)
        where = f"{e.filename}: " if e.filename else ""
        _fail(HlikError(f"{where}{e.strerror or e}"))


@app.command()
def run(
    motion: MotionArg = None,
    robot: Annotated[
        str, typer.Option("--robot", "-r", help="Robot name (see `hlik robots`) or path of a robot .toml.")
    ] = "armar6",
    solver: Annotated[
        str, typer.Option("--solver", "-s", help="Retargeting solver: jm, jv, qp or slsqp.")
    ] = "jm",
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            "-o",
            help="Output .rrd (default: recordings/<motion>_<robot>_<solver>[_<what else differs>].rrd).",
            show_default=False,
        ),
    ] = None,
    force: Annotated[
        bool,
        typer.Option(
            "--force",
            "-f",
            help="Replace an existing output (.rrd, .npz).",
            metavar=_FLAG,
            show_default=False,
        ),
    ] = False,
    rate: Annotated[float, typer.Option(help="Resample the motion to this rate (Hz); 0 keeps it.")] = 100.0,
    layout: Annotated[
        str, typer.Option(help="side: robot beside the human; overlay: on the human.")
    ] = "side",
    corpus: CorpusOpt = None,
    stack: Annotated[
        str,
        typer.Option(help="Task stack: a .toml file, or a bundled one (ee_pose, relative_pose)."),
    ] = "ee_pose",
    criteria: Annotated[
        str | None,
        typer.Option(
            help="Human-likeness criteria to add (jv, qp, slsqp), e.g. SYN,HJA_r; replaces the stack's."
        ),
    ] = None,
    scenario: Annotated[
        str | None,
        typer.Option(help="Functional score: pose or relative (default: the stack's scenario)."),
    ] = None,
    gradients: Annotated[
        str, typer.Option(help="slsqp: analytic gradients, or fd (finite differences, as the paper).")
    ] = "analytic",
    placement: Annotated[
        str | None,
        typer.Option(
            help="Where the robot stands: reach (reachability maps, the paper's), mapped (where "
            "the mapped joint angles reach the hands), working (within the maps, the hands at the "
            "subject's distance from the shoulders), optimize (the best of reach, mapped and others "
            "by m_hl,f of a fast QP run), shoulders (on the human's), or X,Y,YAW (world m, m, deg); "
            "each stands the robot on the floor. X,Y,YAW,Z also sets the base height (m; off the "
            "floor, warned). Default: the robot's (robots/<name>.toml; reach, 2-Panda mapped).",
            show_default=False,
        ),
    ] = None,
    scale: Annotated[
        str | None,
        typer.Option(
            help="Scale the subject before retargeting: auto (to the robot's arm length) or a factor. "
            "Default: the robot's (1 for ARMAR-III, ARMAR-6, 2-Panda, as in the paper).",
            show_default=False,
        ),
    ] = None,
    metric: MetricOpt = None,
) -> None:
    """Retarget a motion to a robot; write a Rerun recording and the trajectory (.npz) beside it."""
    from hlik.paths import tasks_dir
    from hlik.pipeline import RunSpec
    from hlik.pipeline import run as run_pipeline
    from hlik.recording import LAYOUTS
    from hlik.robot.model import load_robot

    with _one_line():
        corpus, corpus_source = (corpus, "--corpus") if corpus is not None else corpus_setting()
        chosen = None if criteria is None else tuple(c.strip() for c in criteria.split(",") if c.strip())
        spec = RunSpec(
            motion,
            robot,
            solver,
            stack,
            chosen,
            scenario,
            placement,
            scale,
            rate,
            None,
            corpus,
            metric,
            gradients,
        )
        if layout not in LAYOUTS:
            raise HlikError(f"unknown layout {layout!r}; choose one of: {', '.join(LAYOUTS)}")
        task_stack = spec.check()
        r = load_robot(robot)
        bundled = not Path(stack).exists() and (tasks_dir() / f"{stack}.toml").is_file()
        tag = _run_tag(
            solver=solver,
            stack=task_stack.name if bundled else _stack_label(Path(stack).stem, task_stack.name),
            default_stack=bundled and task_stack.name == "ee_pose",
            criteria=task_stack.criteria,
            gradients=gradients,
            placement=placement if placement not in (None, r.placement) else None,
            scale=scale if scale not in (None, str(r.subject_scale)) else None,
            scenario=scenario if scenario not in (None, task_stack.scenario) else None,
            metric=metric,
            rate=rate,
            layout=layout,
            corpus=corpus,
        )
        path = spec.motion_path
        rrd = out or Path("recordings") / f"{_file_stem(path.stem, r.name, tag)}.rrd"
        npz = rrd.with_suffix(".npz")
        inputs = [path, metric, robot, stack, tasks_dir() / f"{stack}.toml"]
        _check_outputs(rrd, npz, inputs, create=out is None, force=force)
        with _progress(spinner=True) as bar:
            task = bar.add_task("", total=None)
            result = run_pipeline(
                spec,
                lambda stage, done, total: bar.update(
                    task, description=stage, completed=done or 0, total=total
                ),
                robot=r,
            )
            bar.update(task, description=f"writing {rrd}", total=None)
            info = {
                "stack": stack,
                "criteria": ", ".join(task_stack.criteria) or "-",
                "scenario": result.scenario,
                "placement": placement or r.placement,
                "corpus": _corpus_label(corpus, result.learned.corpus),
                "gradients": gradients,
            }
            write_outputs(npz, rrd, result.trajectory, r, layout, evaluation=result.evaluation, info=info)
    traj, m, ev = result.trajectory, result.motion, result.evaluation
    summary = _run_summary(path.stem, traj, m, result.solve_seconds, rrd, npz, ev)
    summary.add_row("criteria learned from", _corpus_label(corpus, result.learned.corpus, corpus_source))
    console.print(summary)
    if result.tried:
        scores = ", ".join(f"{c.name} {c.m_hl_f:.3f}" for c in result.tried)
        console.print(f"placement optimize (m_hl,f of a short qp run): {scores}")
    console.print(
        f"human likeness m_hl = {ev.m_hl:.3f}, functional m_f = {ev.m_f:.3f} ({result.scenario}), "
        f"m_hl,f = {ev.m_hl_f:.3f}, weights and x0: {ev.metric.source}",
        soft_wrap=True,
    )
    _warn(result.warnings)  # at the end, where they are seen
    # the same scores again: everything that changed them here is passed on
    details = ["hlik", "evaluate", str(npz), "--scenario", result.scenario]
    details += ["--corpus", str(corpus)] if corpus is not None else []
    details += ["--metric", str(metric)] if metric is not None else []
    # Commands to copy: each on its own line, never wrapped inside a path.
    console.print(f"details: {shlex.join(details)}", soft_wrap=True)
    console.print(f"open with: rerun {shlex.quote(str(rrd))}", soft_wrap=True)


def _run_tag(
    *,
    solver: str,
    stack: str,
    default_stack: bool,
    criteria: Sequence[str],
    gradients: str,
    placement: str | None,
    scale: str | None = None,
    scenario: str | None,
    metric: Path | None,
    rate: float,
    layout: str,
    corpus: Path | None,
) -> str:
    """The part of the default output name after motion and robot: every choice that changes the
    result, defaults left out, e.g. ``slsqp_SYN_HJA_r_fd``, ``qp_my_stack_at-0.4_1.2_90``."""
    parts = [solver, *(() if default_stack else (stack,)), *criteria]
    parts += ["fd"] if gradients == "fd" else []
    parts += [f"at-{placement}"] if placement is not None else []
    parts += [f"scale-{scale}"] if scale is not None else []
    parts += [scenario] if scenario is not None else []
    parts += [f"metric-{metric.stem}"] if metric is not None else []
    parts += [] if rate == 100.0 else ["native" if rate == 0 else f"{rate:g}Hz"]
    parts += [layout] if layout != "side" else []
    parts += [f"corpus-{Path(corpus).resolve().name or 'root'}"] if corpus is not None else []
    return "_".join(parts)


def _stack_label(stem: str, name: str) -> str:
    """A stack file in a default output name: its stem, and its ``name`` where that differs (a
    copied ``my.toml`` still named ``ee_pose`` must not write the bundled stack's file)."""
    return stem if name == stem else f"{stem}_{name}"


def _corpus_label(corpus: Path | None, files: Sequence[str], source: str = "") -> str:
    """``demo (demo_pour_wipe.xml)`` or ``DIR (n files, from HLIK_CORPUS)``."""
    if corpus is None:
        return f"the bundled demo ({', '.join(files)})"
    count = f"{len(files)} file" + ("s" if len(files) != 1 else "")
    return f"{corpus} ({count}" + (f", from {source})" if source else ")")


def _controller_line(c) -> str:
    """The summary's ``controller`` row: what :class:`hlik.executable.ControllerChecks` found."""
    j = c.to_json()
    parts = []
    if c.has_acceleration_limits:
        parts.append(
            f"peak acceleration {j['max_acceleration_ratio']:.2f} of its limit ({j['acceleration_joint']}), "
            f"{j['frames_over_acceleration']} frames over"
        )
    else:
        parts.append("no acceleration limits given")
    if c.has_jerk_limits:
        parts.append(
            f"peak jerk {j['max_jerk_ratio']:.2f} of its limit ({j['jerk_joint']}), "
            f"{j['frames_over_jerk']} frames over"
        )
    else:
        parts.append(f"peak jerk {j['max_jerk']:.0f} rad/s³ ({j['jerk_joint']}; no jerk limits given)")
    if c.has_effort_limits:
        parts.append(
            f"peak torque {j['max_torque_ratio']:.2f} of its limit ({j['torque_joint']}, "
            f"{j['max_torque']:.1f} N m), {j['frames_over_effort']} frames over"
        )
    else:
        parts.append(f"peak torque {j['max_torque']:.1f} N m ({j['torque_joint']}; no effort limits given)")
    parts.append(f"a joint within 0.5° of a stop in {100 * j['share_at_stop']:.1f} % of frames")
    parts.append(f"base at z {j['base_height']:.3f} m, lowest point {j['lowest_point']:.3f} m")
    if j["end_speed"] > 0.0:
        parts.append(
            f"ends moving at up to {j['end_speed']:.2f} rad/s ({j['stop_time']:.2f} s to stop at the "
            "acceleration limits)"
        )
    else:
        parts.append("ends at rest")
    return "; ".join(parts)


def _posture_line(p) -> str:
    """The summary's ``posture`` row: the robot's :class:`hlik.posture.Posture` beside the subject's
    (medians; lengths as shares of the arm's length; left / right)."""
    j = p.to_json()
    pair = lambda key: " / ".join(f"{v:.2f}" for v in j[key])  # noqa: E731
    percent = lambda key: " / ".join(f"{100 * v:.0f} %" for v in j[key])  # noqa: E731
    return (
        f"trunk lean {j['trunk_lean_deg']:.0f}° (subject {j['subject_trunk_lean_deg']:.0f}°); "
        f"elbows in front of the shoulders {pair('elbow_front_share')} arm (subject "
        f"{pair('subject_elbow_front_share')}), > 5 cm behind in {percent('elbow_behind_share')} of frames "
        f"(subject {percent('subject_elbow_behind_share')}); hands in front {pair('hand_front_share')} arm "
        f"(subject {pair('subject_hand_front_share')}); swivel off the subject's by "
        f"{' / '.join(f'{v:.0f}°' for v in j['swivel_difference_deg'])}; arm joint path "
        f"{j['path_ratio']:.2f} of the subject's"
    )


def _file_stem(*parts: str) -> str:
    """A file name stem from names read from files (motion, robot, stack): anything but letters,
    digits, ``.``, ``+``, ``-`` and ``_`` becomes ``_``, so no name can reach another folder."""
    return re.sub(r"[^\w.+-]", "_", "_".join(parts)).lstrip(".") or "out"


def _check_outputs(rrd: Path, npz: Path, inputs: list, create: bool, force: bool = False) -> None:
    """Fail before solving, not after: the recording must be a ``.rrd`` whose folder is writable,
    neither output may be one of the ``inputs`` (paths or names; those that are no file are
    skipped), and neither may exist unless ``force``."""
    if rrd.is_dir():
        raise HlikError(f"{rrd}: is a folder, expected a .rrd file name")
    if rrd.suffix != ".rrd":
        raise HlikError(
            f"{rrd}: --out names the recording and must end in .rrd (the trajectory is written beside "
            f"it, as {rrd.with_suffix('.npz').name})"
        )
    read = [Path(p) for p in inputs if p is not None and Path(p).is_file()]
    for output in (rrd, npz):
        for source in read:
            if output.exists() and os.path.samefile(output, source) or output.resolve() == source.resolve():
                raise HlikError(f"{output}: is an input of this run ({source}); choose another --out")
    if not force:
        for output in (rrd, npz):
            if output.is_file() or output.is_symlink():
                raise HlikError(f"{output}: exists; pass --force to replace it, or --out to write elsewhere")
    folder = rrd.parent
    if create and not folder.exists():  # made when the outputs are written: a failed run leaves none
        folder = next(p for p in folder.parents if p.exists())
    if not folder.is_dir():
        raise HlikError(f"{rrd}: output folder {folder} does not exist")
    if npz.is_dir():
        raise HlikError(f"{npz}: is a folder, where the trajectory would be written")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise HlikError(f"{rrd}: output folder {folder} is not writable")


def write_outputs(
    npz: Path,
    rrd: Path,
    traj: Trajectory,
    robot: Robot,
    layout: str = "side",
    metrics: Mapping[str, np.ndarray] | None = None,
    evaluation: Evaluation | None = None,
    info: Mapping[str, str] | None = None,
) -> None:
    """Write the trajectory ``npz`` and its recording ``rrd`` together: both appear, or neither
    (:func:`hlik.atomic.atomic_paths`; a failed, interrupted or terminated write leaves no file).
    ``evaluation`` and ``info`` (setting -> text) go to the recording's result panel.

    Raises:
        HlikError: naming the file that could not be written (never the temporary).
    """
    from hlik.atomic import atomic_paths
    from hlik.recording import write_recording

    with _writing(npz, rrd):
        rrd.parent.mkdir(parents=True, exist_ok=True)
    with _writing(npz, rrd), atomic_paths(npz, rrd) as (npz_tmp, rrd_tmp):
        with _writing(npz):
            traj.save(npz_tmp)
        with _writing(rrd):
            write_recording(
                rrd_tmp, traj, robot, layout=layout, metrics=metrics, evaluation=evaluation, info=info
            )


@contextmanager
def _writing(*paths: Path) -> Iterator[None]:
    """Turn a failed write into one line naming the file (the first of ``paths`` unless the error
    names another)."""
    try:
        yield
    except OSError as e:
        named = Path(e.filename) if e.filename else None
        path = named if named in paths else paths[0]
        raise HlikError(f"{path}: cannot write ({e.strerror or e})") from None
    except RuntimeError as e:  # Rerun reports a failed write (full disk) as a RuntimeError
        raise HlikError(f"{paths[0]}: cannot write ({' '.join(str(e).split())})") from None


def _run_summary(title: str, traj, motion, solve_time: float, rrd: Path, npz: Path, ev) -> Table:
    import numpy as np

    from hlik.criteria.functional import relative_errors
    from hlik.findings import LAG, lag_spans

    fpos, fori = ev.fpos, ev.fori
    table = Table(show_header=False, box=None, title=f"{title} -> {Path(traj.robot).stem} ({traj.solver})")
    table.add_column(no_wrap=True)
    table.add_column(overflow="fold")
    table.add_row("frames", f"{traj.n_frames} over {motion.duration:.2f} s at {motion.rate:.1f} Hz")
    p = traj.placement
    table.add_row(
        "placement",
        f"{p.method}: base at ({p.translation[0]:.2f}, {p.translation[1]:.2f}, {p.translation[2]:.2f}) m, "
        f"yaw {np.degrees(p.yaw):.0f}°",
    )
    table.add_row("solve time", f"{solve_time:.2f} s ({1e3 * solve_time / traj.n_frames:.3f} ms/frame)")
    d = traj.diagnostics
    table.add_row(
        "solver",
        f"{d.n_failed} failed, {d.n_unconverged} unconverged (at the iteration cap) of "
        f"{traj.n_frames} frames; median {np.median(d.iterations):.0f} iterations/frame",
    )
    for i, side in enumerate(("left", "right")):
        table.add_row(
            f"{side} hand",
            f"fPOS mean {100 * fpos[:, i].mean():.1f} cm, max {100 * fpos[:, i].max():.1f} cm; "
            f"fORI mean {np.degrees(fori[:, i].mean()):.1f}°, max {np.degrees(fori[:, i].max()):.1f}°",
        )
    speed = ev.max_speed_ratio
    speeds = (
        f"joint speeds within their limits (at most {speed:.2f} of one)"
        if speed <= 1.0 + 1e-6
        else f"max joint speed {speed:.2f} x its limit"
    )
    table.add_row("body", f"{int(np.count_nonzero(ev.collisions))} frames in self-collision; {speeds}")
    table.add_row("controller", _controller_line(ev.controller))
    table.add_row("posture", _posture_line(ev.posture))
    lag = lag_spans(fpos, traj.times) if ev.scenario == "pose" else ""  # relative: no hand targets
    if lag:
        reason = (
            "jm maps the joints and does not track the hands"
            if traj.solver == "jm"
            else "out of reach, too fast for the speed limits, or outweighed by the criteria"
        )
        table.add_row("lagging", f"hands > {100 * LAG:.0f} cm off their targets ({reason}): {lag}")
    off_pos, off_rot = relative_errors(traj.tcp_pos, traj.tcp_rot, traj.targets.pos, traj.targets.rot)
    table.add_row(
        "hands relative",
        f"fPOS_off mean {100 * off_pos.mean():.1f} cm, fORI_off mean {np.degrees(off_rot.mean()):.1f}°",
    )
    size = lambda path: f"{path.stat().st_size / 1e6:.1f} MB"  # noqa: E731
    table.add_row("recording", f"{rrd} ({size(rrd)})")
    table.add_row("trajectory", f"{npz} ({size(npz)})")
    return table


@app.command()
def evaluate(
    trajectory: Annotated[Path, typer.Argument(help="Trajectory .npz written by `hlik run`.")],
    json_out: Annotated[
        bool, typer.Option("--json", help="Print one JSON object.", metavar=_FLAG, show_default=False)
    ] = False,
    corpus: CorpusOpt = None,
    scenario: ScenarioOpt = "pose",
    metric: MetricOpt = None,
) -> None:
    """Human-likeness criteria h_i and scores m_i, m_hl, m_f and m_hl,f of a trajectory."""
    import json

    from hlik.criteria.learned import learn
    from hlik.criteria.unified import load_metric, midpoints
    from hlik.errors import RobotError
    from hlik.metrics import evaluate as evaluate_trajectory
    from hlik.robot.model import load_robot
    from hlik.trajectory import check_robot, load_trajectory

    with _one_line():
        _check_scenario(scenario)
        unified_metric = load_metric(metric) if metric is not None else None
        traj = load_trajectory(trajectory)
        try:
            r = load_robot(traj.robot)
        except RobotError as e:
            raise HlikError(f"{trajectory}: robot: {e}") from None
        check_robot(trajectory, traj, r)
        learned = learn(r, corpus if corpus is not None else corpus_setting()[0])
        ev = evaluate_trajectory(traj, r, learned, scenario=scenario, metric=unified_metric)
    _warn(learned.notes)
    if json_out:
        sys.stdout.write(json.dumps(ev.to_json(), indent=2) + "\n")
        return
    x0 = midpoints(scenario, ev.metric)
    title = f"{trajectory.name}: {Path(traj.robot).stem}, {traj.solver}; weights and x0: {ev.metric.source}"
    table = Table("criterion", "mean h", "x0", "m", title=title)
    for k in x0:
        table.add_row(k, f"{ev.h[k].mean():.4g}", f"{x0[k]:g}", f"{ev.m[k]:.3f}")
    console.print(table)
    console.print(f"m_hl = {ev.m_hl:.3f}   m_f ({scenario}) = {ev.m_f:.3f}   m_hl,f = {ev.m_hl_f:.3f}")


@app.command()
def learn(
    robots: Annotated[list[str] | None, typer.Argument(help="Robot names (default: all).")] = None,
    corpus: CorpusOpt = None,
) -> None:
    """Fit (or load from the cache) synergies, the swivel regressor and lambda_R; print what was learned."""
    import numpy as np

    from hlik.criteria.learned import learn as learn_robot
    from hlik.paths import cache_dir
    from hlik.robot.model import available_robots, load_robot

    paper = {"armar3": 7.25, "armar6": 8.76, "dual_panda": 4.7}
    table = Table("robot", "corpus", "PCA var. (5)", "1st-order var. (5)", "Psi rms", "lambda_R", "paper")
    with _one_line():
        corpus = corpus if corpus is not None else corpus_setting()[0]
        for name in robots or available_robots():
            r = load_robot(name)
            with _counting(f"learning {name}'s criteria from the corpus") as progress:
                lrn = learn_robot(r, corpus, progress=progress)
            _warn(lrn.notes)
            table.add_row(
                r.name,
                f"{len(lrn.corpus)} files",
                f"{100 * lrn.synergies.explained.sum():.1f} %",
                f"{100 * lrn.synergies.vel_explained.sum():.1f} %",
                f"{np.degrees(lrn.swivel_rms):.1f}°",
                f"{lrn.scale:.2f}",
                f"{paper.get(r.name, float('nan')):g}",
            )
        folder = cache_dir()
    console.print(table)
    console.print(f"cache: {folder}")


def _progress(spinner: bool = False):
    """A transient bar on stderr (none when stderr is no terminal): description, bar, k/n, time."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
    )

    columns = (TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn())
    return Progress(
        *([SpinnerColumn()] if spinner else []),
        *columns,
        TimeElapsedColumn(),
        console=Console(stderr=True),
        transient=True,
        disable=not sys.stderr.isatty(),
    )


@contextmanager
def _counting(description: str) -> Iterator[Callable[[int, int], None]]:
    """A ``progress(k, n)`` callback drawing a transient bar on stderr while the block runs."""
    with _progress() as bar:
        task = bar.add_task(description, total=None)
        yield lambda k, n: bar.update(task, completed=k, total=n)


def _check_scenario(scenario: str) -> None:
    from hlik.criteria.unified import FUNCTIONAL_X0

    if scenario not in FUNCTIONAL_X0:
        raise HlikError(f"unknown scenario {scenario!r}; choose one of: {', '.join(FUNCTIONAL_X0)}")


@app.command()
def study(
    takes: Annotated[
        Path | None,
        typer.Argument(
            help="Folder of MMM takes (default: ../shared/motion_data/kit_bimanual if present, "
            "else the bundled demo).",
            show_default=False,
        ),
    ] = None,
    robots: Annotated[str, typer.Option(help="Robots, comma-separated.")] = "armar3,armar6,dual_panda",
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder (cells, metric, report).")] = Path(
        "study"
    ),
    approaches: Annotated[
        Path | None,
        typer.Option(
            help="Approach file, or a bundled one: paper (the default, the paper's 53) or quick (JM and "
            "QP, minutes).",
            show_default=False,
        ),
    ] = None,
    seconds: Annotated[
        float | None,
        typer.Option(
            help="Retarget this many seconds of each take, after the first (default: all).",
            show_default=False,
        ),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(
            help="Parallel Ray workers (default: all cores; 1: in this process).", show_default=False
        ),
    ] = None,
    address: Annotated[
        str | None, typer.Option(help="Join this Ray cluster (e.g. ray://host:10001).", show_default=False)
    ] = None,
    corpus: CorpusOpt = None,
) -> None:
    """The paper's study: retarget, correlate the criteria, derive the metric, rank the approaches."""
    from hlik.robot.model import robot_toml
    from hlik.study.approaches import PAPER, load_approaches
    from hlik.study.runner import plan, run_study

    folder = takes or _default_takes()
    with _one_line():
        if seconds is not None and not (math.isfinite(seconds) and seconds > 0):
            raise HlikError(f"--seconds must be positive and finite, got {seconds:g}")
        if workers is not None and workers < 1:
            raise HlikError(f"--workers must be at least 1, got {workers}")
        files = (
            sorted(f for pattern in MOTION_FILES for f in folder.glob(pattern))
            if folder.is_dir()
            else [folder]
        )
        if not files or not all(f.is_file() for f in files):
            raise HlikError(f"{folder}: no takes ({', '.join(MOTION_FILES)})")
        names = [r.strip() for r in robots.split(",") if r.strip()]
        if not names:
            raise HlikError(f"unknown robot {robots!r}; see `hlik robots`")
        for name in names:
            robot_toml(name)  # a bundled name or a path of a .toml; the message lists the known ones
        listed = load_approaches(approaches or PAPER)
        n_cells = len(plan(files, names, listed, seconds))
        console.print(
            f"study: {len(files)} takes x {len(names)} robots x {len(listed)} approaches = "
            f"{n_cells} cells -> {out}/"
        )
        with _progress() as progress:
            task = progress.add_task("cells", total=n_cells)
            advance = lambda o: progress.update(task, advance=1, description=o.cell.file_name[:48])  # noqa: E731
            corpus = corpus if corpus is not None else corpus_setting()[0]
            result = run_study(files, names, listed, out, seconds, workers, address, advance, corpus)
    failed = [o for o in result.outcomes if o.error]
    for o in failed:
        console.print(Text.assemble(("failed", "yellow"), f" {o.cell.file_name}: {o.error}"), highlight=False)
    for ranking in result.rankings:
        table = Table(
            "approach", "m_hl", "m_f", "m_hl,f", title=f"best approaches, {ranking.scenario} scenario"
        )
        for r in ranking.rows[:5]:
            table.add_row(r["approach"], f"{r['m_hl']:.3f}", f"{r['m_f']:.3f}", f"{r['m_hl_f']:.3f}")
        console.print(table)
    reused = sum(o.reused for o in result.outcomes)
    console.print(
        f"{len(result.outcomes)} cells ({reused} reused, {len(failed)} failed) in "
        f"{result.wall_seconds:.0f} s; metric: {result.metric_file} (hlik run/evaluate --metric); "
        f"report: {result.report}"
    )


def _default_takes() -> Path:
    """The shared KIT takes beside the checkout (or under HLIK_DATA), else the bundled demo."""
    data = os.environ.get("HLIK_DATA")
    candidates = [Path(data) / "kit_bimanual"] if data else []
    candidates.append(Path.cwd().parent / "shared" / "motion_data" / "kit_bimanual")
    return next((c for c in candidates if c.is_dir()), demo_motion_path())


@app.command()
def robots() -> None:
    """List the bundled robots with their degrees of freedom."""
    from hlik.robot.summary import robot_summaries

    table = Table("name", "robot", "DoF", "arms", "extra joints", "unlimited")
    with _one_line():
        summaries = robot_summaries()
    for r in summaries:
        arms = " + ".join(map(str, r.arms))
        table.add_row(r.name, r.title, str(r.dof), arms, ", ".join(r.extra_joints) or "-", str(r.unlimited))
    console.print(table)


@app.command()
def info(motion: MotionArg = None) -> None:
    """Summarise a motion file: subject, duration, rate, joints, markers, objects."""
    from hlik.human.load import load_motion

    path = motion or demo_motion_path()
    with _one_line():
        m = load_motion(path)
    _warn(m.notes)
    table = Table(show_header=False, box=None)
    table.add_column(no_wrap=True)
    table.add_column(overflow="fold")
    table.add_row("file", str(path))
    table.add_row("motion", m.name)
    table.add_row("subject", f"{m.height:.2f} m" + (f", {m.mass:g} kg" if m.mass else ""))
    table.add_row("frames", f"{m.n_frames} over {m.duration:.2f} s at {m.rate:.1f} Hz")
    arm = [n for n in m.joint_names if n[:2] in ("LS", "LE", "LW", "RS", "RE", "RW")]
    table.add_row("joints", f"{len(m.joint_names)} ({len(arm)} arm)")
    table.add_row(
        "markers", f"{len(m.markers)}" + (f": {', '.join(sorted(m.markers)[:8])} ..." if m.markers else "")
    )
    table.add_row("objects", ", ".join(m.objects) or "-")
    console.print(table)


@app.command()
def calibrate(
    robot: Annotated[str, typer.Argument(help="Robot name (see `hlik robots`) or path of a robot .toml.")],
    toml: Annotated[
        bool,
        typer.Option("--toml", help="Print the mapping tables as TOML.", metavar=_FLAG, show_default=False),
    ] = False,
    write: Annotated[
        bool,
        typer.Option(
            "--write",
            help="Write the mapping tables into the robot's .toml (replacing [mapping.*]).",
            metavar=_FLAG,
            show_default=False,
        ),
    ] = False,
) -> None:
    """Derive the MMM -> robot joint mapping (paper Sec. III-A) and print it."""
    import numpy as np

    from hlik.robot.calibrate import calibrate as run_calibration
    from hlik.robot.calibrate import mapping_toml, write_mapping
    from hlik.robot.model import load_robot

    with _one_line():
        r = load_robot(robot, need_mapping=False)
    cal = run_calibration(r)
    if toml:
        sys.stdout.write(mapping_toml(r, cal.mapping))
        return
    if write:
        assert r.description is not None  # load_robot always names the file it read
        write_mapping(r.description, mapping_toml(r, cal.mapping))
        console.print(f"wrote [mapping.left] and [mapping.right] to {r.description}")
        return
    table = Table(
        "robot joint",
        "MMM joint",
        "a",
        "b (rad)",
        "dynamic offset",
        "match",
        title=f"{r.title}: q_robot = a·q_mmm + b (+ offset)",
    )
    for m in cal.mapping.joints:
        off = f"{m.offset.gain:+.4f}·{m.offset.mmm}" if m.offset else ""
        table.add_row(
            m.joint,
            m.mmm or "(held)",
            f"{m.a:+.0f}",
            f"{m.b:+.4f} ({m.b / np.pi:+.3f}π)",
            off,
            f"{cal.score[m.joint]:.2f}",
        )
    console.print(table)
    res = ", ".join(f"{s} {np.degrees(v):.1f}°" for s, v in cal.residual.items())
    console.print(f"hand-frame error of the mapped default pose: {res}")
    offsets = [(m.joint, m.offset) for m in cal.mapping.joints if m.offset is not None]
    if offsets:
        found = ", ".join(f"{joint} {off.gain:+.3f}·{off.mmm}" for joint, off in offsets)
        console.print(f"dynamic offsets: {found} (paper, ARMAR-6 Sho2: +{0.55 / np.pi:.3f}·s_x)")
    stored = {m.joint: m for m in r.mapping.joints}
    same = all(_close(stored.get(m.joint), m) for m in cal.mapping.joints)
    where = f"robots/{r.name}.toml" if r.reference == r.name else r.description
    console.print(
        f"matches {where}"
        if same
        else Text.assemble((f"differs from {where}", "yellow"), " (print with --toml, store with --write)")
    )


def _close(a: JointMap | None, b: JointMap) -> bool:
    """Same joint mapping up to the printed precision (1e-3 rad, 1e-3 gain)."""
    if a is None:
        return False
    if (a.mmm != b.mmm and not a.a == 0 == b.a) or a.a != b.a or abs(a.b - b.b) >= 1e-3:
        return False
    if a.offset is None or b.offset is None:
        return a.offset is None and b.offset is None
    return a.offset.mmm == b.offset.mmm and abs(a.offset.gain - b.offset.gain) < 1e-3


def main() -> None:  # pragma: no cover
    app()


if __name__ == "__main__":  # python -m hlik.cli
    main()
