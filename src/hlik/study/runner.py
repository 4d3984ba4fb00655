"""Run a study: every cell (take x robot x approach) not on disk yet, in-process or as Ray tasks,
then the analysis and the report. A failed cell is listed, never fatal."""

from __future__ import annotations

import functools
import logging
import os
import signal
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hlik.criteria.learned import learn
from hlik.criteria.unified import Metric
from hlik.problem.placement import placement_from_spec
from hlik.robot.model import load_robot
from hlik.robot.reachability import reachability_map
from hlik.study.analysis import Correlation, Ranking, correlate, correlation_frames, derive_metric, rank
from hlik.study.approaches import Approach
from hlik.study.dataset import Cell, cell_motion, read_dataset, run_cell, write_cell
from hlik.study.reaper import start_reaper
from hlik.study.report import write_report
from hlik.util.atomic import atomic_path
from hlik.util.errors import HlikError


@dataclass(frozen=True)
class CellOutcome:
    """What became of one cell: its file, or the one-line error; CPU seconds spent."""

    cell: Cell
    path: Path | None
    error: str | None
    seconds: float
    reused: bool = False


@functools.cache
def _robot(name: str, corpus: Path | None = None):
    # per process: the model and its learned pieces are read from the disk cache once
    robot = load_robot(name)
    return robot, learn(robot, corpus)


@functools.lru_cache(maxsize=4)
def _scene(take: Path, seconds: float | None, rate: float, robot_name: str, corpus: Path | None = None):
    # per process: the motion and the placement every approach of a take and robot shares (the
    # placement by reachability costs 1.3-1.5 s, more than most cells); plan() groups the cells so
    robot = _robot(robot_name, corpus)[0]
    motion = cell_motion(take, seconds, rate, robot)
    return motion, placement_from_spec(robot.placement, robot, motion)


def solve_cell(cell: Cell, folder: Path) -> CellOutcome:
    """Run one cell and write its file into ``folder``; any error becomes the outcome's message."""
    start = time.process_time()
    try:
        robot, learned = _robot(cell.robot, cell.corpus)
        motion, placement = _scene(cell.take, cell.seconds, cell.rate, cell.robot, cell.corpus)
        path = write_cell(run_cell(cell, robot, learned, motion, placement), folder / cell.file_name)
        return CellOutcome(cell, path, None, time.process_time() - start)
    except Exception as e:  # noqa: BLE001 - a study outlives one bad cell; the message is reported
        line = f"{type(e).__name__}: {e}".splitlines()[0]
        where = traceback.extract_tb(e.__traceback__)[-1]
        return CellOutcome(cell, None, f"{line} ({Path(where.filename).name}:{where.lineno})", 0.0)


def plan(
    takes: Sequence[Path],
    robots: Sequence[str],
    approaches: Sequence[Approach],
    seconds: float | None,
    corpus: Path | None = None,
) -> list[Cell]:
    """Every cell of the study, robots outermost."""
    return [Cell(Path(t), r, a, seconds, corpus=corpus) for r in robots for t in takes for a in approaches]


def prepare(robots: Sequence[str], corpus: Path | None = None) -> None:
    """Compute (or load) each robot's learned pieces and reachability map into the disk cache once,
    before the workers start, so that none of them computes its own."""
    for name in robots:
        robot, _ = _robot(name, corpus)
        if robot.placement == "reach":
            reachability_map(robot)


def run_cells(
    cells: Sequence[Cell],
    folder: Path,
    workers: int | None = None,
    address: str | None = None,
    progress: Callable[[CellOutcome], None] | None = None,
    notes: list[str] | None = None,
) -> list[CellOutcome]:
    """Run the cells whose file is missing in ``folder`` (the others are reused).

    ``workers``: 1 runs in this process; more (default: all cores) run Ray tasks on a local Ray
    (``address``: join that cluster instead), or in this process if Ray is not installed.
    """
    folder.mkdir(parents=True, exist_ok=True)
    done = [
        CellOutcome(c, folder / c.file_name, None, 0.0, True)
        for c in cells
        if (folder / c.file_name).exists()
    ]
    todo = [c for c in cells if not (folder / c.file_name).exists()]
    for outcome in done:
        if progress:
            progress(outcome)
    ray = _ray(workers, address, notes if notes is not None else []) if todo else None
    outcomes = list(done)
    if ray is None:
        for cell in todo:
            outcomes.append(solve_cell(cell, folder))
            if progress:
                progress(outcomes[-1])
        return outcomes
    try:
        with _signals_through_ray():
            task = ray.remote(solve_cell)
            pending = [task.remote(cell, folder) for cell in todo]
            while pending:
                ready, pending = ray.wait(pending, num_returns=1)
                outcomes.append(ray.get(ready[0]))
                if progress:
                    progress(outcomes[-1])
    finally:  # also on Ctrl-C and SIGTERM: the local cluster's processes end with the study
        ray.shutdown()
    return outcomes


