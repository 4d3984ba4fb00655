"""A trajectory played through MuJoCo's physics before anyone sends it to the robot: does the
simulated robot, driven by a joint controller within its motors' efforts, follow the commanded
motion, and does it touch itself?

The controller is what a torque-controlled arm runs: computed torque, ``tau = M(q) (a_ref + w^2
(q_ref - q) + 2 w (v_ref - v)) + c(q, v) + g(q)`` (``mujoco.mj_inverse`` at the simulated state,
contacts and passive forces off), clipped at each joint's effort limit (the robot TOML's
``[effort_limits]``). The reference is the C1 curve of the frames (:func:`reference`), whose
accelerations are those :mod:`hlik.executable` checked; every joint's error decays as a critically
damped loop of :data:`BANDWIDTH` (``w = 2 pi BANDWIDTH``), a gain stated here since no robot file
gives one. :data:`SUBSTEPS` physics steps per frame; the robot starts at rest on the first frame.
The model's joint damping and limits act as simulated (the controller does not cancel the damping);
contacts come from its collision geometry (pairs touching by construction are excluded in the
models).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from hlik.executable import joint_velocity
from hlik.robot.dynamics import inverse_model
from hlik.robot.model import SIDES, Robot
from hlik.trajectory import Trajectory

BANDWIDTH = 10.0  # Hz, each joint's position loop
SUBSTEPS = 10  # physics steps per trajectory frame
FOLLOWED = 0.01  # m: a simulated TCP this close to the commanded one follows it
SPEED_SLACK = 1.005  # a simulated speed this far over its limit is the tracking lag's, not the plan's


@dataclass(frozen=True, eq=False)
class Replay:
    """What the physics did with a trajectory.

    Attributes:
        q: (T, n) simulated joint angles at the frames' times, rad.
        tcp_pos: (T, 2, 3) simulated TCP positions (left, right), robot base frame, m.
        deviation: (T, 2) distance of each simulated TCP from the commanded one, m.
        saturated: (T, n) True where a joint's torque was clipped at its effort limit in the frame.
        speed_ratio: (T, n) each joint's simulated speed at the frame over its speed limit (the
            physics does not stop a joint at its speed limit: a motor would).
        contacts: (T,) the body pairs in contact during the frame ("" where none), ``"a|b"``.
        joint_names: (n,) the robot's joints.
    """

    q: np.ndarray
    tcp_pos: np.ndarray
    deviation: np.ndarray
    saturated: np.ndarray
    speed_ratio: np.ndarray
    contacts: tuple[str, ...]
    joint_names: tuple[str, ...]

    def followed(self) -> float:
        """Share of frames where both TCPs are within :data:`FOLLOWED` of the commanded ones."""
        return float(np.mean(np.all(self.deviation <= FOLLOWED, axis=1)))

    def verdict(self) -> str:
        """One line: whether the robot would follow, and what stops it (the simulation lets a joint
        pass its speed limit, which a motor would not: that is a failure too)."""
        share = 100 * self.followed()
        fast = [n for j, n in enumerate(self.joint_names) if self.speed_ratio[:, j].max() > SPEED_SLACK]
        if self.followed() >= 0.99 and not fast:
            within = f"within {100 * FOLLOWED:.0f} cm ({share:.1f} % of frames)"
            return f"the simulated robot follows the commanded motion {within}"
        why = (
            [f"the TCPs within {100 * FOLLOWED:.0f} cm in only {share:.1f} % of frames"] if share < 99 else []
        )
        why += [f"{', '.join(fast)} over their speed limits"] if fast else []
        return f"NOT executable as commanded: {'; '.join(why)}"

    def lines(self) -> list[str]:
        """The report, one line per hand, then saturation and contacts."""
        out = []
        for a, side in enumerate(SIDES):
            d = self.deviation[:, a]
            over = int(np.count_nonzero(d > FOLLOWED))
            out.append(
                f"{side} TCP off the commanded one: median {100 * np.median(d):.2f} cm, "
                f"max {100 * d.max():.2f} cm, {over} of {len(d)} frames over {100 * FOLLOWED:.0f} cm"
            )
        hit = np.asarray(self.saturated.any(axis=0))
        joints = ", ".join(
            f"{n} ({100 * self.saturated[:, j].mean():.0f} %)"
            for j, n in enumerate(self.joint_names)
            if hit[j]
        )
        out.append(f"joints at their effort limit: {joints or 'none'}")
        peak = self.speed_ratio.max(axis=0)
        fast = ", ".join(
            f"{n} ({peak[j]:.2f} x)" for j, n in enumerate(self.joint_names) if peak[j] > SPEED_SLACK
        )
        out.append(f"joints over their speed limit: {fast or 'none'}")
        touching = sorted({c for c in self.contacts if c})
        frames = sum(bool(c) for c in self.contacts)
        out.append(f"contacts: {', '.join(touching) + f' in {frames} frames' if touching else 'none'}")
        return out


def commanded(traj: Trajectory, robot: Robot) -> tuple[np.ndarray, np.ndarray, float]:
    """What :func:`reference` reads: (T, n) the angles with unlimited joints unwound, (T + 2, n)
    the speed into each frame (at rest before the first) and after the last (a take may end
    moving: it goes on at its last speed), and the frame period, s."""
    n, dt = robot.dof, traj.period
    v = joint_velocity(traj, robot)
    q = traj.q[0] + np.cumsum(np.vstack([np.zeros((1, n)), v[1:] * dt]), axis=0)
    return q, np.vstack([v, v[-1:], v[-1:]]), dt


def reference(q: np.ndarray, velocity: np.ndarray, dt: float, k: int, u: float) -> tuple[np.ndarray, ...]:
    """(n,) position, velocity and acceleration of the commanded motion at ``u`` in [0, 1] of the
    way from frame ``k`` to ``k + 1``: the quadratic B-spline of the frames, whose acceleration is
    the trajectory's own second difference held for a frame period about each frame (so the
    controller is asked for exactly the accelerations :mod:`hlik.executable` checked, with no
    velocity jump); it passes through the midpoints between frames and within ``a dt^2 / 8`` of the
    frames themselves. ``q`` (T, n) angles unwound, ``velocity`` (T + 1, n) the speed into each
    frame and after the last (at rest before the first)."""
    tau = (u - 0.5) * dt  # from the midpoint between frames k and k + 1
    a = (velocity[k + 1] - velocity[k] if u < 0.5 else velocity[k + 2] - velocity[k + 1]) / dt
    mid = 0.5 * (q[k] + q[min(k + 1, len(q) - 1)])
    return mid + velocity[k + 1] * tau + 0.5 * a * tau**2, velocity[k + 1] + a * tau, a


def replay(traj: Trajectory, robot: Robot) -> Replay:
    """Play ``traj`` on ``robot`` through MuJoCo's physics (see the module docstring)."""
    T, n = traj.q.shape
    q, velocity, dt = commanded(traj, robot)
    model = robot.model.__copy__()
    model.opt.timestep = dt / SUBSTEPS
    data = mujoco.MjData(model)
    data.qpos[:] = traj.q[0]
    mujoco.mj_forward(model, data)
    control = inverse_model(model)
    law = mujoco.MjData(control)
    w, effort, ids = 2 * math.pi * BANDWIDTH, robot.effort_limit, [robot.site_id(s, "tcp") for s in SIDES]
    q_out, tcp, speed = np.empty((T, n)), np.empty((T, 2, 3)), np.empty((T, n))
    saturated, contacts = np.zeros((T, n), dtype=bool), [""] * T
    for k in range(T):  # the state at frame k, then the steps toward frame k + 1
        q_out[k], tcp[k], speed[k] = data.qpos, data.site_xpos[ids], np.abs(data.qvel) / robot.velocity_limit
        touching: set[str] = set()
        for s in range(SUBSTEPS if k + 1 < T else 0):
            pos, vel, acc = reference(q, velocity, dt, k, s / SUBSTEPS)
            law.qpos[:], law.qvel[:] = data.qpos, data.qvel
            law.qacc[:] = acc + w**2 * (pos - data.qpos) + 2 * w * (vel - data.qvel)
            mujoco.mj_inverse(control, law)
            tau = law.qfrc_inverse
            clipped = np.clip(tau, -effort, effort)
            saturated[k] |= clipped != tau
            data.qfrc_applied[:] = clipped
            mujoco.mj_step(model, data)
            touching |= _touching(model, data)
        contacts[k] = "; ".join(sorted(touching))
    deviation = np.linalg.norm(tcp - traj.tcp_pos, axis=-1)
    return Replay(q_out, tcp, deviation, saturated, speed, tuple(contacts), robot.joint_names)


def _touching(model: mujoco.MjModel, data: mujoco.MjData) -> set[str]:
    pairs = set()
    for c in data.contact[: data.ncon]:
        if c.dist < 0:
            a, b = sorted(model.body(model.geom_bodyid[g]).name for g in (c.geom1, c.geom2))
            pairs.add(f"{a}|{b}")
    return pairs
