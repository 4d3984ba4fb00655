"""The result panel: the run's motion, robot, solver, settings, scores and diagnostics as markdown."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from hlik.metrics import Evaluation
from hlik.robot.model import Robot
from hlik.trajectory import Trajectory


def summary(traj: Trajectory, robot: Robot, evaluation: Evaluation | None, info: Mapping[str, str]) -> str:
    """The markdown of the result panel: motion, robot, solver, placement and ``info``'s settings;
    the scores (the numbers of ``hlik evaluate --json``, rounded); the solver's diagnostics; the
    hlik version."""
    from hlik.util.version import __version__

    d = traj.diagnostics
    rate = 1.0 / traj.period
    source = traj.motion.source
    named = Path(source).name if source else traj.motion.name  # the file, as the CLI names runs
    settings = {
        "motion": f"{named} ({traj.n_frames} frames, {rate:.0f} Hz)",
        "robot": f"{robot.title} ({robot.name})",
        "solver": traj.solver,
        "placement": traj.placement.method,
        **{k: str(v) for k, v in info.items()},
    }
    title = Path(source).stem if source else traj.motion.name
    lines = [f"### {title} on {robot.name}, {traj.solver}", ""]
    if evaluation is not None:  # the scores first, then each criterion's: what the panel is opened for
        result = evaluation.to_json()
        lines += [
            f"**m_hl = {result['m_hl']:.4f}**, m_f = {result['m_f']:.4f}, "
            f"m_hl,f = {result['m_hl_f']:.4f} (scenario {result['scenario']}; "
            f"weights and x0: {_cell(result['metric'])})",
            "",
            *_criteria_table(
                [(k, v["h"], v["m"]) for group in ("metrics", "functional") for k, v in result[group].items()]
            ),
            "",
        ]
    lines += ["| | |", "|---|---|"]
    lines += [f"| {k} | {_cell(v)} |" for k, v in settings.items()]
    n = traj.n_frames
    lines += [
        "",
        "| diagnostics | |",
        "|---|---:|",
        f"| failed frames | {d.n_failed} of {n} |",
        f"| unconverged frames | {d.n_unconverged} of {n} |",
    ]
    if evaluation is not None:
        lines += [
            f"| frames in self-collision | {int(np.count_nonzero(evaluation.collisions))} of {n} |",
            f"| max speed ratio | {evaluation.max_speed_ratio:.3g} |",
        ]
    lines += ["", f"hlik {__version__}"]
    return "\n".join(lines) + "\n"


def _criteria_table(rows: list[tuple[str, float, float]], across: int = 3) -> list[str]:
    """Markdown rows of (criterion, mean h, m), ``across`` criteria to a row: the eleven metrics and
    the functional ones fit the panel's opening height in five rows (one a row needed scrolling)."""
    head = "|" + " criterion | mean h | m |" * across
    rule = "|" + "---|---:|---:|" * across
    out = [head, rule]
    for i in range(0, len(rows), across):
        chunk = rows[i : i + across]
        cells = [f" {k} | {h:.4g} | {m:.4f} " for k, h, m in chunk] + [" | | "] * (across - len(chunk))
        out.append("|" + "|".join(cells) + "|")
    return out


def _cell(text: str) -> str:
    """``text`` safe in a markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ")
