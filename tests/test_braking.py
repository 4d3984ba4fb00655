"""The braking frames an export appends (hlik/braking.py): a trajectory that ends moving is brought
to rest within the speed, acceleration and jerk limits and the joints' ranges, as the controller
check differences it, on every bundled robot."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hlik import load_motion, load_robot, retarget
from hlik.braking import braking, brought_to_rest, end_state, hand_travel
from hlik.executable import controller_checks, joint_velocity
from hlik.export import first_violation
from hlik.robot.model import tcp_poses
from hlik.util.paths import demo_motion_path

ROBOTS = ("armar3", "armar6", "dual_panda")
DT = 0.01


@functools.cache
def _take(name: str):
    """A short QP run of the demo on ``name``, for its Trajectory's fields (the ends are replaced)."""
    robot = load_robot(name)
    return robot, retarget(load_motion(demo_motion_path(), rate=100).crop(0, 0.3), robot, "qp")


def _ending(name: str, q: np.ndarray, v: np.ndarray, a: np.ndarray):
    """A trajectory whose last frame is ``q`` (n,), moving into it at ``v`` after accelerating at
    ``a`` (the controller check's differences), preceded by frames at rest."""
    robot, traj = _take(name)
    q1 = q - v * DT
    q0 = q1 - (v - a * DT) * DT
    frames = np.vstack([np.repeat(q0[None], traj.n_frames - 2, axis=0), q1, q])
    pos, rot = tcp_poses(robot, frames)
    return robot, dataclasses.replace(traj, q=frames, tcp_pos=pos, tcp_rot=rot)


def _limits_from(robot, traj, start: int) -> None:
    """Speeds, accelerations and jerks within their limits from frame ``start`` on, and the
    trajectory at rest at its end (its last frame held as a controller does)."""
    held = dataclasses.replace(
        traj, q=np.vstack([traj.q, traj.q[-1:]]), times=np.r_[traj.times, traj.times[-1] + DT]
    )
    checks = controller_checks(held, robot)
    assert np.all(np.abs(joint_velocity(held, robot)[start:]) <= robot.velocity_limit * (1 + 1e-9))
    assert checks.acceleration_ratio[start:].max() <= 1 + 1e-6
    assert checks.jerk_ratio[start:].max() <= 1 + 1e-6
    assert np.all((traj.q >= robot.lower) & (traj.q <= robot.upper))


def _middle(robot) -> np.ndarray:
    """(n,) each joint's mid-range, rad (0 for a joint without stops)."""
    middle = np.zeros(robot.dof)
    limited = np.isfinite(robot.lower)
    middle[limited] = 0.5 * (robot.lower[limited] + robot.upper[limited])
    return middle


@st.composite
def _end_states(draw):
    name = draw(st.sampled_from(ROBOTS))
    robot, _ = _take(name)
    n = robot.dof
    unit = lambda: np.array(draw(st.lists(st.floats(-1, 1), min_size=n, max_size=n)))  # noqa: E731
    limited = np.isfinite(robot.lower)
    width = np.where(limited, robot.upper - robot.lower, 2 * np.pi)
    middle = _middle(robot)
    q = middle + 0.25 * width * unit()  # in the middle half of each range
    # slow enough to brake within a quarter of the range at half the acceleration limit
    v_max = np.minimum(robot.velocity_limit, np.sqrt(0.25 * width * robot.acceleration_limit))
    return name, q, 0.8 * v_max * unit(), 0.5 * robot.acceleration_limit * unit()


@given(_end_states())
@settings(max_examples=40, deadline=None)
def test_a_trajectory_ending_moving_comes_to_rest_within_every_limit(state):
    name, q, v, a = state
    robot, traj = _ending(name, q, v, a)
    np.testing.assert_allclose(np.stack(end_state(traj.q, DT, np.isinf(robot.lower))), [v, a], atol=1e-6)
    rest, stop = brought_to_rest(traj, robot)
    assert stop.inside and rest.n_frames == traj.n_frames + stop.n_frames
    assert (stop.n_frames > 0) == bool(np.any(v) or np.any(a))
    np.testing.assert_array_equal(rest.q[: traj.n_frames], traj.q)
    if stop.n_frames:  # the hands' travel while braking, by forward kinematics of the frames
        moved = np.linalg.norm(tcp_poses(robot, stop.q)[0] - traj.tcp_pos[-1], axis=-1).max()
        assert hand_travel(rest, stop.n_frames) == pytest.approx(moved, abs=1e-12)
    # from the junction on (before it, the take's own), the last frame held: at rest within the limits
    _limits_from(robot, rest, traj.n_frames - 1)
    # no slower than needed: the fastest joint's speed at its own acceleration limit, plus the
    # jerk ramps and a frame's rounding
    ramp = np.where(np.isfinite(robot.jerk_limit), 2 * robot.acceleration_limit / robot.jerk_limit, 0)
    bound = np.abs(v) / robot.acceleration_limit + np.abs(a) / robot.acceleration_limit + ramp
    assert stop.n_frames * DT <= bound.max() + 2 * DT


