"""MJE and the smoothness terms: the solvers' form never excites the frame loop; MJE lowers the jerk."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import ROBOTS
from hlik import load_motion, load_robot
from hlik.criteria.learned import learn
from hlik.criteria.smoothness import ACCELERATION, JERK, MJE, VELOCITY
from hlik.human.kinematics import forward_kinematics
from hlik.metrics import costs
from hlik.problem.placement import shoulder_placement
from hlik.problem.problem import build_problem
from hlik.retarget import trajectory_of
from hlik.solvers import get_solver
from hlik.solvers.qp import QPSettings, build_terms
from hlik.solvers.stack_file import load_stack

OMEGA = np.linspace(0.0, np.pi, 721)  # rad per frame, up to Nyquist


def response(stencil: np.ndarray) -> np.ndarray:
    """S(w) = sum_k stencil_k e^{-i k w} of a backward-difference stencil over (q_t, ..., q_t-3)."""
    return np.exp(-1j * np.outer(OMEGA, np.arange(4))) @ stencil


def spectral_radius(stencil: np.ndarray, stiffness: float) -> float:
    """Largest pole of q_t = argmin stiffness (q_t - r)^2 + (stencil . q)^2 (scalar, s_0 = 1)."""
    s = stencil / stencil[0]
    return float(np.max(np.abs(np.roots([stiffness + 1.0, *s[1:]]))))


def test_the_solver_form_of_mje_never_amplifies_a_frequency():
    """Re S(w) >= 0: with any tracking stiffness the frame loop damps the jerk at every frequency
    and its poles stay inside the unit circle. The jerk stencil alone has Re S < 0 below a third
    of the frame rate and goes unstable (the QP oscillated)."""
    stencil = MJE.solver_stencil
    assert stencil[0] == 1.0 and stencil.sum() == pytest.approx(0.0)
    assert response(stencil).real.min() >= -1e-12
    slow = (OMEGA > 0.0) & (OMEGA < 2 * np.pi / 3 - 0.01)
    assert response(JERK).real[slow].max() < 0.0
    # the QP's default velocity, acceleration, jerk costs are positive real too
    costs_sq = np.array([0.02, 0.01, 0.005]) ** 2
    assert response(costs_sq @ np.stack([VELOCITY, ACCELERATION, JERK])).real.min() >= -1e-12
    stiffness = np.logspace(-4, 3, 50)  # tracking weight over the term's weight
    assert max(spectral_radius(stencil, p) for p in stiffness) < 1.0
    assert max(spectral_radius(JERK, p) for p in stiffness) > 1.1


def test_motion_criteria_stay_out_of_the_first_frame():
    """The first frame has no motion before it: MIS and MJE are 0 there whatever q."""
    robot = load_robot("dual_panda")
    settings = QPSettings(criteria=("MJE", "MIS", "HJA_r"))
    names = lambda terms: [t.name for t, _ in terms]  # noqa: E731
    assert {"MJE", "MIS", "HJA_r"} <= set(names(build_terms(robot, settings, learn(robot))))
    first = names(build_terms(robot, settings, learn(robot), first=True))
    assert "HJA_r" in first and "MJE" not in first and "MIS" not in first


@pytest.mark.parametrize("name", ROBOTS)
def test_mje_lowers_the_jerk_of_the_qp(name, takes):
    """On a recorded take, adding MJE to the QP lowers the measured jerk (MJE's h, averaged over
    the frames), at the stack's criterion weight and clearly at ten times it, with the hands
    weighed 10 per m and 1 per rad, no elbow term and no look-ahead (the stack's own weights hold
    the arms so that MJE moves the jerk by about 1 % either way at its weight, 5 % at a hundred
    times); the jerk alone
    raised it up to 25 times on 2-Panda. (Placed at the shoulders: fast, and the jerk does not
    depend on it.)"""
    robot = load_robot(name)
    learned = learn(robot)
    motion = load_motion(takes[1], rate=100.0).crop(1.0, 2.0)  # Cut, 1 s
    problem = build_problem(motion, robot, shoulder_placement(robot, forward_kinematics(motion)), learned)
    stack = load_stack("ee_pose")

    def jerk(criteria: tuple[str, ...], scale: float = 1.0) -> float:
        settings = stack.with_criteria(list(criteria)).settings("qp")
        settings = replace(
            settings,
            criterion_cost=scale * settings.criterion_cost,
            position_cost=10.0,
            orientation_cost=1.0,
            elbow_cost=0.0,
            preview_cost=0.0,  # one pass: the look-ahead's path would hold the jerk as well
        )
        traj = trajectory_of(problem, get_solver("qp", settings)(problem), "qp")
        return float(np.mean(costs(traj, robot, learned)["MJE"]))

    plain = jerk(())
    # with the acceleration limits, 2-Panda's jerk is mostly the limits' corners, which MJE at the
    # stack's weight does not move (0.8395e-3 against 0.8340e-3 without)
    assert jerk(("MJE",)) < (1.01 if name == "dual_panda" else 1.0) * plain
    assert jerk(("MJE",), scale=10.0) < 0.95 * plain
