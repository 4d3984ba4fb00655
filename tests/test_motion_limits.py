"""Acceleration limits, braking before the stops, the stop margin and the torque rows
(hlik.solvers.limits): every optimising solver's frames stay inside them."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from conftest import ROBOTS, solve_problem
from hlik import load_robot
from hlik.executable import controller_checks
from hlik.human.demo import demo_motion
from hlik.problem.problem import build_problem
from hlik.retarget import trajectory_of
from hlik.robot.model import SIDES
from hlik.solvers import jv, qp, slsqp
from hlik.solvers.limits import MotionLimits, braking_speed, jerk_stop_distance
from hlik.solvers.mink_ik import MinkSolver
from hlik.solvers.settings import STOP_MARGIN, LimitSettings


def _mink_solve(problem, settings=None):
    import mink

    hands = [mink.FrameTask(f"{s}_tcp", "site", position_cost=10.0, orientation_cost=1.0) for s in SIDES]
    return MinkSolver(hands, [mink.ConfigurationLimit(problem.robot.model)])(problem)


SOLVES = {"qp": qp.solve, "jv": jv.solve, "slsqp": slsqp.solve, "mink": _mink_solve}


def _square_wave(problem, amplitude=(0.0, 0.25, 0.25), period=12):
    """The problem's targets jumping back and forth by ``amplitude`` (m) every ``period`` frames
    from frame 5 on: each joint has to reverse at the largest speed it can reach."""
    pos = problem.targets.pos.copy()
    k = np.arange(problem.n_frames)
    on = (k >= 5) & (((k - 5) // period) % 2 == 0)
    pos[on] += np.asarray(amplitude)
    return replace(problem.targets, pos=pos)


@pytest.mark.parametrize("solver", SOLVES)
@pytest.mark.parametrize("name", ROBOTS)
def test_a_target_reversing_at_full_speed_keeps_every_limit(name, solver):
    r = load_robot(name)
    motion = demo_motion().crop(1.0, 1.5).resample(100.0)
    problem = build_problem(motion, r)
    q, _ = solve_problem(SOLVES[solver], r, motion, _square_wave(problem), problem.placement)
    dt = problem.dt
    v = np.diff(q, axis=0) / dt
    dv = np.diff(np.vstack([np.zeros((1, r.dof)), v]), axis=0)  # at rest before the first frame
    assert np.all(np.abs(v) <= r.velocity_limit * (1 + 1e-9)), (name, solver)
    ratio = np.max(np.abs(dv) / (r.acceleration_limit * dt))
    # 1e-4: JV's steps come from a QP where the body is near (daqp's tolerance)
    assert ratio <= 1.0 + 1e-4, (name, solver, ratio)
    assert ratio > 0.99, "the reversals should drive some joint to its acceleration limit"
    assert np.all(q >= r.lower - 1e-9) and np.all(q <= r.upper + 1e-9)
    checks = controller_checks(trajectory_of(problem, q, solver), r)
    assert np.max(checks.acceleration_ratio) <= 1.0 + 1e-4 and checks.frames_over_effort == 0, (name, solver)
    # the frames run at the limit are reported, counted as the ratio says
    at_limit = checks.to_json()["share_at_acceleration_limit"]
    assert 0 < at_limit == np.mean(checks.acceleration_ratio >= 0.99), (name, solver)


@pytest.mark.parametrize("solver", ["qp", "jv", "slsqp"])
def test_a_panda_retargeted_at_1_khz_keeps_its_jerk_limits(solver):
    """A target reversing every 0.1 s at libfranka's control rate: no frame's jerk above the
    Panda's limits, as :func:`hlik.executable.controller_checks` measures it."""
    r = load_robot("dual_panda")
    motion = demo_motion().crop(1.0, 1.3).resample(1000.0)
    problem = build_problem(motion, r)
    q, _ = solve_problem(SOLVES[solver], r, motion, _square_wave(problem, period=100), problem.placement)
    checks = controller_checks(trajectory_of(problem, q, solver), r)
    assert checks.frames_over_jerk == 0, np.max(checks.jerk_ratio)
    assert np.max(checks.jerk_ratio) > 0.5, "the reversals should drive some joint near its jerk limit"


