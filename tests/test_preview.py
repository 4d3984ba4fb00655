"""The look-ahead (hlik.solvers.preview): a joint path within the speed, acceleration and stop
limits, nearest to the unlimited solution, that starts a motion before its target does; and the QP
and SLSQP with it keep every limit of the frame box."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hlik import load_robot
from hlik.solvers.limits import MotionLimits
from hlik.solvers.preview import HEADROOM, PathTask, PathTerm, feasible_path
from hlik.solvers.settings import QPSettings, SLSQPSettings

DT = 0.01


@pytest.fixture(scope="module")
def panda():
    return load_robot("dual_panda")


def _keeps_every_limit(traj, robot) -> None:
    """No failed frame, and the accelerations and torques a controller sees within their limits."""
    from hlik.executable import controller_checks

    checks = controller_checks(traj, robot)
    assert checks.acceleration_ratio.max() <= 1.0 + 1e-6
    assert checks.torque_ratio.max() <= 1.0 + 1e-6
    assert not np.any(traj.diagnostics.failed)


def _rates(path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.abs(np.diff(path, axis=0)) / DT, np.abs(np.diff(path, 2, axis=0)) / DT**2


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(0.005, 0.08))
def test_the_path_keeps_the_stops_speeds_and_accelerations(panda, seed, scale):
    """Any joint motion, however fast (a random walk of up to 8 rad/s steps): the path keeps the
    stops with their margin, and its speed and acceleration stay within the limits (the fit within
    :data:`HEADROOM` of them, the spline between its knots a little above)."""
    rng = np.random.default_rng(seed)
    q = panda.home + np.cumsum(rng.normal(scale=scale, size=(300, panda.dof)), axis=0)
    limits = MotionLimits.of(panda, QPSettings())
    path = feasible_path(q, limits, DT)
    assert path.shape == q.shape
    assert np.all(path >= limits.inner_lower - 1e-9) and np.all(path <= limits.inner_upper + 1e-9)
    speed, acceleration = _rates(path)
    assert np.all(speed <= limits.velocity + 1e-6)
    assert np.all(acceleration <= limits.acceleration + 1e-6)
    np.testing.assert_allclose(path[0], np.clip(q[0], limits.inner_lower, limits.inner_upper), atol=1e-6)


def test_a_slow_motion_is_its_own_path(panda):
    """Well inside every limit, a motion that starts at rest is its own nearest path (to the
    spline's error)."""
    t = np.arange(200) * DT
    q = panda.home + 0.05 * (1 - np.cos(2 * np.pi * 0.5 * t))[:, None]  # inside the stops
    path = feasible_path(q, MotionLimits.of(panda, QPSettings()), DT)
    assert np.abs(path - q).max() < 1e-3


def test_a_take_cut_mid_motion_gets_a_path_that_starts_at_rest_where_it_does(panda):
    """The solvers start at the first frame at rest (a span of a take starts mid-motion): the path
    starts there too, at rest, and joins the motion within its limits, instead of already moving
    (2-Panda, Cut take 2-6 s: the QP, pulled toward a path moving at 1.2 rad/s from the first frame,
    caught up with it by swinging the hand about a still target, up to 2 cm for a second)."""
    t = np.arange(200) * DT
    q = panda.home + 0.1 * np.sin(2 * np.pi * 0.5 * t)[:, None]  # 0.31 rad/s at the first frame
    limits = MotionLimits.of(panda, QPSettings())
    path = feasible_path(q, limits, DT)
    np.testing.assert_allclose(path[0], q[0], atol=1e-9)
    speed, acceleration = _rates(path)
    assert np.all(speed[0] <= HEADROOM * limits.jerk * DT**2 / 6 + 1e-9)  # at rest: a jerk's start
    assert np.all(acceleration <= limits.acceleration + 1e-6)
    assert np.abs(path[50:] - q[50:]).max() < 1e-3  # on the motion within half a second


def test_the_path_starts_a_fast_move_before_its_target_does(panda):
    """A joint told to jump 0.5 rad at 1 s: a frame-by-frame solver starts at 1 s; the path, fitted
    over the whole take, is already moving before, and arrives no later than its limits allow."""
    q = np.tile(panda.home, (200, 1))
    q[100:, 0] += 0.5
    limits = MotionLimits.of(panda, QPSettings())
    path = feasible_path(q, limits, DT)
    assert path[90, 0] > panda.home[0] + 0.01  # moving 0.1 s before the jump
    assert abs(path[-1, 0] - q[-1, 0]) < 1e-3  # and there in the end
    # half the jump is passed about at the jump: the least-squares path is symmetric about it
    assert 95 <= np.argmax(path[:, 0] > panda.home[0] + 0.25) <= 105
    assert HEADROOM < 1.0


def test_the_path_task_aims_at_its_frame(panda):
    path = np.tile(panda.home, (5, 1)) + np.arange(5)[:, None] * 0.01
    task = PathTask(panda.model, path, cost=3.0)
    for k in (0, 3):
        task.at(k)
        np.testing.assert_allclose(task.target_q, path[k])


def test_the_qp_with_look_ahead_keeps_every_limit(cut_take, panda):
    """Both passes on 1.5 s of the Cut take: the second keeps the frame box (acceleration, torque,
    stops) in every frame, with the hands on target."""
    from hlik.human.load import load_motion
    from hlik.retarget import retarget
    from hlik.solvers.qp import qp_solver

    motion = load_motion(cut_take, rate=100.0).crop(1.0, 2.5)
    traj = retarget(motion, panda, qp_solver(QPSettings(preview_cost=3.0)))
    _keeps_every_limit(traj, panda)
    assert np.median(np.linalg.norm(traj.tcp_pos - traj.targets.pos, axis=-1)) < 0.01


def test_the_path_fit_prints_nothing(panda, capfd):
    """OSQP's C library writes to stdout for some settings, and its Python side warns on sparse
    arrays: neither may reach a user's terminal or a piped summary."""
    import warnings

    q = np.tile(panda.home, (120, 1))
    q[60:, 3] += 0.4
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        feasible_path(q, MotionLimits.of(panda, QPSettings()), DT)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_a_look_ahead_from_the_hands_first_turns_the_hands_less_within_every_limit(cut_take, panda):
    """``preview_hands_first`` (2-Panda's default in ``ee_pose``): the path comes from a pass that
    holds the hands first, so with SYN + HJA^r on 1.5 s of the Cut take the hands turn less off
    their targets than with a weighted first pass (median 5.0 -> 2.6 deg when written), and the
    second pass still keeps the acceleration and torque limits."""
    from hlik.criteria.functional import rotation_angle
    from hlik.criteria.learned import learn
    from hlik.human.load import load_motion
    from hlik.retarget import retarget
    from hlik.solvers.qp import qp_solver

    motion = load_motion(cut_take, rate=100.0).crop(1.0, 2.5)
    turned = {}
    for first in (False, True):
        settings = QPSettings(criteria=("SYN", "HJA_r"), preview_hands_first=first)
        traj = retarget(motion, panda, qp_solver(settings), learned=learn(panda))
        _keeps_every_limit(traj, panda)
        turned[first] = np.median(rotation_angle(traj.tcp_rot, traj.targets.rot))
    assert turned[True] < 0.75 * turned[False], np.degrees([turned[False], turned[True]])


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(0, 4))
def test_the_path_term_is_the_distance_to_its_frame(seed, k):
    """SLSQP's :class:`PathTerm` after ``at(k)``: the residual is ``q - path[k]``, an angle's
    difference on ARMAR-6's unlimited joints (a turn away is no distance), its Jacobian equals
    finite differences, and its cost is the residual's norm."""
    from hlik.criteria.angles import wrap
    from hlik.robot.state import robot_state

    robot = load_robot("armar6")
    rng = np.random.default_rng(seed)
    path = robot.home + rng.normal(scale=0.3, size=(5, robot.dof))
    q = path[k] + rng.normal(scale=0.2, size=robot.dof)
    q[np.isinf(robot.lower)] += 2 * np.pi  # a whole turn on the unlimited joints
    term = PathTerm(robot, path)
    term.at(k)
    e, jac = term(robot_state(robot, q[None]), None)
    expected = q - path[k]
    unlimited = np.isinf(robot.lower)
    expected[unlimited] = wrap(expected[unlimited])
    np.testing.assert_allclose(e, expected, atol=1e-12)
    step = 1e-6
    numeric = np.stack(
        [
            (term(robot_state(robot, (q + step * np.eye(robot.dof)[j])[None]), None)[0] - e) / step
            for j in range(robot.dof)
        ],
        axis=1,
    )
    np.testing.assert_allclose(jac, numeric, atol=1e-6)
    np.testing.assert_allclose(term.cost(e[None])[0], np.linalg.norm(expected))


