"""The frames that bring a trajectory to rest, which every export appends.

A trajectory ends where its last frame does, often still moving: a span cut from a take, a hand
still on its way. A controller given it holds the last position, which asks the whole speed to
vanish within one frame (2-Panda, QP, Cut take 2–6 s: 1.2 rad/s, 7× its acceleration limit).
The braking frames go on from the last frame's speed and acceleration, differenced as the
controller check does (:mod:`hlik.executable`), to rest: zero speed and acceleration, within the
robot's speed, acceleration and jerk limits (time-optimal; Ruckig, Berscheid & Kröger, RSS 2021).
All joints come to rest at the same time (Ruckig's synchronisation), so the hands run on about
along their path rather than each joint stopping at its own time; where that leaves a joint's
range, each joint brakes on its own at its limits, the shortest way it can (the solvers keep
every joint able to do that before its stop's margin, :mod:`hlik.solvers.limits`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import ruckig

from hlik.criteria.angles import joint_difference
from hlik.problem.targets import HandTargets
from hlik.robot.dynamics import motion_rates
from hlik.robot.model import Robot, tcp_poses
from hlik.solvers.limits import MotionLimits
from hlik.solvers.settings import LimitSettings
from hlik.trajectory import Trajectory

MAX_BRAKING_FRAMES = 1000  # a braking still planned again after these many frames is given up
AT_REST = 1e-9  # rad: a frame the box moves less than this is the plan's


@dataclass(frozen=True, eq=False)
class Braking:
    """How a trajectory is brought to rest.

    Attributes:
        q: (K, n) joint angles of the frames after the last, rad, at the trajectory's frame
            period; K = 0 where it ends at rest.
        synchronised: Whether the joints come to rest together (False: each on its own, since
            stopping together leaves a joint's range).
        inside: Whether every braking frame is inside the joints' ranges (False: no braking
            within the limits keeps them there; the frames are the per-joint braking all the same).
    """

    q: np.ndarray
    synchronised: bool = True
    inside: bool = True

    @property
    def n_frames(self) -> int:
        return len(self.q)


def end_state(q: np.ndarray, dt: float, unlimited: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Speed (n,) into the last frame of ``q`` (T, n) and its acceleration (n,), rad/s and rad/s^2,
    as the controller check differences them (:func:`~hlik.robot.dynamics.motion_rates`, at rest
    before the first frame)."""
    velocity, _, accel = motion_rates(joint_difference(q[1:], q[:-1], unlimited), dt, len(q))
    return velocity[-1], accel[-2] if len(q) > 1 else accel[-1]  # one frame: at rest


def braking(traj: Trajectory, robot: Robot) -> Braking:
    """The frames that bring ``traj`` (of ``robot``) to rest after its last frame (module
    docstring). Joints without a speed or acceleration limit brake at no limit of their own."""
    dt, n = traj.period, traj.q.shape[1]
    unlimited = np.isinf(robot.lower)
    v, a = end_state(traj.q, dt, unlimited)
    if not np.any(v) and not np.any(a):
        return Braking(np.zeros((0, n)))
    for sync in (ruckig.Synchronization.Phase, ruckig.Synchronization.No):
        plan = _plan(robot, traj.q[-1], v, a, dt, sync)
        if np.all((plan >= robot.lower) & (plan <= robot.upper)):
            break
    frames = _held_to_the_frames(traj.q, plan, robot, dt, sync)
    inside = bool(np.all((frames >= robot.lower) & (frames <= robot.upper)))
    return Braking(frames, synchronised=sync == ruckig.Synchronization.Phase, inside=inside)


def _plan(
    robot: Robot, q: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float, sync: ruckig.Synchronization
) -> np.ndarray:
    """(K, n) Ruckig's time-optimal profile from position ``q``, speed ``v`` and acceleration ``a``
    (n,) to rest, sampled at dt, 2 dt, ...; K = 0 at rest."""
    n = len(q)
    inp = ruckig.InputParameter(n)
    inp.control_interface = ruckig.ControlInterface.Velocity
    inp.synchronization = sync
    # the continuous state at the last frame whose mean speed over the last step is v, within the
    # speed limit: Ruckig's velocity interface does not bound the speed, and a joint at its limit
    # still accelerating would start braking above it (2-Panda: 2.22 rad/s over 2.175)
    speed = robot.velocity_limit
    inp.current_position = q.tolist()
    inp.current_velocity = np.clip(v + 0.5 * a * dt, -speed, speed).tolist()
    # likewise within the acceleration limit: a trajectory exported over its limits (--allow-violations)
    # starting at 20x it would take Ruckig seconds of jerk-limited turning round (1189 rad)
    inp.current_acceleration = np.clip(a, -robot.acceleration_limit, robot.acceleration_limit).tolist()
    inp.target_velocity = [0.0] * n
    inp.target_acceleration = [0.0] * n
    # limits not given are inf: without a jerk limit, Ruckig's acceleration-limited profiles (the
    # acceleration may step, as the solvers' may on such a robot: README "What a controller checks")
    inp.max_velocity = speed.tolist()
    inp.max_acceleration = robot.acceleration_limit.tolist()
    inp.max_jerk = robot.jerk_limit.tolist()
    return _sample(inp, n, dt)


