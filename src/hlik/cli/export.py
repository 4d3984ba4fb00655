"""``hlik export``: a trajectory in a format robot software reads, refused where a controller would
refuse it."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from hlik.cli.app import FLAG, check_trajectory_file, console, one_line, trajectory_and_robot
from hlik.run_spec import EXPORT_FORMATS
from hlik.util.errors import HlikError


def braked(traj, robot) -> str:
    """What an export's message says of the braking frames it adds to ``traj`` (none: nothing): how
    many, how long and how far the hands move on (:mod:`hlik.braking`)."""
    from hlik.braking import brought_to_rest, hand_travel

    rest, stop = brought_to_rest(traj, robot)
    if not stop.n_frames:
        return ""
    travel = 100 * hand_travel(rest, stop.n_frames)
    return (
        f", then {stop.n_frames} frames ({stop.n_frames * traj.period:.2f} s) braking the joints to rest, "
        f"the hands moving on up to {travel:.1f} cm"
    )


def export(
    trajectory: Annotated[Path, typer.Argument(help="Trajectory .npz written by `hlik run`.")],
    fmt: Annotated[
        str,
        typer.Option(
            "--format",
            "-f",
            help="Export format: csv, mcap (ROS 2 messages) or lerobot (a LeRobot v3 dataset folder).",
        ),
    ] = "csv",
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            "-o",
            help="Output file (default: the trajectory's, new suffix; lerobot: a folder NAME_lerobot).",
        ),
    ] = None,
    allow_violations: Annotated[
        bool,
        typer.Option(
            "--allow-violations",
            help="Write a trajectory that breaks a joint limit anyway (the file says which).",
            metavar=FLAG,
            show_default=False,
        ),
    ] = False,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing file.", metavar=FLAG)] = False,
) -> None:
    """Export a trajectory (joint angles by name, time, base pose) for a robot's software, with the
    frames that bring it to rest where it ends moving; refused, naming the first frame and joint,
    where a controller would reject it (a joint out of range or over its speed, acceleration, jerk
    or effort limit)."""
    with one_line():
        check_trajectory_file(trajectory)
        if fmt not in EXPORT_FORMATS:  # before the writers' libraries load
            raise HlikError(f"unknown export format {fmt!r}; choose one of: {', '.join(EXPORT_FORMATS)}")
        from hlik.export import WRITERS, default_path
        from hlik.export import export as export_trajectory

        suffix = WRITERS[fmt][1]
        path = out or default_path(trajectory, fmt)
        if suffix and path.suffix.lower() != suffix:
            raise HlikError(f"{path}: --format {fmt} writes {suffix} files; name the output so")
        if path.exists() and not force:
            raise HlikError(f"{path}: exists; pass --force to replace it, or --out to write elsewhere")
        if path.resolve() == trajectory.resolve():
            raise HlikError(f"{path}: is the trajectory itself; choose another --out")
        traj, robot = trajectory_and_robot(trajectory)
        written = export_trajectory(traj, robot, path, fmt, allow_violations)
        added = braked(traj, robot)
    console.print(
        f"wrote {written} ({fmt}, {traj.n_frames} frames{added}; {robot.dof} joints)",
        highlight=False,
        soft_wrap=True,
    )
