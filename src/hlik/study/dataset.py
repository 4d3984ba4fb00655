"""The study's dataset: one Parquet file of per-frame costs per cell (take x robot x approach).

A cell's table has one row per frame: ``take``, ``robot``, ``approach``, ``solver``, ``scenario``,
``frame``, ``time`` (s), ``h_<criterion>`` for every registered criterion (functional ones included;
units of the criterion's cost), ``fpos_left`` and ``fpos_right`` (m), ``iterations``, ``converged``,
``failed``, ``solve_time`` (s), ``collision`` and ``speed_ratio`` (the step into the frame; 0 at the
first), and the posture measures (:mod:`hlik.posture`) of the robot and the subject: ``lean_robot``,
``lean_subject`` (rad), ``elbow_front_<side>_<who>``, ``hand_front_<side>_<who>``,
``wrist_front_<side>_<who>`` (arm lengths) and ``swivel_<side>_<who>`` (rad; NaN where
undefined). Files are written whole or not at all, so a rerun skips finished cells and a crash
loses one cell.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from hlik.criteria.functional import position_error
from hlik.criteria.learned import Learned
from hlik.human.motion import HumanMotion
from hlik.pipeline import RunSpec, read_motion, run
from hlik.problem.placement import Placement
from hlik.robot.model import Robot
from hlik.study.approaches import Approach
from hlik.util.atomic import atomic_path
from hlik.util.version import __version__

SKIP = 1.0  # s cut from the start of a take (the subject's T-pose and first reach) when cropping


@dataclass(frozen=True)
class Cell:
    """One retargeting run of the study: a take, a robot, an approach; ``seconds`` of motion after
    the first second (``None``: the whole take), resampled to ``rate`` Hz; the learned pieces from
    ``corpus`` (``hlik.criteria.learned.learn``'s default if None)."""

    take: Path
    robot: str
    approach: Approach
    seconds: float | None = None
    rate: float = 100.0
    corpus: Path | None = None

    @property
    def file_name(self) -> str:
        """``<take>__<robot>__<approach>__<seconds>s.parquet``: what a reused cell must match."""
        span = "all" if self.seconds is None else f"{self.seconds:g}"
        rate = "" if self.rate == 100.0 else f"__{self.rate:g}hz"
        robot = Path(self.robot).stem  # a robot given by the path of its .toml
        return f"{self.take.stem}__{robot}__{self.approach.key}__{span}s{rate}.parquet"


def cell_spec(cell: Cell) -> RunSpec:
    """The :class:`~hlik.pipeline.RunSpec` of a cell."""
    a = cell.approach
    return RunSpec(
        motion=cell.take,
        robot=cell.robot,
        solver=a.solver,
        stack=a.stack,
        criteria=tuple(a.criteria),
        scenario=a.scenario,
        rate=cell.rate,
        span=_span(cell.seconds),
        corpus=cell.corpus,
    )


def cell_motion(take: Path, seconds: float | None, rate: float, robot: Robot) -> HumanMotion:
    """A cell's motion: ``take`` resampled to ``rate`` Hz, ``seconds`` of it after the first second
    (``None``: all of it), the subject scaled by the robot's rule."""
    return read_motion(RunSpec(motion=take, rate=rate, span=_span(seconds)), robot)


def _span(seconds: float | None) -> tuple[float, float] | None:
    return None if seconds is None else (SKIP, SKIP + seconds)


def run_cell(
    cell: Cell,
    robot: Robot,
    learned: Learned,
    motion: HumanMotion | None = None,
    placement: Placement | None = None,
) -> pa.Table:
    """Retarget and evaluate one cell (:func:`hlik.pipeline.run`); its per-frame table (see the
    module docstring).

    ``motion`` and ``placement``: the cell's (:func:`cell_motion`; the robot's own placement rule),
    when the caller already has them (every approach of a take and robot shares both).
    """
    a = cell.approach
    result = run(cell_spec(cell), robot=robot, motion=motion, learned=learned, placement=placement)
    traj, ev, cpu = result.trajectory, result.evaluation, result.solve_cpu
    n = traj.n_frames
    fpos = position_error(traj.tcp_pos, traj.targets.pos)
    d = traj.diagnostics
    columns: dict[str, object] = {
        "take": [cell.take.stem] * n,
        "robot": [robot.name] * n,
        "approach": [a.name] * n,
        "solver": [a.solver] * n,
        "scenario": [a.scenario] * n,
        "frame": np.arange(n),
        "time": traj.times - traj.times[0],
        **{f"h_{k}": np.asarray(v, dtype=float) for k, v in ev.h.items()},
        "fpos_left": fpos[:, 0],
        "fpos_right": fpos[:, 1],
        "iterations": d.iterations.astype(np.int32),
        "converged": d.converged.astype(bool),
        "failed": d.failed.astype(bool),
        "solve_time": d.solve_time.astype(float),
        "collision": ev.collisions.astype(bool),
        "speed_ratio": np.concatenate([[0.0], ev.speed_ratio]),
    }
    for who, body in (("robot", ev.posture.robot), ("subject", ev.posture.subject)):
        columns[f"lean_{who}"] = body.lean
        for i, side in enumerate(("left", "right")):
            columns[f"elbow_front_{side}_{who}"] = body.elbow_front_share[:, i]
            columns[f"hand_front_{side}_{who}"] = body.hand_front_share[:, i]
            columns[f"wrist_front_{side}_{who}"] = body.wrist_front_share[:, i]
            columns[f"swivel_{side}_{who}"] = body.swivel[:, i]
    meta = {
        "hlik": __version__,
        "placement": traj.placement.method,
        "criteria": ",".join(a.criteria),
        "stack": a.stack,
        "seconds": "" if cell.seconds is None else f"{cell.seconds:g}",
        "cpu_seconds": f"{cpu:.3f}",
    }
    table = pa.table(columns)
    return table.replace_schema_metadata({k.encode(): v.encode() for k, v in meta.items()})


def write_cell(table: pa.Table, path: Path) -> Path:
    """Write a cell's table to ``path`` atomically."""
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)
    return path


def read_dataset(paths: list[Path]) -> pa.Table:
    """The cells' tables, concatenated; a column some cells lack (a cell written by an older hlik,
    before the posture measures) is null in their rows."""
    tables = [pq.read_table(p) for p in paths]
    return pa.concat_tables(tables, promote_options="default") if tables else pa.table({})
