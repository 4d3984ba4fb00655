"""What a robot's controller rejects before it moves (Kinovarobotics/ros_kortex #131, #267; the UR
ROS 2 driver #1273; libfranka's motion generator): a joint outside its range, or faster,
accelerating harder, jerking harder or needing more torque than its limits, at any frame, and at
the end, where the controller holds the last position (a trajectory that ends moving must stop
within one frame: :mod:`hlik.braking` appends the frames that stop it). The same differencing and
inverse dynamics as :mod:`hlik.executable`."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from hlik.executable import controller_checks, joint_jerks, joint_velocity
from hlik.robot.model import Robot
from hlik.trajectory import Trajectory

TOLERANCE = 1e-6  # relative: what rounding leaves of a limit the solver kept exactly


def first_violation(traj: Trajectory, robot: Robot) -> str | None:
    """None if ``traj`` keeps every position, speed, acceleration and effort limit of ``robot``;
    else the first broken one as ``"frame 12 (0.12 s): joint Elbow_L acceleration 14.2 rad/s^2
    over its limit 10, the first of 3 frames that break a limit"`` (the earliest frame; at that
    frame, position before speed before acceleration before jerk before effort). The last frame is
    held after it, as a controller does: a trajectory that ends moving breaks the acceleration
    limit there unless it brakes within one frame."""
    held = replace(
        traj,
        q=traj.q[np.r_[np.arange(traj.n_frames), -1]],
        times=np.r_[traj.times, traj.times[-1] + traj.period],
    )
    checks = controller_checks(held, robot)
    q, v = held.q, joint_velocity(held, robot)
    slack = TOLERANCE * np.maximum(1.0, np.abs(np.stack([robot.lower, robot.upper])))
    below, above = q < robot.lower - slack[0], q > robot.upper + slack[1]
    acc, tau = np.abs(checks.acceleration), np.abs(checks.torque)
    jerk = np.abs(joint_jerks(checks.acceleration, traj.period))
    with np.errstate(invalid="ignore", divide="ignore"):
        tests = (
            ("position", q, below | above, np.where(below, robot.lower, robot.upper), "rad"),
            (
                "speed",
                np.abs(v),
                np.abs(v) > robot.velocity_limit * (1 + TOLERANCE),
                robot.velocity_limit,
                "rad/s",
            ),
            (
                "acceleration",
                acc,
                acc > robot.acceleration_limit * (1 + TOLERANCE),
                robot.acceleration_limit,
                "rad/s^2",
            ),
            ("jerk", jerk, jerk > robot.jerk_limit * (1 + TOLERANCE), robot.jerk_limit, "rad/s^3"),
            ("effort", tau, tau > robot.effort_limit * (1 + TOLERANCE), robot.effort_limit, "N m"),
        )
    first = min((int(np.argmax(bad.any(axis=1))) for _, _, bad, _, _ in tests if bad.any()), default=None)
    if first is None:
        return None
    frames = int(np.count_nonzero(np.any([bad.any(axis=1) for _, _, bad, _, _ in tests], axis=0)))
    for what, values, bad, limits, unit in tests:
        if bad[first].any():
            j = int(np.argmax(bad[first]))
            limit = np.broadcast_to(limits, q.shape)[first, j]
            value = values[first, j]
            word = "outside its range at" if what == "position" else "over its limit"
            k = min(first, traj.n_frames - 1)  # the held frame's fault is the last frame's
            end = ", the last, held after it" if first >= traj.n_frames - 1 else ""
            return (
                f"frame {k}{end} ({traj.times[k] - traj.times[0]:.2f} s): joint {robot.joint_names[j]} "
                f"{what} {value:.4g} {unit} {word} {limit:.4g}, "
                f"the first of {frames} frames that break a limit"
            )
    return None  # pragma: no cover - a frame found bad above is bad in one test