@pytest.mark.parametrize("name", ROBOTS)
def test_joints_moving_and_accelerating_along_one_line_stop_on_it(name):
    """Stopping together, joints moving and accelerating along one line in joint space stay on it
    (within 0.2°: Ruckig keeps it exactly only for an exactly parallel state, and differences
    leave it parallel to 1e-12), so the hands run on along their path."""
    robot, _ = _take(name)
    rng = np.random.default_rng(3)
    direction = rng.normal(size=robot.dof)
    direction *= 0.3 * np.min(robot.velocity_limit / np.abs(direction))
    q = _middle(robot)
    robot, traj = _ending(name, q, direction, -2.0 * direction)
    stop = braking(traj, robot)
    assert stop.synchronised and stop.n_frames > 1
    moved = stop.q - q
    cosine = moved @ direction / (np.linalg.norm(moved, axis=1) * np.linalg.norm(direction))
    assert np.all(cosine > np.cos(np.radians(0.2)))


def test_a_joint_near_its_stop_brakes_on_its_own_where_the_line_would_pass_it():
    """2-Panda: one joint fast (a long stop), another slow toward a stop it can brake short of
    alone but not while stopping with the first: each joint brakes on its own, inside its range."""
    robot, _ = _take("dual_panda")
    fast, slow = robot.joint_names.index("left_joint1"), robot.joint_names.index("left_joint4")
    q, v = 0.5 * (robot.lower + robot.upper), np.zeros(robot.dof)
    v[fast], v[slow] = 2.0, 0.3
    alone = v[slow] ** 2 / (2 * robot.acceleration_limit[slow])  # rad the slow joint needs alone
    q[slow] = robot.upper[slow] - 3 * alone
    robot, traj = _ending("dual_panda", q, v, np.zeros(robot.dof))
    stop = braking(traj, robot)
    assert not stop.synchronised and stop.inside
    rest, _ = brought_to_rest(traj, robot)
    _limits_from(robot, rest, traj.n_frames - 1)


def test_a_trajectory_at_rest_gets_no_frames_and_passes_the_end_check():
    robot, traj = _take("armar6")
    still = dataclasses.replace(traj, q=np.repeat(traj.q[-1:], traj.n_frames, axis=0))
    assert braking(still, robot).n_frames == 0 and brought_to_rest(still, robot)[0] is still
    assert first_violation(still, robot) is None


def test_the_end_check_names_a_trajectory_that_ends_moving_faster_than_a_frame_can_stop():
    """Held after its last frame, 1 rad/s must vanish in 10 ms: 100 rad/s^2, over every robot's
    limit; the braking frames remove it."""
    robot, traj = _take("dual_panda")
    speed = np.minimum(10.0 * (traj.times - traj.times[0]), 1.0)  # up to 1 rad/s at 10 rad/s^2
    q = np.repeat(0.5 * (robot.lower + robot.upper)[None], traj.n_frames, axis=0)
    q[:, 0] += np.cumsum(speed) * DT
    traj = dataclasses.replace(traj, q=q)
    robot = dataclasses.replace(robot, effort_limit=np.full(robot.dof, np.inf))  # the joints alone
    message = first_violation(traj, robot)
    last = traj.n_frames - 1
    assert message is not None and message.startswith(f"frame {last}, the last, held after it")
    assert f"joint {robot.joint_names[0]} acceleration 100 rad/s^2" in message
    assert first_violation(brought_to_rest(traj, robot)[0], robot) is None


@pytest.mark.parametrize("name", ROBOTS)
def test_a_joint_at_its_speed_limit_still_accelerating_brakes_within_it(name):
    """The take's last step at the speed limit, accelerating at nearly its limit into it (within
    every limit so far, as the differences see it): the braking starts at the limit, not above
    (a fresh helper's case: 2-Panda's left_joint1 went 2.22 rad/s over its 2.175)."""
    robot, _ = _take(name)
    v, a = np.zeros(robot.dof), np.zeros(robot.dof)
    v[0], a[0] = robot.velocity_limit[0], 0.97 * robot.acceleration_limit[0]
    q = _middle(robot)
    q[0] = robot.lower[0] + 0.25 * (robot.upper[0] - robot.lower[0])  # room ahead to brake
    robot, traj = _ending(name, q, v, a)
    rest, stop = brought_to_rest(traj, robot)
    assert stop.n_frames > 0
    _limits_from(robot, rest, traj.n_frames - 1)


@pytest.mark.parametrize("jerk", [300.0, 1000.0])
@pytest.mark.parametrize("name", ROBOTS)
def test_where_the_jerk_limit_binds_the_braking_keeps_the_speed_limit_too(name, jerk):
    """The same end at a jerk limit that binds at 100 Hz: Ruckig's continuous profile, sampled,
    ran 0.4-1.2 % over the speed limit while the acceleration turned round (a fresh helper's robot
    at 300 rad/s^3; its JV export was refused for hlik's own braking). Held to the solvers' frame
    box, re-planned where the box moves a frame: every limit as the check differences it."""
    robot, traj = _take(name)
    robot = dataclasses.replace(robot, jerk_limit=np.full(robot.dof, jerk))
    j = np.flatnonzero(np.isfinite(robot.lower))[:2]  # two joints with stops, moving toward them
    v, a = np.zeros(robot.dof), np.zeros(robot.dof)
    v[j], a[j] = robot.velocity_limit[j], 0.97 * robot.acceleration_limit[j]
    q = _middle(robot)
    q[j] = robot.lower[j] + 0.25 * (robot.upper[j] - robot.lower[j])
    _, traj = _ending(name, q, v, a)
    rest, stop = brought_to_rest(traj, robot)
    assert stop.n_frames > 0 and stop.inside
    _limits_from(robot, rest, traj.n_frames)  # the take's own end jumps into its acceleration