def _held_to_the_frames(
    q: np.ndarray, plan: np.ndarray, robot: Robot, dt: float, sync: ruckig.Synchronization
) -> np.ndarray:
    """(K', n) the Ruckig ``plan`` (K, n) after the trajectory ``q`` (T, n), each frame moved into
    the box the solvers keep (:class:`~hlik.solvers.limits.MotionLimits`, the stops without a
    margin); where the box moves one, the rest is planned again from the state it left. Ruckig's
    continuous profile may leave the limits as the controller check differences them, by a
    frame's rounding: a joint at its speed limit still accelerating started 1 % over it where the
    jerk limit binds (a robot at 300 rad/s^3); the box is that differencing's own."""
    limits = MotionLimits.of(robot, LimitSettings(stop_margin=0.0, torque_limits=False))
    q3, q2, q1 = np.vstack([np.repeat(q[:1], max(0, 3 - len(q)), axis=0), q[-3:]])  # at rest before
    out: list[np.ndarray] = []
    i = 0
    while i < len(plan) and len(out) < MAX_BRAKING_FRAMES:
        q3, q2, q1 = q2, q1, limits.box(q1, q2, dt, q3=q3).clip(plan[i])
        out.append(q1)
        if np.allclose(q1, plan[i], rtol=0.0, atol=AT_REST):
            i += 1
        else:
            plan, i = _plan(robot, q1, (q1 - q2) / dt, (q1 - 2.0 * q2 + q3) / (dt * dt), dt, sync), 0
    return np.array(out).reshape(-1, q.shape[1])


def brought_to_rest(traj: Trajectory, robot: Robot) -> tuple[Trajectory, Braking]:
    """``traj`` followed by its :func:`braking` frames (their TCP poses by forward kinematics, the
    hand targets held at the last frame's), and the braking. The human motion, reference and
    diagnostics stay the take's: the braking frames have no human behind them."""
    stop = braking(traj, robot)
    if not stop.n_frames:
        return traj, stop
    k, last = stop.n_frames, traj.n_frames - 1
    pos, rot = tcp_poses(robot, stop.q)
    held = np.r_[np.arange(traj.n_frames), np.full(k, last)]
    targets = HandTargets(pos=traj.targets.pos[held], rot=traj.targets.rot[held])
    return (
        replace(
            traj,
            times=np.r_[traj.times, np.round(traj.times[-1] + traj.period * np.arange(1, k + 1), 9)],
            q=np.vstack([traj.q, stop.q]),
            tcp_pos=np.concatenate([traj.tcp_pos, pos]),
            tcp_rot=np.concatenate([traj.tcp_rot, rot]),
            targets=targets,
        ),
        stop,
    )


def hand_travel(rest: Trajectory, frames: int) -> float:
    """How far, m, either TCP moves on over the last ``frames`` frames of ``rest`` (the braking of
    :func:`brought_to_rest`) from where the retargeted motion left it; 0 without braking."""
    if frames <= 0:
        return 0.0
    start = rest.tcp_pos[-frames - 1]
    return float(np.max(np.linalg.norm(rest.tcp_pos[-frames:] - start, axis=-1)))


def _sample(inp: ruckig.InputParameter, n: int, dt: float) -> np.ndarray:
    """(K, n) the Ruckig profile of ``inp`` at dt, 2 dt, ... until it has come to rest."""
    path = ruckig.Trajectory(n)
    result = ruckig.Ruckig(n).calculate(inp, path)
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):  # pragma: no cover - Ruckig's own
        raise RuntimeError(f"Ruckig could not brake the trajectory: {result}")
    k = int(np.ceil(path.duration / dt - 1e-9))
    return np.array([path.at_time(min((i + 1) * dt, path.duration))[0] for i in range(k)]).reshape(k, n)
