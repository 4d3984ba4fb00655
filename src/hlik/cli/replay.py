"""``hlik replay``: a trajectory played through MuJoCo's physics, as a check before the robot."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Annotated

import typer

from hlik.cli.app import FLAG, check_trajectory_file, console, one_line, trajectory_and_robot
from hlik.util.errors import HlikError


def replay(
    trajectory: Annotated[Path, typer.Argument(help="Trajectory .npz written by `hlik run`.")],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", help="Recording of the replay (default: the trajectory's name + _replay.rrd)."
        ),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Replace an existing recording.", metavar=FLAG)
    ] = False,
) -> None:
    """Play a trajectory through MuJoCo's physics under a torque controller within the motors'
    efforts; report how far each simulated TCP is from the commanded one, the joints at their
    effort or speed limits, and contacts; write a recording with the simulated robot drawn over
    the commanded one."""
    with one_line():
        check_trajectory_file(trajectory)
        rrd = out or trajectory.with_name(f"{trajectory.stem}_replay.rrd")
        if rrd.suffix != ".rrd":
            raise HlikError(f"{rrd}: a recording is an .rrd file; name the output so")
        if rrd.exists() and not force:
            raise HlikError(f"{rrd}: exists; pass --force to replace it, or --out to write elsewhere")
        from hlik.recording import write_recording
        from hlik.replay import BANDWIDTH, SUBSTEPS
        from hlik.replay import replay as play

        traj, robot = trajectory_and_robot(trajectory)
        result = play(traj, robot)
        info = {"replay": result.verdict(), "commanded": str(trajectory)}
        write_recording(rrd, traj, robot, info=info, simulated=result.q)
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
    console.print(f"recording (simulated robot in orange over the commanded): {rrd}", soft_wrap=True)
    console.print(f"open with: rerun {shlex.quote(str(rrd))}", soft_wrap=True)
