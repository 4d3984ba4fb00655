"""What a robot controller checks before it runs a trajectory: joint accelerations, jerks and
torques against the robot's limits, joints parked on their stops, and the robot on its floor.

Finite differences at the trajectory's frame period dt, the robot at rest before the first frame
(as the solvers assume, :mod:`hlik.solvers.limits`): velocity ``v_t = (q_t+1 - q_t) / dt``,
acceleration ``a_t = (q_t+1 - 2 q_t + q_t-1) / dt^2`` (t = 0 .. T-2), jerk the difference of a.
Torques are ``mujoco.mj_inverse`` at ``q_t`` with the central-difference velocity and ``a_t``:
inertia (with the models' armature, where they have one), Coriolis and centrifugal terms and
gravity; contacts and other constraints are off (the solvers keep the robot out of itself, and
nothing else touches it), as are passive forces: the models have no springs, and their joint
damping (ARMAR-III 1.0, ARMAR-6 0.5 N m s/rad) is a simulation setting, not a measured friction
(with it ARMAR-6's peak torque on the Cut take moves by 0.2 %). The trajectory ends where its last
frame does: ``end_speed`` says how fast it still moves there and ``stop_time`` how long its joints
need to stop at their acceleration limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hlik.criteria.angles import joint_difference
from hlik.robot.dynamics import inverse_dynamics, motion_rates
from hlik.robot.floor import lowest_points
from hlik.robot.model import Robot
from hlik.solvers.settings import STOP_MARGIN
from hlik.trajectory import Trajectory

AT_STOP = math.radians(0.5)  # a joint this close to a stop "sits on it"
AT_LIMIT = 0.99  # a joint at this share of its acceleration limit runs on it (no margin left)
# a joint this close to a stop is parked on the solvers' margin (STOP_MARGIN, 3 deg, plus AT_STOP):
# at rest against their soft stop, where JM's joints sit on the hard one
AT_MARGIN = STOP_MARGIN + AT_STOP
BELOW_FLOOR = 0.01  # m: a lowest point this far under the floor is reported


@dataclass(frozen=True, eq=False)
class ControllerChecks:
    """Per-frame checks of a trajectory; arrays (T,) unless said.

    Attributes:
        joint_names: (n,) the robot's joints.
        acceleration: (T, n) joint accelerations, rad/s^2 (0 at the last frame).
        acceleration_ratio: Largest |a_j| / a_max,j of the frame (0 where no joint has a limit).
        jerk: Largest |jerk_j| of the frame, rad/s^3.
        jerk_ratio: Largest |jerk_j| / jerk_max,j of the frame (0 where no joint has a limit).
        jerk_joint: The joint of the largest jerk over its limit (of the largest jerk without limits).
        torque: (T, n) joint torques, N m.
        torque_ratio: Largest |tau_j| / tau_max,j of the frame (0 where no joint has a limit).
        at_stop: A limited joint within :data:`AT_STOP` of one of its stops.
        at_margin: (T, n) each joint within :data:`AT_MARGIN` of one of its stops (the solvers'
            margin; False for unlimited joints).
        lowest: World height of the robot's lowest point, m.
        base_height: World height of the base frame (the robot's floor), m.
        end_speed: (n,) each joint's speed into the last frame, rad/s.
        acceleration_limit, jerk_limit, effort_limit: (n,) the robot's limits, rad/s^2, rad/s^3
            and N m (``inf``: none).
    """

    joint_names: tuple[str, ...]
    acceleration: np.ndarray
    acceleration_ratio: np.ndarray
    jerk: np.ndarray
    jerk_ratio: np.ndarray
    jerk_joint: str
    torque: np.ndarray
    torque_ratio: np.ndarray
    at_stop: np.ndarray
    at_margin: np.ndarray
    lowest: np.ndarray
    base_height: float
    end_speed: np.ndarray
    acceleration_limit: np.ndarray
    jerk_limit: np.ndarray
    effort_limit: np.ndarray

    @property
    def has_acceleration_limits(self) -> bool:
        """Whether the robot gives an acceleration limit for any joint."""
        return bool(np.any(np.isfinite(self.acceleration_limit)))

    @property
    def has_jerk_limits(self) -> bool:
        """Whether the robot gives a jerk limit for any joint."""
        return bool(np.any(np.isfinite(self.jerk_limit)))

    @property
    def has_effort_limits(self) -> bool:
        """Whether the robot gives an effort limit for any joint."""
        return bool(np.any(np.isfinite(self.effort_limit)))

    @property
    def n_frames(self) -> int:
        return len(self.at_stop)

    @property
    def frames_over_acceleration(self) -> int:
        return int(np.count_nonzero(self.acceleration_ratio > 1.0 + 1e-6))

    @property
    def frames_over_jerk(self) -> int:
        return int(np.count_nonzero(self.jerk_ratio > 1.0 + 1e-6))

    @property
    def frames_over_effort(self) -> int:
        return int(np.count_nonzero(self.torque_ratio > 1.0 + 1e-6))

    @property
    def share_at_stop(self) -> float:
        return float(np.count_nonzero(self.at_stop) / max(self.n_frames, 1))

    @property
    def share_at_margin(self) -> float:
        return float(np.count_nonzero(self.at_margin.any(axis=1)) / max(self.n_frames, 1))

    @property
    def share_at_acceleration_limit(self) -> float:
        """The share of frames with a joint at :data:`AT_LIMIT` of its acceleration limit or more."""
        return float(np.count_nonzero(self.acceleration_ratio >= AT_LIMIT) / max(self.n_frames, 1))

    @property
    def stop_time(self) -> float:
        """How long the joints still moving at the last frame need to stop at their acceleration
        limits, s (0 at rest; ``inf`` if a moving joint has no limit)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            speed = np.abs(self.end_speed)
            limit = np.where(np.isfinite(self.acceleration_limit), self.acceleration_limit, 0.0)
            times = np.where(speed > 0, speed / limit, 0.0)  # moving without a limit: inf
        return float(np.max(times, initial=0.0))

    @property
    def lowest_point(self) -> float:
        """The lowest the robot reaches in any frame, world z, m."""
        return float(self.lowest.min(initial=np.inf)) if self.n_frames else self.base_height

    def peak(self, values: np.ndarray, limits: np.ndarray) -> tuple[str, float]:
        """The joint of the largest |value| / limit over all frames of ``values`` (T, n), and
        that value (its |value| where no joint has a limit)."""
        if not values.size:
            return "", 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.abs(values) / np.where(np.isfinite(limits), limits, np.inf)
        if not np.any(np.isfinite(limits)):
            ratio = np.abs(values)
        k, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        return self.joint_names[j], float(values[k, j])

    def to_json(self) -> dict:
        """The ``"controller"`` object of ``hlik evaluate --json``: a ratio to limits the robot
        does not give, and the time to stop without acceleration limits, are null (not 0, inf)."""
        accel_joint, _ = self.peak(self.acceleration, self.acceleration_limit)
        torque_joint, torque = self.peak(self.torque, self.effort_limit)
        parked = self.at_margin.mean(axis=0) if self.n_frames else np.zeros(len(self.joint_names))
        most = int(parked.argmax()) if parked.size else 0  # the joint parked on the margin most

        def ratio(values: np.ndarray, given: bool) -> float | None:
            return float(values.max(initial=0.0)) if given else None

        stop = self.stop_time
        return {
            "max_acceleration_ratio": ratio(self.acceleration_ratio, self.has_acceleration_limits),
            "acceleration_joint": accel_joint,
            "frames_over_acceleration": self.frames_over_acceleration,
            "share_at_acceleration_limit": self.share_at_acceleration_limit,
            "max_jerk": float(self.jerk.max(initial=0.0)),
            "max_jerk_ratio": ratio(self.jerk_ratio, self.has_jerk_limits),
            "jerk_joint": self.jerk_joint,
            "frames_over_jerk": self.frames_over_jerk,
            "max_torque_ratio": ratio(self.torque_ratio, self.has_effort_limits),
            "torque_joint": torque_joint,
            "max_torque": abs(torque),
            "frames_over_effort": self.frames_over_effort,
            "frames_at_stop": int(np.count_nonzero(self.at_stop)),
            "share_at_stop": self.share_at_stop,
            "share_at_margin": self.share_at_margin,
            "margin_joint": self.joint_names[most] if parked.any() else "",
            "margin_joint_share": float(parked[most]) if parked.size else 0.0,
            "base_height": self.base_height,
            "lowest_point": self.lowest_point,
            "end_speed": float(np.max(np.abs(self.end_speed), initial=0.0)),
            "stop_time": stop if np.isfinite(stop) else None,
            "acceleration_limits": self.has_acceleration_limits,
            "jerk_limits": self.has_jerk_limits,
            "effort_limits": self.has_effort_limits,
        }


def joint_velocity(traj: Trajectory, robot: Robot) -> np.ndarray:
    """(T, n) each joint's speed into each frame, rad/s (0 into the first: at rest before it), the
    differencing of every check here (unlimited joints by their shorter way round)."""
    q, dt = traj.q, traj.period
    return motion_rates(joint_difference(q[1:], q[:-1], np.isinf(robot.lower)), dt, len(q))[0]


def joint_jerks(accel: np.ndarray, dt: float) -> np.ndarray:
    """(T, n) each joint's jerk into each frame's acceleration from the last, rad/s^3, from the
    accelerations (T, n) of :func:`~hlik.robot.dynamics.motion_rates` (0 at the first frame, and
    at the last, whose acceleration is 0 by that convention, not a jerk)."""
    jerks = np.zeros_like(accel)
    if len(accel) > 2:
        jerks[1:-1] = np.diff(accel[:-1], axis=0) / dt
    return jerks


def controller_checks(traj: Trajectory, robot: Robot) -> ControllerChecks:
    """The :class:`ControllerChecks` of ``traj`` on ``robot``."""
    q, dt = traj.q, traj.period
    unlimited = np.isinf(robot.lower)
    velocity, central, accel = motion_rates(joint_difference(q[1:], q[:-1], unlimited), dt, len(q))
    jerks = joint_jerks(accel, dt)
    jerk = np.max(np.abs(jerks), axis=1, initial=0.0)
    limits = robot.jerk_limit if np.any(np.isfinite(robot.jerk_limit)) else np.ones(robot.dof)
    jerk_joint = robot.joint_names[int(np.argmax(np.max(np.abs(jerks), axis=0) / limits))] if q.size else ""
    torque = inverse_dynamics(robot, q, central, accel)
    with np.errstate(invalid="ignore"):
        acc_ratio = np.max(np.abs(accel) / robot.acceleration_limit, axis=1, initial=0.0)
        tau_ratio = np.max(np.abs(torque) / robot.effort_limit, axis=1, initial=0.0)
        jerk_ratio = np.max(np.abs(jerks) / robot.jerk_limit, axis=1, initial=0.0)
    room = np.minimum(q - robot.lower, robot.upper - q)  # (T, n), inf for unlimited joints
    p = traj.placement
    base = float(p.translation[2])
    return ControllerChecks(
        joint_names=robot.joint_names,
        acceleration=accel,
        acceleration_ratio=np.nan_to_num(acc_ratio),
        jerk=jerk,
        jerk_ratio=np.nan_to_num(jerk_ratio),
        jerk_joint=jerk_joint,
        torque=torque,
        torque_ratio=np.nan_to_num(tau_ratio),
        at_stop=np.any(room < AT_STOP, axis=1),
        at_margin=room < AT_MARGIN,
        lowest=lowest_points(robot, q, p.rotation, base),
        base_height=base,
        end_speed=velocity[-1] if len(q) else np.zeros(robot.dof),
        acceleration_limit=robot.acceleration_limit,
        jerk_limit=robot.jerk_limit,
        effort_limit=robot.effort_limit,
    )
