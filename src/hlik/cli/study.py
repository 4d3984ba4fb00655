"""``hlik study``: the paper's study over takes, robots and approaches."""

from __future__ import annotations

import math
import signal
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table
from rich.text import Text

from hlik.cli.app import (
    MOTION_FILES,
    TERMINATED,
    CorpusOpt,
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
from hlik.util.errors import HlikError
from hlik.util.paths import demo_motion_path, shared_takes

if TYPE_CHECKING:
    from hlik.study.runner import StudyResult


TakesArg = Annotated[
    Path | None,
    typer.Argument(
        help="Folder of MMM takes (default: ../shared/motion_data/kit_bimanual beside the working "
        "folder or the checkout, if present, "
        "else the bundled demo).",
        show_default=False,
    ),
]
RobotsOpt = Annotated[str, typer.Option(help="Robots, comma-separated.")]
FolderOpt = Annotated[Path, typer.Option("--out", "-o", help="Output folder (cells, metric, report).")]
ApproachesOpt = Annotated[
    Path | None,
    typer.Option(
        help="Approach file, or a bundled one: paper (the default, the paper's 53) or quick (JM and "
        "QP, minutes).",
        show_default=False,
    ),
]
SecondsOpt = Annotated[
    float | None,
    typer.Option(
        help="Retarget this many seconds of each take, after the first (default: all).", show_default=False
    ),
]
WorkersOpt = Annotated[
    int | None,
    typer.Option(help="Parallel Ray workers (default: all cores; 1: in this process).", show_default=False),
]
AddressOpt = Annotated[
    str | None, typer.Option(help="Join this Ray cluster (e.g. ray://host:10001).", show_default=False)
]


def study(
    takes: TakesArg = None,
    robots: RobotsOpt = "armar3,armar6,dual_panda",
    out: FolderOpt = Path("study"),
    approaches: ApproachesOpt = None,
    seconds: SecondsOpt = None,
    workers: WorkersOpt = None,
    address: AddressOpt = None,
    corpus: CorpusOpt = None,
) -> None:
    """The paper's study: retarget, correlate the criteria, derive the metric, rank the approaches."""
    from hlik.robot.files import robot_toml

    folder = takes or _default_takes()
    with one_line():
        if seconds is not None and not (math.isfinite(seconds) and seconds > 0):
            raise HlikError(f"--seconds must be positive and finite, got {seconds:g}")
        if workers is not None and workers < 1:
            raise HlikError(f"--workers must be at least 1, got {workers}")
        files = _takes(folder)
        names = [r.strip() for r in robots.split(",") if r.strip()]
        if not names:
            raise HlikError(f"unknown robot {robots!r}; see `hlik robots`")
        for name in names:
            robot_toml(name)  # a bundled name or a path of a .toml; the message lists the known ones
        from hlik.study.approaches import PAPER, load_approaches
        from hlik.study.runner import plan, run_study

        listed = load_approaches(approaches or PAPER)
        n_cells = len(plan(files, names, listed, seconds))
        console.print(
            f"study: {_count(files, 'take')} x {_count(names, 'robot')} x {_count(listed, 'approach')} = "
            f"{_count(range(n_cells), 'cell')} -> {out}/",
            soft_wrap=True,  # a path is never broken across lines
        )
        with progress_bar() as progress:
            task = progress.add_task("cells", total=n_cells)
            advance = lambda o: progress.update(task, advance=1, description=_cell_name(o.cell))  # noqa: E731
            corpus = resolve_corpus(corpus)[0]  # --corpus demo: the bundled demo
            try:
                result = run_study(files, names, listed, out, seconds, workers, address, advance, corpus)
            except (KeyboardInterrupt, SystemExit) as e:
                _stopped(e, out, n_cells)
                raise
    _report(result)


def _stopped(stop: BaseException, out: Path, n_cells: int) -> None:
    """Say what a study stopped by Ctrl-C or SIGTERM kept: the finished cells (each written whole),
    which the same command reuses; before, SIGTERM ended it silently and Ctrl-C said "nothing
    written" over the kept cells."""
    code = stopped_by(stop)
    if code is None:
        return
    how = "terminated" if code == TERMINATED else "interrupted"
    kept = len(list((out / "cells").glob("*.parquet"))) if (out / "cells").is_dir() else 0
    print_error(
        f"{how}: {kept} of {n_cells} cells kept in {out / 'cells'}; run the same command to resume "
        "(no metric or report written)"
    )
    if threading.current_thread() is threading.main_thread():
        # said and decided: a Ctrl-C delivered late (one held back while a cell was written) must
        # not turn this exit into death by SIGINT (exit -2 instead of 130, seen once in CI)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    raise Said(code) from None


def _takes(folder: Path) -> list[Path]:
    """The motion files of ``folder`` (or ``folder`` itself, a file).

    Raises:
        HlikError: none there, or one that is no file.
    """
    files = (
        sorted(f for pattern in MOTION_FILES for f in folder.glob(pattern)) if folder.is_dir() else [folder]
    )
    if not files or not all(f.is_file() for f in files):
        raise HlikError(f"{folder}: no takes ({', '.join(MOTION_FILES)})")
    return files


def _report(result: StudyResult) -> None:
    """The failed cells, the five best approaches per scenario and where the files are; a warning
    where the rankings or the metric rest on less than a finding needs."""
    from hlik.study.report import MIN_CELLS, MIN_FRAMES, MIN_TAKES

    failed = [o for o in result.outcomes if o.error]
    for o in failed:
        console.print(
            Text.assemble(("failed", "yellow"), f" {o.cell.file_name}: {o.error}"),
            highlight=False,
            soft_wrap=True,
        )
    small = []
    for ranking in result.rankings:
        title = f"best approaches, {ranking.scenario} scenario"
        table = Table("approach", "m_hl", "m_f", "m_hl,f", "cells", title=title)
        for r in ranking.rows[:5]:
            row = (f"{r['m_hl']:.3f}", f"{r['m_f']:.3f}", f"{r['m_hl_f']:.3f}", str(r["cells"]))
            table.add_row(r["approach"], *row)
        print_table(table)
        fewest = min((int(r["cells"]) for r in ranking.rows), default=0)
        if fewest < MIN_CELLS:
            small.append(
                f"the {ranking.scenario} ranking rests on {fewest} cell(s) per approach (a finding needs "
                f"{MIN_CELLS}): an order, not a result"
            )
    corr = result.correlation
    if corr.takes < MIN_TAKES or corr.frames < MIN_FRAMES:
        small.append(
            f"{result.metric_file} comes from {corr.takes} take(s), {corr.frames} frames (a finding needs "
            f"{MIN_TAKES} takes and {MIN_FRAMES} frames): a try of the pipeline, not a metric to score with"
        )
    reused = sum(o.reused for o in result.outcomes)
    warn([*result.notes, *small])
    if failed:
        warn(
            [
                f"{result.metric_file} and the rankings come from {len(result.outcomes) - len(failed)} of "
                f"{len(result.outcomes)} cells: {len(failed)} failed (listed above); run again to retry them"
            ]
        )
    console.print(
        f"{len(result.outcomes)} cells ({reused} reused, {len(failed)} failed) in "
        f"{result.wall_seconds:.0f} s; metric: {result.metric_file} (hlik run/evaluate --metric); "
        f"report: {result.report}",
        soft_wrap=True,
    )


def _default_takes() -> Path:
    """The shared KIT takes beside the checkout (or under HLIK_DATA), else the bundled demo."""
    return shared_takes() or demo_motion_path()


def _count(items, noun: str) -> str:
    """``"1 robot"``, ``"3 robots"``, ``"2 approaches"``."""
    n = len(items)
    return f"{n} {noun}" if n == 1 else f"{n} {noun}{'es' if noun.endswith('ch') else 's'}"


def _cell_name(cell) -> str:
    """A finished cell as the progress line shows it: robot and approach whole, the take cut short."""
    take = cell.take.stem if len(cell.take.stem) <= 24 else cell.take.stem[:23] + "…"
    return f"{take} {Path(cell.robot).stem} {cell.approach.key}"
