"""The shared frame loop: its iteration (convergence, the damping of flip-flopping steps) and the
constrained steps a frame falls back on."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hlik.solvers.frames import COLLISION_PENALTY, JointBox, constrained_steps, iterate
from hlik.solvers.qp_backend import solve_qp


def test_a_step_that_flips_back_and_forth_is_damped_to_the_fixed_point():
    """A Gauss-Newton step that overshoots by exactly twice the error (``-2 (q - c)``) flips between
    two points forever; halving on each reversal converges to c."""
    c = np.array([0.3, -0.2])
    box = JointBox(np.full(2, -1.0), np.full(2, 1.0))
    flip = lambda q: -2.0 * (q - c)  # noqa: E731
    plain = iterate(flip, np.zeros(2), box, max_iter=50, tol=1e-6)
    damped = iterate(flip, np.zeros(2), box, max_iter=50, tol=1e-6, damp_reversals=True)
    assert not plain.converged and plain.iterations == 50
    assert damped.converged and damped.iterations < 50
    np.testing.assert_allclose(damped.q, c, atol=1e-5)


def test_damping_leaves_a_monotone_iteration_alone():
    c = np.array([0.5, 0.1, -0.4])
    box = JointBox(np.full(3, -1.0), np.full(3, 1.0))
    newton = lambda q: -0.5 * (q - c)  # noqa: E731
    plain = iterate(newton, np.zeros(3), box, max_iter=100, tol=1e-8)
    damped = iterate(newton, np.zeros(3), box, max_iter=100, tol=1e-8, damp_reversals=True)
    assert plain.iterations == damped.iterations
    np.testing.assert_array_equal(plain.q, damped.q)


def test_soft_rows_are_missed_as_little_as_the_bounds_allow():
    """Rows no step can meet (x0 <= -1 and x0 >= 1) are missed equally at equal penalties; a
    feasible row is kept as if it were hard, to the penalty's precision."""
    hessian, gradient = np.eye(2), np.array([0.0, -1.0])
    lower, upper = np.full(2, -2.0), np.full(2, 2.0)
    rows, bound = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]]), np.array([-1.0, -1.0, 0.5])
    assert solve_qp(hessian, gradient, lower, upper, "daqp", rows, bound) is None
    x = solve_qp(hessian, gradient, lower, upper, "daqp", rows, bound, np.full(3, COLLISION_PENALTY))
    np.testing.assert_allclose(x, [0.0, 0.5], atol=1e-5)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_the_last_constrained_step_is_always_feasible_and_keeps_the_box(seed):
    """(3) of :func:`constrained_steps`, the collision and torque rows soft, has a solution for any
    rows, inside the step bounds; the first try keeps every row hard."""
    rng = np.random.default_rng(seed)
    n = 5
    q = rng.uniform(-1, 1, n)
    half = rng.uniform(1e-3, 0.05, n)
    rows = rng.normal(size=(2, n))
    box = JointBox(q - half, q + half, rows, rows @ q + rng.normal(0, 0.05, 2))
    a_col, b_col = rng.normal(size=(3, n)), rng.normal(0, 0.05, 3)
    tries = constrained_steps(box, q, 0.2, a_col, b_col)
    assert tries[0].soft is None and len(tries) == 3
    a = rng.normal(size=(n, n))
    c = tries[-1]
    x = solve_qp(a @ a.T + np.eye(n), rng.normal(size=n), c.lower, c.upper, "daqp", c.rows, c.bound, c.soft)
    assert x is not None
    assert np.all(x >= c.lower - 1e-9) and np.all(x <= c.upper + 1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_the_nearest_band_is_met_and_moves_only_the_rows_no_step_meets(seed):
    """A band of random rows, some beyond the step's box: :func:`nearest_band` returns bounds a step
    meets (the step's own QP then has a solution), equal to the band's where the band could be met
    row by row at the stage-one step, and the body's rows untouched."""
    from hlik.solvers.frames import nearest_band

    rng = np.random.default_rng(seed)
    n, k = 5, 4
    q = rng.uniform(-1, 1, n)
    half = rng.uniform(1e-3, 0.05, n)
    box = JointBox(q - half, q + half)
    a_band = rng.normal(size=(k, n))
    b_band = rng.normal(0, 0.2, k)  # some rows out of a step's reach
    (c, *_) = constrained_steps(box, q, 0.2, np.zeros((0, n)), np.zeros(0), a_band, b_band)
    nearest = nearest_band(c, k, "daqp")
    assert nearest is not None and np.all(nearest >= c.bound)
    a = rng.normal(size=(n, n))
    x = solve_qp(a @ a.T + np.eye(n), rng.normal(size=n), c.lower, c.upper, "daqp", c.rows, nearest)
    assert x is not None and np.all(c.rows @ x <= nearest + 1e-7)
    if solve_qp(np.eye(n), np.zeros(n), c.lower, c.upper, "daqp", c.rows, c.bound) is not None:
        np.testing.assert_allclose(nearest, c.bound, atol=1e-6)  # the band itself could be met


def test_a_step_the_solver_cannot_find_fails_the_frame_where_it_stands():
    box = JointBox(np.full(2, -1.0), np.full(2, 1.0))
    steps = iter([np.array([0.1, 0.0]), None])
    result = iterate(lambda q: next(steps), np.zeros(2), box, max_iter=10, tol=1e-6)
    assert result.failed and not result.converged and result.iterations == 2
    np.testing.assert_allclose(result.q, [0.1, 0.0])


def test_every_solver_leaves_the_terms_of_motion_out_of_the_first_frame():
    """One first-frame rule (``frames.first_frame_terms``): the QP's and SLSQP's first stacks hold
    every term of their later frames but those of motion (MIS, MJE, minimum velocity, acceleration,
    jerk), and track the TCP poses in the relative scenario."""
    from dataclasses import replace

    from hlik.criteria.learned import learn
    from hlik.robot.model import load_robot
    from hlik.solvers import qp, slsqp

    robot = load_robot("armar6")
    learned = learn(robot)
    criteria = ("MJE", "MIS", "HJA_r", "SYN")
    stacks = {
        "qp": lambda s, first: [t for t, _ in qp.build_terms(robot, s, learned, first=first)],
        "slsqp": lambda s, first: [loss.term for loss in slsqp.build_losses(robot, s, learned, first)],
    }
    for name, base in (
        ("qp", qp.QPSettings(criteria=criteria)),
        ("slsqp", slsqp.SLSQPSettings(criteria=criteria)),
    ):
        for scenario in ("pose", "relative"):
            s = replace(base, scenario=scenario)
            later, first = stacks[name](s, False), stacks[name](s, True)
            assert any(t.motion for t in later) and not any(t.motion for t in first), name
            assert {"MJE", "MIS"} <= {t.name for t in later}
            assert {"HJA_r", "SYN"} <= {t.name for t in first}
            assert "fPOS" in {t.name for t in first} and "fPOS_off" not in {t.name for t in first}
