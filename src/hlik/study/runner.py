"""Run a study: every cell (take x robot x approach) not on disk yet, in-process or as Ray tasks,
then the analysis and the report. A failed cell is listed, never fatal."""

from __future__ import annotations

import functools
import logging
import os
import time
import traceback
from collections.abc import Callable, Sequence
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
    ray = _ray(workers, address) if todo else None
    outcomes = list(done)
    if ray is None:
        for cell in todo:
            outcomes.append(solve_cell(cell, folder))
            if progress:
                progress(outcomes[-1])
        return outcomes
    task = ray.remote(solve_cell)
    pending = [task.remote(cell, folder) for cell in todo]
    while pending:
        ready, pending = ray.wait(pending, num_returns=1)
        outcomes.append(ray.get(ready[0]))
        if progress:
            progress(outcomes[-1])
    return outcomes


def _ray(workers: int | None, address: str | None):
    """Ray, initialised for ``workers`` CPUs (or joined to ``address``); None to run in-process."""
    if workers == 1 and address is None:
        return None
    try:
        import ray
    except ImportError:
        return None
    if not ray.is_initialized():
        src = str(Path(__file__).resolve().parents[2])  # workers import hlik from the same checkout
        env = {"env_vars": {"PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}}
        # hlik prints its own progress; Ray's start-up INFO and WARNING lines would break the bar
        quiet: dict[str, Any] = {"runtime_env": env, "log_to_driver": False, "logging_level": logging.ERROR}
        if address:
            ray.init(address=address, **quiet)
        else:
            ray.init(num_cpus=workers or os.cpu_count(), include_dashboard=False, **quiet)
    return ray


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
    outcomes = run_cells(cells, out / "cells", workers, address, progress)
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
    return StudyResult(tuple(outcomes), corr, metric, rankings, report, metric_file, wall)
