"""A trajectory as CSV: one row per frame, ``time`` then each joint by its name, then the base pose
(position and a scalar-first quaternion), under ``#`` comment lines that give the robot, the units,
the quaternion order and the frame rate (GMR's robot CSV carries the same, with the order left to
the reader: YanjieZe/GMR issues). Values are written in full (Python's shortest round-trip form), so
reading the file gives back the trajectory's numbers exactly."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from hlik.braking import hand_travel
from hlik.robot.model import Robot
from hlik.trajectory import Trajectory

BASE_COLUMNS = ("base_x", "base_y", "base_z", "base_qw", "base_qx", "base_qy", "base_qz")


def base_pose(traj: Trajectory) -> np.ndarray:
    """(7,) the robot base in the world: position (m) and quaternion w, x, y, z (world <- base)."""
    x, y, z, w = Rotation.from_matrix(traj.placement.rotation).as_quat()
    return np.array([*traj.placement.translation, w, x, y, z])


def header(traj: Trajectory, robot: Robot, violation: str | None, braking: int = 0) -> list[str]:
    """The comment lines (without ``#``) above the table; ``braking``: how many of the last rows
    are the frames that bring the joints to rest (:mod:`hlik.braking`)."""
    lines = [
        f"hlik trajectory: robot {robot.name} ({robot.title}), solver {traj.solver}, "
        f"{len(traj.times)} frames at {1.0 / traj.period:g} Hz",
        "units: time s from the first frame; joints rad (hinge angles, the robot model's zero and sign); "
        "base_x, base_y, base_z m",
        "base pose: world <- robot base (z up, the floor at z = 0), quaternion order w, x, y, z "
        "(scalar first), constant over the take",
    ]
    if braking:
        start = traj.times[-braking] - traj.times[0]
        rest = traj.q[-braking:]
        # the braking keeps the ranges from any state the solvers leave; one exported over its
        # limits may start beyond what braking can keep
        inside = bool(np.all((rest >= robot.lower) & (rest <= robot.upper)))
        within = "limits" if inside else "speed, acceleration and jerk limits, leaving a joint's range"
        lines.append(
            f"braking rows: the last {braking} (from {start:.2f} s) bring the joints to rest within their "
            f"{within}, added by hlik after the retargeted motion, which ended moving (the hands move "
            f"on up to {100 * hand_travel(traj, braking):.1f} cm)"
        )
    if violation is not None:
        lines.append(f"WARNING: exported with --allow-violations; a controller would reject it: {violation}")
    return lines


def write(traj: Trajectory, robot: Robot, path: Path, violation: str | None = None, braking: int = 0) -> None:
    """Write ``traj`` to ``path`` (see the module docstring)."""
    base = base_pose(traj)
    times = traj.times - traj.times[0]
    with open(path, "w", newline="", encoding="utf-8") as f:
        for line in header(traj, robot, violation, braking):
            f.write(f"# {line}\n")
        out = csv.writer(f)
        out.writerow(["time", *traj.joint_names, *BASE_COLUMNS])
        for t, q in zip(times, traj.q):
            out.writerow([repr(float(t)), *(repr(float(v)) for v in q), *(repr(float(b)) for b in base)])
