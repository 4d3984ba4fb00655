"""``hlik replay``: a trajectory played through MuJoCo's physics, as a check before the robot."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from hlik.cli.app import check_trajectory_file, console, one_line, trajectory_and_robot


def replay(
    trajectory: Annotated[Path, typer.Argument(help="Trajectory .npz written by `hlik run`.")],
) -> None:
    """Play a trajectory through MuJoCo's physics under a torque controller within the motors'
    efforts; report how far each simulated TCP is from the commanded one, the joints at their
    effort or speed limits, and contacts."""
    with one_line():
        check_trajectory_file(trajectory)
        from hlik.replay import BANDWIDTH, SUBSTEPS
        from hlik.replay import replay as play

        traj, robot = trajectory_and_robot(trajectory)
        result = play(traj, robot)
    console.print(
        f"{trajectory.name}: {robot.title}, {traj.solver}, {traj.n_frames} frames replayed "
        f"(computed torque, each joint's error a {BANDWIDTH:g} Hz loop, {SUBSTEPS} physics steps a frame, "
        "clipped at the effort limits)",
        highlight=False,
        soft_wrap=True,
    )
    for line in result.lines():
        console.print(f"  {line}", highlight=False, soft_wrap=True)
    console.print(result.verdict(), highlight=False, soft_wrap=True)