@pytest.mark.parametrize("solver", ["qp", "jv", "slsqp"])
def test_jerk_limits_that_bind_at_100_hz_are_kept_with_the_acceleration_limits(solver):
    """A robot whose jerk limits bind at the frame rate (a Panda at 1000 rad/s^3, 100 Hz) and a
    target reversing at full speed: jerk, acceleration and stops all kept. Braking before a stop
    at the acceleration limit alone had asked 20x it where the jerk limit could not turn round in
    time (a user's robot with a 0.6 rad wrist)."""
    r = load_robot("dual_panda")
    # and narrow wrists, 0.3 rad either side of home: the square wave drives them onto their stops
    narrow = np.isin(r.joint_names, ["left_joint7", "right_joint7", "left_joint5", "right_joint5"])
    lower, upper = np.where(narrow, r.home - 0.3, r.lower), np.where(narrow, r.home + 0.3, r.upper)
    r = replace(r, jerk_limit=np.full(r.dof, 1000.0), lower=lower, upper=upper)
    motion = demo_motion().crop(1.0, 2.0).resample(100.0)
    problem = build_problem(motion, r)
    q, _ = solve_problem(SOLVES[solver], r, motion, _square_wave(problem, period=25), problem.placement)
    checks = controller_checks(trajectory_of(problem, q, solver), r)
    assert checks.frames_over_acceleration == 0, np.max(checks.acceleration_ratio)
    assert checks.frames_over_jerk == 0, np.max(checks.jerk_ratio)
    assert np.max(checks.jerk_ratio) > 0.9, "the reversals should drive some joint to its jerk limit"
    assert np.all(q >= r.lower) and np.all(q <= r.upper)


@settings(max_examples=40, deadline=None)
@example(v=-1.0, a=-10.0, a_max=10.0, j_max=50.0)  # moving away, speeding away: 0 (CI's find)
@given(
    v=st.floats(-3.0, 3.0),
    a=st.floats(-20.0, 20.0),
    a_max=st.floats(1.0, 40.0),
    j_max=st.floats(50.0, 10000.0),
)
def test_the_jerk_stop_distance_is_the_time_optimal_braking_simulated(v, a, a_max, j_max):
    """jerk_stop_distance against the braking integrated in 10 us steps: the acceleration turned
    round at j_max to -a_max, held, until the speed is 0 (the largest excursion toward the stop)."""
    a = float(np.clip(a, -a_max, a_max))
    x, vel, acc, h, most = 0.0, v, a, 1e-5, 0.0
    for _ in range(2_000_000):
        if vel <= 0.0 and acc <= 0.0:
            break
        acc = max(acc - j_max * h, -a_max)
        x, vel = x + vel * h + 0.5 * acc * h * h, vel + acc * h
        most = max(most, x)
    got = float(jerk_stop_distance(np.array([v]), np.array([a]), np.array([a_max]), np.array([j_max]))[0])
    assert got == pytest.approx(most, abs=1e-4 + 1e-3 * most)


