"""Stage 7b, exports: a trajectory in the formats robot software reads, followed by the frames
that bring it to rest (:mod:`hlik.braking`) and checked first against what a controller rejects
(:mod:`~hlik.export.violations`).

- ``csv``: one row per frame, ``time`` then the joints by name and the base pose
  (:mod:`~hlik.export.csvfile`);
- ``mcap``: ROS 2 messages, joint states, the joint trajectory and the hands' target poses
  (:mod:`~hlik.export.mcapfile`);
- ``lerobot``: a LeRobot v3.0 dataset folder, joint positions as state, the next ones as action
  (:mod:`~hlik.export.lerobotfile`).

A format adds one module with a ``write(traj, robot, path, violation, braking)`` function (the
trajectory with its braking frames, and how many of its last frames they are) and one line in
:data:`WRITERS` (its suffix; "" for a folder).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType

from hlik.braking import brought_to_rest
from hlik.export import csvfile, lerobotfile, mcapfile
from hlik.export.violations import first_violation
from hlik.robot.model import Robot
from hlik.trajectory import Trajectory
from hlik.util.atomic import atomic_folder, atomic_path
from hlik.util.errors import HlikError

# format -> (writer into a path, file suffix; "" writes a folder)
WRITERS: Mapping[str, tuple[Callable[[Trajectory, Robot, Path, str | None, int], None], str]] = (
    MappingProxyType(
        {
            "csv": (csvfile.write, ".csv"),
            "mcap": (mcapfile.write, ".mcap"),
            "lerobot": (lerobotfile.write, ""),
        }
    )
)


def default_path(trajectory: Path, fmt: str) -> Path:
    """Where ``hlik export`` (and ``hlik run --export``) writes ``fmt`` of the trajectory file
    ``trajectory``: beside it, its name with the format's suffix, or ``NAME_lerobot`` for a folder."""
    suffix = WRITERS[fmt][1]
    return trajectory.with_suffix(suffix) if suffix else trajectory.with_name(f"{trajectory.stem}_{fmt}")


def export(
    traj: Trajectory, robot: Robot, path: str | Path, fmt: str = "csv", allow_violations: bool = False
) -> Path:
    """Write ``traj`` (of ``robot``) to ``path`` in ``fmt``, whole or not at all, followed by the
    frames that bring it to rest (none where it ends at rest; :func:`hlik.braking.braking`).

    A trajectory a controller would reject (:func:`first_violation`: a position, speed,
    acceleration or effort limit broken) is refused unless ``allow_violations``; then the file says
    which limit it breaks.

    Raises:
        HlikError: an unknown format, or the first violation (frame, joint, value, limit).
    """
    if fmt not in WRITERS:
        raise HlikError(f"unknown export format {fmt!r}; choose one of: {', '.join(WRITERS)}")
    traj, stop = brought_to_rest(traj, robot)
    violation = first_violation(traj, robot)
    if violation is not None and not allow_violations:
        raise HlikError(f"{path}: not exported: {violation} (--allow-violations writes it anyway)")
    write, suffix = WRITERS[fmt]
    path = Path(path)
    with atomic_path(path) if suffix else atomic_folder(path) as tmp:
        write(traj, robot, tmp, violation, stop.n_frames)
    return path


__all__ = ["WRITERS", "default_path", "export", "first_violation"]
