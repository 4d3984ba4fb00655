"""The shared frame loop's iteration: convergence and the damping of flip-flopping steps."""

from __future__ import annotations

import numpy as np

from hlik.solvers.frames import JointBox, iterate


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