@settings(max_examples=20, deadline=None)
@given(
    name=st.sampled_from(ROBOTS),
    jerk=st.floats(100.0, 5000.0),
    seed=st.integers(0, 2**31 - 1),
    greedy=st.sampled_from(["up", "down", "random"]),
)
def test_a_walk_through_jerk_limited_boxes_keeps_every_limit_and_the_margin(name, jerk, seed, greedy):
    """Any jerk limit at 100 Hz (binding below 2 a_max / dt): any walk through the boxes keeps the
    jerk, acceleration and speed limits and never enters the stops' margin; driven at full effort
    toward a stop it comes to rest there."""
    r = load_robot(name)
    r = replace(r, jerk_limit=np.full(r.dof, jerk))
    limits = MotionLimits.of(r, LimitSettings(torque_limits=False))
    dt = 0.01
    for _, q, q1, q2, q3 in _walk(limits, dt, 600, greedy, np.random.default_rng(seed)):
        a, a1 = (q - 2 * q1 + q2) / dt**2, (q1 - 2 * q2 + q3) / dt**2
        assert np.all(np.abs(a - a1) / dt <= jerk * (1 + 1e-6) + 1e-6)
        assert np.all(np.abs(a) <= r.acceleration_limit * (1 + 1e-6))
        assert np.all(np.abs(q - q1) / dt <= r.velocity_limit * (1 + 1e-9))
        assert np.all(q <= limits.inner_upper + 1e-9) and np.all(q >= limits.inner_lower - 1e-9)
    if greedy != "random":
        limited = np.isfinite(r.lower)
        stop = limits.inner_upper if greedy == "up" else limits.inner_lower
        np.testing.assert_allclose(q[limited], stop[limited], atol=1e-4)


def test_every_bundled_robot_has_acceleration_and_effort_limits():
    for name in ROBOTS:
        r = load_robot(name)
        assert np.all(np.isfinite(r.acceleration_limit)) and np.all(r.acceleration_limit > 0), name
        assert np.all(np.isfinite(r.effort_limit)) and np.all(r.effort_limit > 0), name
        assert r.acceleration_source and r.effort_source, name
    panda = load_robot("dual_panda")  # the one with published jerk limits (libfranka)
    assert np.all(np.isfinite(panda.jerk_limit)) and "libfranka" in panda.jerk_source


def _walk(limits, dt: float, steps: int, greedy: str, rng):
    """A walk through the frames' boxes of ``limits`` from home (clipped into the margin): each
    frame's configuration at the top of its box (``up``), the bottom (``down``) or anywhere in it
    (``random``); yields the box, the configuration and the three before it, newest first."""
    r = limits.robot
    q3 = q2 = q1 = np.clip(r.home, limits.inner_lower, limits.inner_upper)
    for _ in range(steps):
        box = limits.box(q1, q2, dt, q3=q3)
        if greedy == "up":
            q = box.upper.copy()
        elif greedy == "down":
            q = box.lower.copy()
        else:
            q = box.lower + rng.random(r.dof) * (box.upper - box.lower)
        q = np.where(np.isfinite(q), q, q1)  # unlimited joints: any finite choice
        yield box, q, q1, q2, q3
        q3, q2, q1 = q2, q1, q