def test_slsqp_with_look_ahead_follows_its_path_within_every_limit(cut_take, panda, monkeypatch):
    """SLSQP's look-ahead on 1.5 s of the Cut take (2-Panda, SYN + HJA^r): the second pass keeps
    the acceleration and torque limits with no failed frame and the hands on target, and stays
    nearer the path than one pass without it does (the loss pulls; median distance, rad)."""
    from hlik.criteria.learned import learn
    from hlik.human.load import load_motion
    from hlik.retarget import retarget
    from hlik.solvers import preview, slsqp

    paths = []

    def kept(q, *args, **kwargs):
        paths.append(feasible_path(q, *args, **kwargs))
        return paths[-1]

    monkeypatch.setattr(preview, "feasible_path", kept)
    motion = load_motion(cut_take, rate=100.0).crop(1.0, 2.5)
    learned = learn(panda)
    distance = {}
    for pull in (0.0, 30.0):
        settings = SLSQPSettings(criteria=("SYN", "HJA_r"), preview_cost=pull)
        traj = retarget(motion, panda, slsqp.slsqp_solver(settings), learned=learned)
        _keeps_every_limit(traj, panda)
        assert np.median(np.linalg.norm(traj.tcp_pos - traj.targets.pos, axis=-1)) < 0.01
        distance[pull] = traj.q
    (path,) = paths  # one pass without the pull, two with it
    near = {pull: np.median(np.linalg.norm(q - path, axis=1)) for pull, q in distance.items()}
    # 0.064 -> 0.019 rad when written
    assert near[30.0] < 0.5 * near[0.0], near


