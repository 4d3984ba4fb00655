"""The robots' inverse dynamics as the controller check (:mod:`hlik.executable`) and the
whole-take stage (:mod:`hlik.solvers.whole_take`) compute them, from the same finite differences
(:func:`motion_rates`): ``mujoco.mj_inverse`` with contacts,
joint limits and passive forces off (the models' joint damping is a simulation setting, not a
measured friction: :mod:`hlik.executable`)."""

from __future__ import annotations

import mujoco
import numpy as np

from hlik.robot.model import Robot

_D = mujoco.mjtDisableBit
_OFF = _D.mjDSBL_CONSTRAINT | _D.mjDSBL_SPRING | _D.mjDSBL_DAMPER  # contacts, limits; passive forces


def inverse_model(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of ``model`` for ``mj_inverse``: contacts, joint limits and
    passive forces off (the inverse model of this module)."""
    copy = model.__copy__()
    copy.opt.disableflags |= _OFF
    return copy


def inverse_dynamics(robot: Robot, q: np.ndarray, qvel: np.ndarray, qacc: np.ndarray) -> np.ndarray:
    """(T, n) joint torques (N m) of ``q``, ``qvel``, ``qacc`` (T, n) each, by ``mujoco.mj_inverse``
    with contacts and constraints off."""
    model = inverse_model(robot.model)
    data = mujoco.MjData(model)
    out = np.empty_like(q)
    for k in range(len(q)):
        data.qpos[:], data.qvel[:], data.qacc[:] = q[k], qvel[k], qacc[k]
        mujoco.mj_inverse(model, data)
        out[k] = data.qfrc_inverse
    return out


def motion_rates(steps: np.ndarray, dt: float, frames: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The finite differences of a motion of ``frames`` frames from its steps (T - 1, n), rad, at
    the frame period ``dt``, s: the velocity into each frame (T, n; 0 into the first: at rest
    before it), the central velocity at each frame (T, n; the last frame's the velocity into it)
    and the acceleration ``(v_t+1 - v_t) / dt`` (T, n; 0 at the last frame); rad/s, rad/s^2."""
    velocity = np.vstack([np.zeros((1, steps.shape[1])), steps / dt])
    accel = np.zeros((frames, steps.shape[1]))
    accel[:-1] = np.diff(velocity, axis=0) / dt
    central = 0.5 * (velocity + np.vstack([velocity[1:], velocity[-1:]]))
    return velocity, central, accel