@settings(max_examples=30, deadline=None)
@given(
    name=st.sampled_from(ROBOTS),
    seed=st.integers(0, 2**31 - 1),
    greedy=st.sampled_from(["up", "down", "random"]),
)
def test_a_walk_through_the_boxes_never_breaks_a_limit_and_brakes_before_the_stops(name, seed, greedy):
    """Any sequence of configurations chosen inside the frames' boxes keeps speed, acceleration and
    the stops; one driven at full effort toward a stop comes to rest inside the margin."""
    r = load_robot(name)
    limits = MotionLimits.of(r, LimitSettings(torque_limits=False))
    dt = 0.01
    for box, q, q1, q2, q3 in _walk(limits, dt, 400, greedy, np.random.default_rng(seed)):
        assert np.all(box.lower <= box.upper + 1e-12)
        v, v1 = (q - q1) / dt, (q1 - q2) / dt
        assert np.all(np.abs(v) <= r.velocity_limit * (1 + 1e-9))
        assert np.all(np.abs(v - v1) <= r.acceleration_limit * dt * (1 + 1e-9) + 1e-12)
        assert np.all(q >= r.lower - 1e-12) and np.all(q <= r.upper + 1e-12)
        # never past the margin, and never faster toward it than it can still stop
        assert np.all(q <= limits.inner_upper + 1e-9) and np.all(q >= limits.inner_lower - 1e-9)
        jerk = np.abs((q - 2 * q1 + q2) - (q1 - 2 * q2 + q3)) / dt**3
        assert np.all(jerk <= r.jerk_limit * (1 + 1e-9))
    if greedy != "random":  # 4 s at full effort: every limited joint has come to rest at the margin
        limited = np.isfinite(r.lower)
        stop = limits.inner_upper if greedy == "up" else limits.inner_lower
        np.testing.assert_allclose(q[limited], stop[limited], atol=1e-6)
        assert np.max(np.abs(q - q1)[limited]) / dt < 1e-3


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), greedy=st.sampled_from(["up", "down", "random"]))
def test_at_the_pandas_1_khz_the_boxes_keep_its_jerk_limits(seed, greedy):
    """At libfranka's 1 kHz the Panda's jerk limits bind (at 100 Hz its acceleration limits imply
    them): any walk through the boxes keeps them, and the speed and acceleration limits, and the
    stops' margin (braking as the jerk lets it: before, it overran the 3 deg margin by 0.2 deg)."""
    r = load_robot("dual_panda")
    limits = MotionLimits.of(r, LimitSettings(torque_limits=False))
    dt = 0.001
    for _, q, q1, q2, q3 in _walk(limits, dt, 3000, greedy, np.random.default_rng(seed)):
        a, a1 = (q - 2 * q1 + q2) / dt**2, (q1 - 2 * q2 + q3) / dt**2
        assert np.all(np.abs(a - a1) / dt <= r.jerk_limit * (1 + 1e-6))
        assert np.all(np.abs(a) <= r.acceleration_limit * (1 + 1e-6))
        assert np.all(np.abs(q - q1) / dt <= r.velocity_limit * (1 + 1e-9))
        assert np.all(q >= r.lower) and np.all(q <= r.upper)
        assert np.all(q <= limits.inner_upper + 1e-9) and np.all(q >= limits.inner_lower - 1e-9)


def test_the_braking_speed_stops_in_front_of_the_stop():
    a, dt = np.array([20.0, 7.5, np.inf]), 0.01
    d = np.array([0.1, 0.02, 0.1])
    v = braking_speed(d, a, dt)
    assert np.isinf(v[2])
    # after the step, sqrt(2 a (d - v dt)) is exactly v: it can still stop
    np.testing.assert_allclose(v[:2] ** 2, 2 * a[:2] * (d[:2] - v[:2] * dt))
    np.testing.assert_array_equal(braking_speed(np.array([-0.1]), np.array([20.0]), dt), [0.0])


def _with_payload(r, kg: float):
    """``r`` with ``kg`` at each hand (a point mass at the TCP body's origin, inertia kept small)."""
    model = r.model.__copy__()
    for side in ("left", "right"):
        body = model.site_bodyid[r.site_id(side, "tcp")]
        model.body_mass[body] += kg
        model.body_inertia[body] += kg * 1e-3
    mujoco.mj_setConst(model, mujoco.MjData(model))
    return replace(r, model=model)


def test_the_torque_rows_keep_a_heavy_payload_within_the_effort_limits():
    r = _with_payload(load_robot("dual_panda"), 2.5)
    motion = demo_motion().crop(1.0, 2.0).resample(100.0)
    problem = build_problem(motion, r)
    targets = _square_wave(problem, amplitude=(0.0, 0.3, 0.3), period=15)
    ratios = {}
    for on in (False, True):
        s = qp.QPSettings(torque_limits=on)
        q, _ = solve_problem(qp.solve, r, motion, targets, problem.placement, s)
        ratios[on] = controller_checks(trajectory_of(problem, q, "qp"), r).torque_ratio.max()
    assert ratios[False] > 1.0, "the payload should overload a joint without the torque rows"
    assert ratios[True] <= 1.0 + 1e-6, ratios