def test_slsqp_objective_gradient_with_the_path_loss_equals_finite_differences(panda):
    """The groove loss on :class:`PathTerm` in SLSQP's objective: its analytic gradient (from the
    term's identity Jacobian) equals forward differences of the objective, off the path and near it
    (inside the groove's well, |q - path| < 0.1 rad)."""
    from hlik.criteria.base import Sample
    from hlik.solvers.slsqp import Loss, Objective

    eye = np.tile(np.eye(3), (2, 1, 1))
    home = panda.home
    sample = Sample.one(np.zeros((2, 3)), eye, home, np.zeros(2), eye, np.tile(home, (3, 1)), 0.01)
    rng = np.random.default_rng(3)
    path = panda.home + rng.normal(scale=0.2, size=(4, panda.dof))
    term = PathTerm(panda, path)
    objective = Objective(panda, [Loss(term, 30.0, 1.0)], fd_step=1e-7, precondition="none")
    for k, scale in ((1, 0.3), (2, 0.01)):
        term.at(k)
        q = path[k] + rng.normal(scale=scale, size=panda.dof)
        objective.reset(sample)
        f, grad = objective.value_and_gradient(q)
        np.testing.assert_allclose(
            grad, objective.fd_gradient(q, f), rtol=1e-4, atol=1e-4 * np.abs(grad).max()
        )
