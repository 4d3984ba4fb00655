"""The command line's application, console, shared options and error handling: bad input ends
in one line on stderr and exit code 2."""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console
from rich.text import Text
from typer.core import TyperGroup

from hlik.util.atomic import raising_on_sigterm
from hlik.util.errors import HlikError

if TYPE_CHECKING:  # imported where used: `hlik --help` stays quick
    from hlik.robot.model import Robot
    from hlik.trajectory import Trajectory

FLAG = ""  # metavar of an on/off option: typer would show it as `--json <bool>`, taking a value


def warn(notes) -> None:
    """``warning: <note>`` on one line of stderr for each note (text, never markup)."""
    err = Console(stderr=True, soft_wrap=True, highlight=False)
    for note in notes:
        err.print(Text.assemble(("warning:", "yellow"), " ", " ".join(str(note).split())))


def print_error(message: str) -> None:
    """``error: <message>`` on one line of stderr; the message is text, never markup ("[qp]")."""
    text = Text.assemble(("error:", "red"), " ", " ".join(message.split()))
    Console(stderr=True, soft_wrap=True, highlight=False).print(text)


INTERRUPTED = 130  # exit code of a command ended by Ctrl-C (128 + SIGINT)
TERMINATED = 143  # exit code of a command ended by SIGTERM (hlik.util.atomic.Termination)


def stopped_by(stop: BaseException) -> int | None:
    """The exit code of the Ctrl-C (:data:`INTERRUPTED`) or SIGTERM (:data:`TERMINATED`) that
    ``stop`` is (a ``KeyboardInterrupt``, or the ``SystemExit`` SIGTERM's handler raises), else None."""
    if isinstance(stop, KeyboardInterrupt):
        return INTERRUPTED
    code = stop.code if isinstance(stop, SystemExit) else None
    return code if code in (INTERRUPTED, TERMINATED) else None


class Said(SystemExit):
    """A command's exit by Ctrl-C or SIGTERM that it has already explained in its own line (a
    study's kept cells): :class:`_OneLineErrors` adds none."""


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
                print_error(f"{e.format_message()}{see}")
            result = 2
        except typer.Abort:  # end of input at a prompt
            print_error("aborted")
            result = 1
        except SystemExit as stop:  # SIGTERM (raising_on_sigterm): the temporaries are gone by now
            if stop.code == TERMINATED and not isinstance(stop, Said):
                print_error("terminated; nothing written")
            raise
        if result == INTERRUPTED:  # typer turns Ctrl-C into this exit code, silently
            print_error("interrupted; nothing written")
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


def print_table(table) -> None:
    """A table on stdout: laid out to the terminal's width there; piped, each row on one line with
    no padding after it, so that a path or a command is never broken and ``grep`` finds a row. A
    title is its own line above (rich wraps one to the table's width, mid-name)."""
    if table.title:
        console.print(str(table.title), soft_wrap=True, markup=False, highlight=False)
        table.title = None
    if console.is_terminal:
        console.print(table)
        return
    wide = Console(markup=False, width=100_000, color_system=None, highlight=False)
    with wide.capture() as captured:
        wide.print(table)
    console.file.write("".join(f"{line.rstrip()}\n" for line in captured.get().splitlines()))


MotionArg = Annotated[
    Path | None,
    typer.Argument(
        help="Motion: MMM .xml, .bvh or a keypoint .toml (default: the bundled demo).", show_default=False
    ),
]

CorpusOpt = Annotated[
    Path | None,
    typer.Option(
        help="Folder of MMM motions to learn synergies and the swivel regressor from, or demo (the "
        'bundled synthetic demo). Default: $HLIK_CORPUS, else corpus = "DIR" in ./hlik.toml, else the '
        "corpus the learn command remembered (~/.config/hlik/config.toml), else the shared KIT takes "
        "(../shared/motion_data/kit_bimanual beside the working folder or the checkout, or $HLIK_DATA), "
        "else the demo (warned).",
        show_default=False,
    ),
]
# The line said whenever criteria or scores come from the synthetic demo for want of a corpus
# (not where --corpus demo or HLIK_CORPUS=demo chose it).
DEMO_CORPUS_WARNING = (
    "criteria learned from the bundled demo, a 12 s pour and wipe authored here, not recorded: "
    "the synergies, swivel regressor and lambda_R of SYN, MIS, EEA, SYN_r, EEA_r and MAN_r are not a "
    "person's; learn them from recorded takes once with `hlik learn --corpus DIR`"
)


def resolve_corpus(corpus: Path | None) -> tuple[Path | None, str]:
    """The corpus folder of a command's ``--corpus`` (``demo``: None, the bundled demo), else the
    configured one (:func:`hlik.util.paths.corpus_setting`), and where it came from."""
    from hlik.util.paths import DEMO, corpus_setting

    if corpus is not None:
        return (None, "--corpus") if str(corpus) == DEMO else (corpus, "--corpus")
    return corpus_setting()