def _ray(workers: int | None, address: str | None, notes: list[str]):
    """Ray, initialised for ``workers`` CPUs (or joined to ``address``); None to run in-process
    (``workers`` 1, Ray not installed, or a local Ray that did not start: said in ``notes``).

    Raises:
        HlikError: the cluster at ``address`` cannot be joined (one line, with what to set).
    """
    if workers == 1 and address is None:
        return None
    if address:
        _token_auth()  # read by Ray when it is imported
    try:
        import ray
    except ImportError:
        return None
    if not ray.is_initialized():
        src = str(Path(__file__).resolve().parents[2])  # workers import hlik from the same checkout
        env = {"env_vars": {"PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}}
        # hlik prints its own progress; Ray's start-up INFO and WARNING lines would break the bar
        quiet: dict[str, Any] = {"runtime_env": env, "log_to_driver": False, "logging_level": logging.ERROR}
        # Ray's core worker installs C++ handlers that answer SIGTERM (and SIGINT) with a stack dump
        # and abort (exit -6): keep hlik's, which end the study through its finally blocks.
        handlers = _stop_handlers()
        said: list[str] = []
        try:
            if address:
                with _native_stderr(said):
                    ray.init(address=address, **quiet)
            else:
                start_reaper()  # Ray's agents outlive a killed study otherwise (study/reaper.py)
                with _native_stderr(said):
                    ray.init(num_cpus=workers or os.cpu_count(), include_dashboard=False, **quiet)
        except Exception as e:  # Ray raises ConnectionError, RuntimeError, TimeoutError, ...
            why = _one_line(str(e) or type(e).__name__)
            if address:
                raise HlikError(
                    f"--address {address}: cannot join the Ray cluster: {why}{_auth_hint(said)}"
                ) from None
            notes.append(f"Ray did not start ({why}): the cells run in this process")
            return None
        finally:
            for signum, handler in handlers.items():
                signal.signal(signum, handler)
    return ray


def _token_auth() -> None:
    """Join a cluster started with token authentication (``ray start --head`` does by default since
    Ray 2.59) as Ray documents: ``RAY_AUTH_MODE=token`` where a token is at hand (``RAY_AUTH_TOKEN``,
    ``RAY_AUTH_TOKEN_PATH`` or ``~/.ray/auth_token``), unless the user set the mode."""
    if "RAY_AUTH_MODE" in os.environ:
        return
    paths = [os.environ.get("RAY_AUTH_TOKEN_PATH", ""), str(Path.home() / ".ray" / "auth_token")]
    if os.environ.get("RAY_AUTH_TOKEN") or any(p and Path(p).is_file() for p in paths):
        os.environ["RAY_AUTH_MODE"] = "token"


def _auth_hint(said: list[str]) -> str:
    """What to set, where Ray's own log said the token was missing or wrong."""
    if any("Unauthenticated" in line or "InvalidAuthToken" in line for line in said):
        return (
            "; the cluster wants its token: set RAY_AUTH_MODE=token and RAY_AUTH_TOKEN (or put it in "
            "~/.ray/auth_token; `ray get-auth-token` on the head node prints it)"
        )
    return ""


def _one_line(text: str) -> str:
    return " ".join(text.split())[:300]


@contextmanager
def _native_stderr(said: list[str]) -> Iterator[None]:
    """Ray's C++ core logs to file descriptor 2 while it connects (a line a second, for 20 s, when a
    token is missing): keep those lines from the terminal, read into ``said`` when the block ends
    (for the one-line error)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as log:
        os.dup2(log.fileno(), 2)
        try:
            yield
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            log.seek(0)
            said += log.read().decode(errors="replace").splitlines()


@contextmanager
def _signals_through_ray() -> Iterator[None]:
    """Ctrl-C and SIGTERM end the study as they end any command (KeyboardInterrupt, exit 130; hlik's
    SIGTERM exit, 143): Ray turns whatever a signal handler raises inside ``ray.wait`` into
    ``SystemExit(1)``, so the signal is remembered and its own handler called again outside."""
    handlers = _stop_handlers()
    came: list[int] = []

    def remember(signum: int, frame: Any) -> None:
        came.append(signum)
        handlers[signum](signum, frame)

    for signum, handler in handlers.items():
        if callable(handler):
            signal.signal(signum, remember)
    try:
        yield
    except SystemExit:
        if came and callable(handlers[came[0]]):
            handlers[came[0]](came[0], None)
        raise
    finally:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)


def _stop_handlers() -> dict[int, Any]:
    """The Python handlers of SIGINT and SIGTERM (main thread only; none elsewhere)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {s: h for s in (signal.SIGINT, signal.SIGTERM) if (h := signal.getsignal(s)) is not None}


@dataclass(frozen=True)
class StudyResult:
    """A finished study: every cell's outcome, the analysis and where the report is."""

    outcomes: tuple[CellOutcome, ...]
    correlation: Correlation
    metric: Metric
    rankings: tuple[Ranking, ...]
    report: Path
    metric_file: Path
    wall_seconds: float
    notes: tuple[str, ...] = ()  # one line each: how the cells ran where not as asked (Ray)


def run_study(
    takes: Sequence[Path],
    robots: Sequence[str],
    approaches: Sequence[Approach],
    out: Path,
    seconds: float | None = None,
    workers: int | None = None,
    address: str | None = None,
    progress: Callable[[CellOutcome], None] | None = None,
    corpus: Path | None = None,
) -> StudyResult:
    """Run (or reuse) every cell into ``out/cells``, derive the metric into ``out/metric.toml``,
    rank the approaches and write ``out/report.html`` with its figures.

    Raises:
        HlikError: no cell of the correlation part succeeded (nothing to correlate).
    """
    start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    cells = plan(takes, robots, approaches, seconds, corpus)
    prepare(robots, corpus)
    notes: list[str] = []
    outcomes = run_cells(cells, out / "cells", workers, address, progress, notes)
    table = read_dataset([o.path for o in outcomes if o.path is not None])
    frames = correlation_frames(table, {a.name for a in approaches if a.correlation}) if len(table) else table
    if not len(frames):
        failed = [o for o in outcomes if o.error is not None]
        first = (
            f"; {len(failed)} cells failed, the first: {failed[0].cell.take.name}: {failed[0].error}"
            if failed
            else ""
        )
        raise HlikError(f"{out}: no frames to correlate{first}")
    corr = correlate(frames)
    failed = [o for o in outcomes if o.error is not None]
    # a metric from part of the cells says so where it is kept, not only in the run's output
    partial = f"; partial: {len(failed)} of {len(cells)} cells failed (report.html)" if failed else ""
    source = f"hlik study of {len(takes)} takes on {', '.join(robots)}{partial}"
    metric = derive_metric(frames, corr, source=source)
    metric_file = out / "metric.toml"
    with atomic_path(metric_file) as tmp:
        tmp.write_text(metric.to_toml(), encoding="utf-8")
    scenarios = sorted({a.scenario for a in approaches}, key=("pose", "relative").index)
    rankings = tuple(rank(table, metric, s) for s in scenarios)
    wall = time.perf_counter() - start
    ran = [o for o in outcomes if not o.reused]
    summary: dict[str, object] = {
        "takes": len(takes),
        "robots": ", ".join(robots),
        "approaches": len(approaches),
        "seconds per take": "whole" if seconds is None else f"{seconds:g}",
        "cells": f"{len(cells)} ({len(ran)} run, {len(cells) - len(ran)} reused, "
        f"{sum(o.error is not None for o in outcomes)} failed)",
        "wall time": f"{wall:.0f} s",
        "CPU time of the cells run": f"{sum(o.seconds for o in ran):.0f} s",
        "metric": metric_file.name,
    }
    failures = [(o.cell.file_name, o.error) for o in outcomes if o.error is not None]
    report = write_report(out, corr, metric, rankings, summary, failures)
    return StudyResult(tuple(outcomes), corr, metric, rankings, report, metric_file, wall, tuple(notes))