def _closest_pair(r, q) -> float:
    """The smallest distance between the robot's collision pairs at ``q`` (m; 1 if none is near)."""
    from hlik.robot.collision import collision_pairs, pair_distances

    pairs, data = collision_pairs(r), mujoco.MjData(r.model)
    data.qpos[:] = q
    mujoco.mj_kinematics(r.model, data)
    mujoco.mj_comPos(r.model, data)
    dist, _ = pair_distances(r, data, pairs, 1.0)
    return float(dist.min()) if len(dist) else 1.0


@pytest.mark.parametrize("solver", ["qp", "jv", "slsqp"])
@pytest.mark.parametrize("name", ROBOTS)
def test_hands_sent_into_each_other_brake_before_the_margin(name, solver):
    """Both hand targets slide to the point between the hands in 0.3 s (a closing speed of about
    1 m/s, a fast human clap): the arms must brake in time and stop at the collision margin
    within the acceleration and torque limits (the damper alone stopped them within a frame, or
    gave up the limits to do it). Closings faster than the arms can brake from where the pair is
    first looked for are not covered (README, "Executable motion")."""
    r = load_robot(name)
    motion = demo_motion().crop(1.0, 1.8).resample(100.0)
    problem = build_problem(motion, r)
    pos = problem.targets.pos.copy()
    share = np.clip((np.arange(len(pos)) - 5) / 30.0, 0.0, 1.0)[:, None, None]
    pos = (1 - share) * pos + share * pos.mean(axis=1, keepdims=True)
    q, _ = solve_problem(SOLVES[solver], r, motion, replace(problem.targets, pos=pos), problem.placement)
    checks = controller_checks(trajectory_of(problem, q, solver), r)
    assert np.max(checks.acceleration_ratio) <= 1.0 + 1e-4 and checks.frames_over_effort == 0, (name, solver)
    # the frames run at the limit are reported, counted as the ratio says
    at_limit = checks.to_json()["share_at_acceleration_limit"]
    assert 0 < at_limit == np.mean(checks.acceleration_ratio >= 0.99), (name, solver)
    margin = qp.QPSettings().collision_margin
    closest = np.array([_closest_pair(r, x) for x in q])
    assert closest.min() >= min(margin, closest[0]) - 1e-3, (name, solver, closest.min())
    assert closest[5:].min() < 0.05, "the hands should come close"


@pytest.mark.parametrize("name", ROBOTS)
def test_joints_parked_on_the_solvers_margin_are_counted(name):
    """The controller check counts a joint within 3.5° of a stop (the solvers' 3° margin) per joint,
    as the margin itself: a joint held at the margin (as the QP holds one against its soft stop) is
    counted, one a degree further in is not, and JM's joints on their hard stops are counted in both."""
    r = load_robot(name)
    motion = demo_motion().crop(1.0, 1.5).resample(100.0)
    problem = build_problem(motion, r)
    limited = np.flatnonzero(np.isfinite(r.lower))
    j, k = limited[0], limited[-1]
    q = np.tile(r.home, (problem.n_frames, 1))
    q[10:30, j] = r.lower[j] + STOP_MARGIN  # parked on the margin for 20 frames
    q[:, k] = r.upper[k] - STOP_MARGIN - np.radians(1.0)  # inside, by a degree more
    checks = controller_checks(trajectory_of(problem, q, "qp"), r)
    assert checks.at_margin[:, j].sum() == 20 and not checks.at_margin[:, k].any()
    assert checks.share_at_margin == pytest.approx(checks.at_margin.any(axis=1).mean())
    summary = checks.to_json()
    parked = checks.at_margin.mean(axis=0)
    assert summary["margin_joint_share"] == pytest.approx(parked.max())
    assert parked[r.index(summary["margin_joint"])] == parked.max() >= 20 / problem.n_frames
    q[40:, j] = r.lower[j]  # on the hard stop: in both counts
    on_stop = controller_checks(trajectory_of(problem, q, "jm"), r)
    assert on_stop.at_stop[40:].all() and on_stop.at_margin[40:, j].all()