MetricOpt = Annotated[
    Path | None,
    typer.Option(
        help="Weights and x0 of m_hl from a TOML file (e.g. study/metric.toml of `hlik study`); "
        "default: the paper's Table III.",
        show_default=False,
    ),
]


def fail(err: HlikError) -> None:
    print_error(str(err))
    raise typer.Exit(2)


@contextmanager
def one_line() -> Iterator[None]:
    """Bad input and failed reads or writes end the command with one line and exit code 2."""
    try:
        yield
    except HlikError as e:
        fail(e)
    except OSError as e:  # what the readers do not name themselves (permission, full disk)
        where = f"{e.filename}: " if e.filename else ""
        fail(HlikError(f"{where}{e.strerror or e}"))


def check_trajectory_file(path: Path) -> None:
    """Refuse a missing or unreadable trajectory before the heavy imports (one line, in a
    fraction of a second).

    Raises:
        TrajectoryFormatError: no such file, a folder, or unreadable.
    """
    from hlik.util.errors import TrajectoryFormatError
    from hlik.util.files import check_readable

    check_readable(
        path, lambda problem: TrajectoryFormatError(f"{path}: {problem}"), "a trajectory .npz file"
    )


def trajectory_and_robot(path: Path) -> tuple[Trajectory, Robot]:
    """The trajectory ``path`` and the robot it names, checked to be that robot's.

    Raises:
        HlikError: the file cannot be read, its robot cannot be loaded (named as the file's), or
            its joints are not the robot's.
    """
    from hlik.robot.model import load_robot
    from hlik.trajectory import check_robot, load_trajectory
    from hlik.util.errors import RobotError

    traj = load_trajectory(path)
    try:
        robot = load_robot(traj.robot)
    except RobotError as e:
        raise HlikError(f"{path}: robot: {e}") from None
    check_robot(path, traj, robot)
    return traj, robot


class _PlainProgress:
    """Progress for a stderr that is no terminal (piped, logged): a plain line ``hlik: STAGE (k/n,
    T s)`` once a stage has run :data:`QUIET_FOR` seconds, then every :data:`EVERY` seconds, so
    that a cold cache (a reachability map sampled, criteria learned) is not a silent minute, while
    quick stages and errors print nothing more. A ticker thread says it: a stage that reports no
    count (reading, learning) is heard too."""

    QUIET_FOR, EVERY = 2.0, 10.0

    def __init__(self) -> None:
        self.tasks: dict[int, dict[str, Any]] = {}
        self._done, self._lock = threading.Event(), threading.Lock()
        self._ticker = threading.Thread(target=self._tick, name="hlik-progress", daemon=True)

    def __enter__(self) -> _PlainProgress:
        self._ticker.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._ticker.join()

    def add_task(self, description: str, total: float | None = None, **_: object) -> int:
        with self._lock:
            task = len(self.tasks)
            self.tasks[task] = {"description": description, "total": total, "completed": 0} | self._fresh()
        return task

    def _fresh(self) -> dict[str, float]:
        now = time.monotonic()
        return {"since": now, "said": now - self.EVERY + self.QUIET_FOR}

    def update(self, task: int, advance: float | None = None, **fields: Any) -> None:
        with self._lock:
            state = self.tasks[task]
            if "description" in fields and fields["description"] != state["description"]:
                state |= self._fresh()
            state.update({k: v for k, v in fields.items() if k in ("description", "total", "completed")})
            if advance:
                state["completed"] = (state["completed"] or 0) + advance

    def _tick(self) -> None:
        while not self._done.wait(0.25):
            with self._lock:
                now = time.monotonic()
                due = [state for state in self.tasks.values() if now - state["said"] >= self.EVERY]
                for state in due:
                    state["said"] = now
                lines = [self._line(state, now) for state in due]
            for line in lines:
                Console(stderr=True, soft_wrap=True, highlight=False, markup=False).print(line)

    @staticmethod
    def _line(state: dict[str, Any], now: float) -> str:
        count = f"{int(state['completed'] or 0)}/{int(state['total'])}, " if state["total"] else ""
        return f"hlik: {state['description']} ({count}{now - state['since']:.0f} s)"


def progress_bar(spinner: bool = False):
    """A transient bar on stderr: description, bar, k/n, time; plain lines for a long stage where
    stderr is no terminal (:class:`_PlainProgress`)."""
    if not sys.stderr.isatty():
        return _PlainProgress()
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
    )


@contextmanager
def counting(description: str) -> Iterator[Callable[[int, int], None]]:
    """A ``progress(k, n)`` callback drawing a transient bar on stderr while the block runs."""
    with progress_bar() as bar:
        task = bar.add_task(description, total=None)
        yield lambda k, n: bar.update(task, completed=k, total=n)
