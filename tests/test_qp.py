"""QP retargeting: hlik terms inside plain mink, the stacked solver, stopping rule, unreachable targets."""

from __future__ import annotations

from dataclasses import replace

import mink
import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import ROBOTS, central_differences, hand_errors, reachable_stretch, slowed, solve_problem
from hlik import load_motion, load_robot, retarget
from hlik.cli import app
from hlik.criteria.base import Sample
from hlik.criteria.functional import fORI, fORI_off, fPOS, fPOS_off, rotation_vector
from hlik.criteria.learned import learn
from hlik.human.demo import demo_motion
from hlik.human.kinematics import forward_kinematics
from hlik.problem.placement import placement_from_spec, shoulder_placement
from hlik.problem.targets import HandTargets, hand_targets
from hlik.robot.model import SIDES, joint_mapping, tcp_poses
from hlik.robot.state import robot_state
from hlik.solvers import qp
from hlik.solvers.gradients import gradient
from hlik.solvers.mink_tasks import CriterionTask, HumanJointLimit
from hlik.solvers.qp import QPSettings, qp_solver, solve
from hlik.solvers.stack_file import load_stack


def _frame(robot, q_target):
    s = robot_state(robot, q_target)
    eye = np.tile(np.eye(3), (2, 1, 1))
    return Sample.one(s.tcp[0], s.tcp_rot[0], q_target, np.full(2, 2.5), eye, np.tile(q_target, (3, 1)), 0.01)


@pytest.mark.parametrize("robot", ROBOTS)
def test_criteria_work_inside_plain_mink(robot):
    r = load_robot(robot)
    learned = learn(r)
    config = mink.Configuration(r.model, np.clip(r.home, r.lower, r.upper))
    hand = mink.FrameTask("left_tcp", "site", position_cost=1.0, orientation_cost=0.5)
    hand.set_target_from_configuration(config)
    posture = mink.PostureTask(r.model, cost=1e-3)
    posture.set_target(config.q.copy())
    goal = np.clip(r.home + 0.2, r.lower, r.upper)
    tasks = [CriterionTask.criterion(name, r, learned) for name in ("HJA_r", "SYN_r")]
    for task in tasks:
        task.set_sample(_frame(r, goal))
    before = [np.linalg.norm(t.compute_error(config)) for t in tasks]
    limits = [mink.ConfigurationLimit(r.model), HumanJointLimit(r)]
    for _ in range(30):
        v = mink.solve_ik(config, [hand, posture, *tasks], dt=0.01, solver="daqp", limits=limits)
        config.integrate_inplace(v, 0.01)
    after = [np.linalg.norm(t.compute_error(config)) for t in tasks]
    assert np.all(np.isfinite(config.q)) and all(a < b for a, b in zip(after, before)), (before, after)
    assert np.all(config.q >= r.lower - 1e-6) and np.all(config.q <= r.upper + 1e-6)


TARGET_TERMS = (fPOS, fORI, fPOS_off, fORI_off)


def test_rotation_vector():
    from scipy.spatial.transform import Rotation

    rot = Rotation.random(20, random_state=np.random.default_rng(5))
    np.testing.assert_allclose(rotation_vector(rot.as_matrix()), rot.as_rotvec(), atol=1e-9)


@pytest.mark.parametrize("term", TARGET_TERMS, ids=lambda t: t.__name__)
@pytest.mark.parametrize("name", ["armar3", "armar6", "dual_panda"])
def test_target_term_jacobians(term, name):
    """At the target e = 0 and J = de/dq (the rotation-vector Jacobian is exact there); away from
    it, the gradient of h(e) is exact everywhere."""
    rng = np.random.default_rng(6)
    r = load_robot(name)
    q = np.clip(r.home + rng.normal(0, 0.2, r.dof), r.lower, r.upper)
    t = term()
    residual = lambda x, f: t(robot_state(r, x, True), f)[0]  # noqa: E731
    at_target = _frame(r, q)
    e0, jac = t(robot_state(r, q, jacobians=True), at_target)
    np.testing.assert_allclose(e0, 0.0, atol=1e-9)
    np.testing.assert_allclose(central_differences(lambda x: residual(x, at_target), q), jac, atol=1e-5)
    away = _frame(r, np.clip(q + rng.normal(0, 0.3, r.dof), r.lower, r.upper))
    _, grad = gradient(t, robot_state(r, q, jacobians=True), away)
    cost = lambda x: np.array([gradient(t, robot_state(r, x, True), away)[0]])  # noqa: E731
    np.testing.assert_allclose(central_differences(cost, q)[0], grad, atol=1e-6)


@pytest.mark.parametrize("robot", ROBOTS)
def test_reachable_targets_converge_within_the_iteration_limit(robot):
    """Targets made by the robot itself: every frame stops early, on target."""
    r = load_robot(robot)
    motion = slowed(demo_motion().crop(0, 1.0).resample(50.0), 3.0)
    jm = retarget(motion, r)  # a feasible, smooth robot motion, within the speed limits
    placement = shoulder_placement(r, forward_kinematics(motion))
    targets = HandTargets(jm.tcp_pos, jm.tcp_rot)
    settings = QPSettings(max_iter=30)
    q, steps = solve_problem(solve, r, motion, targets, placement, settings)
    state = robot_state(r, q)
    assert np.median(np.linalg.norm(state.tcp - jm.tcp_pos, axis=-1)) < 1e-3
    iterations = steps.diagnostics.iterations[1:]
    assert np.all(iterations <= settings.max_iter) and np.median(iterations) < settings.max_iter
    assert steps.diagnostics.n_failed == 0 and steps.diagnostics.converged[1:].all()


def test_unreachable_targets_give_finite_motion_and_report_the_error():
    r = load_robot("dual_panda")
    motion = demo_motion().crop(0, 0.5)
    human = forward_kinematics(motion)
    placement = shoulder_placement(r, human)
    far = hand_targets(human, placement)
    far = replace(far, pos=far.pos + np.array([0.0, 5.0, 0.0]))  # 5 m in front of the robot
    q, steps = solve_problem(solve, r, motion, far, placement, QPSettings(criteria=("HJA_r",), max_iter=10))
    assert np.all(np.isfinite(q)) and np.all(q >= r.lower - 1e-9) and np.all(q <= r.upper + 1e-9)
    err = np.linalg.norm(robot_state(r, q).tcp - far.pos, axis=-1)
    assert np.all(err > 4.0)  # reported, not hidden
    # the step budget holds; the first frame, which leaves the hands off, is solved from its start,
    # from the hands' IK, and from its start again (frames.track), 10 x 10 steps at most each
    iterations = steps.diagnostics.iterations
    assert iterations[0] <= 300 and np.all(iterations[1:] <= 10)


def test_criteria_improve_their_own_score(takes):
    r = load_robot("armar3")
    motion = load_motion(takes[0], rate=50.0).crop(1.0, 3.0)
    learned = learn(r)
    from hlik.metrics import evaluate

    plain = evaluate(retarget(motion, r, qp_solver(QPSettings()), learned=learned), r, learned)
    hja = evaluate(
        retarget(motion, r, qp_solver(QPSettings(criteria=("HJA_r",), criterion_cost=0.3)), learned=learned),
        r,
        learned,
    )
    assert hja.m["HJA_r"] > plain.m["HJA_r"]
    assert np.median(hja.h["fPOS"]) < 0.03


def test_cli_qp_with_criteria(takes, tmp_path):
    out = tmp_path / "q.rrd"
    args = ["run", str(takes[0]), "--rate", "10", "--solver", "qp", "--criteria", "SYN", "--out", str(out)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert out.is_file() and "fPOS mean" in result.stdout
    bad = CliRunner().invoke(app, ["run", "--solver", "jm", "--criteria", "SYN"])
    assert bad.exit_code == 2 and "jm maps joints and cannot add criteria" in bad.stderr
    bad = CliRunner().invoke(app, ["run", "--solver", "qp", "--criteria", "NOPE"])
    assert bad.exit_code == 2 and "unknown criteria NOPE" in bad.stderr


def test_mink_solver_retargets_with_mink_and_hlik_tasks():
    """A user stack: mink FrameTasks beside hlik criterion tasks and limits, in plain mink.solve_ik."""
    from hlik.solvers.mink_ik import MinkSolver

    r = load_robot("armar6")
    motion = demo_motion().crop(2.0, 2.5)
    hands = [mink.FrameTask(f"{s}_tcp", "site", position_cost=10.0, orientation_cost=2.0) for s in SIDES]
    criteria = [CriterionTask.criterion(c, r, learn(r), cost=0.1) for c in ("SYN", "HJA_r")]
    limits = [mink.ConfigurationLimit(r.model), HumanJointLimit(r)]
    traj = retarget(motion, r, MinkSolver([*hands, *criteria], limits))
    assert traj.solver == "mink" and np.all(np.isfinite(traj.q))
    assert np.median(np.linalg.norm(traj.tcp_pos - traj.targets.pos, axis=-1)) < 0.02
    assert np.all((traj.q >= r.lower - 1e-6) & (traj.q <= r.upper + 1e-6))


@pytest.mark.parametrize("name", ["armar3", "armar6", "dual_panda"])
def test_relative_scenario_keeps_the_hands_relative_pose(takes, name):
    """Eqs. 3-4 tracked after a first frame on the TCP poses; the absolute poses may drift."""
    from hlik.criteria.functional import relative_errors

    r = load_robot(name)
    motion = slowed(load_motion(takes[7], rate=50.0).crop(1.0, 2.0), 5.0)
    traj = retarget(motion, r, qp_solver(QPSettings(scenario="relative")))
    off_pos, off_rot = relative_errors(traj.tcp_pos, traj.tcp_rot, traj.targets.pos, traj.targets.rot)
    assert np.median(off_pos) < 0.01 and np.median(off_rot) < np.radians(3)
    first = np.linalg.norm(traj.tcp_pos[0] - traj.targets.pos[0], axis=-1)
    assert np.all(first < 0.05)  # the first frame tracks the hands themselves


@pytest.mark.parametrize("name", ROBOTS)
def test_the_band_keeps_reachable_hands_on_target_while_the_criteria_shape_the_arm(takes, name):
    """Reachable targets (the robot's own TCP along its joint mapping, played 3x slower) and strong
    criteria: without the band they turn the hands cm and degrees off; with it every hand stays
    within 5 mm and 3 deg of its target after the first frame, and the arm still moves away from
    the mapping (the criteria act inside the band and in the null space)."""
    r = load_robot(name)
    motion, targets, placement = reachable_stretch(r, takes[0], 2.0, 2.5)
    # the hands at 10 per m and 1 per rad: the stack's 30 and 5 already hold them against these criteria
    strong = QPSettings(
        criteria=("SYN", "HJA_r"), criterion_cost=1.0, position_cost=10.0, orientation_cost=1.0
    )
    banded = replace(strong, position_band=0.005, orientation_band=np.radians(3.0))
    errors = {}
    for label, settings in (("free", strong), ("band", banded)):
        q, _ = solve_problem(qp.solve, r, motion, targets, placement, settings, learned=learn(r))
        errors[label] = (*hand_errors(r, q, targets), np.abs(q - joint_mapping(r, motion)).max())
    assert errors["free"][0] > 0.01 or errors["free"][1] > np.radians(6.0), errors
    assert errors["band"][0] <= 0.005 + 1e-4 and errors["band"][1] <= np.radians(3.0) + 1e-3, errors
    assert errors["band"][2] > 0.05, errors


@pytest.mark.parametrize("name", ROBOTS)
def test_hands_first_keeps_the_hands_of_the_plain_qp_while_the_criteria_move_the_arm(takes, name):
    """``hands_first``: the same strong criteria that turn the hands off their reachable targets in
    the weighted QP leave them as the QP without criteria does (within 1 mm and 0.3 deg), while the
    arm moves away from that QP's (the criteria act in the hands' null space)."""
    r = load_robot(name)
    motion, targets, placement = reachable_stretch(r, takes[0], 2.0, 2.5)
    plain = QPSettings(position_cost=10.0, orientation_cost=1.0)
    strong = replace(plain, criteria=("SYN", "HJA_r"), criterion_cost=1.0)
    runs = {}
    first = replace(strong, hands_first=True)
    for label, settings in (("plain", plain), ("weighted", strong), ("first", first)):
        q, result = solve_problem(qp.solve, r, motion, targets, placement, settings, learned=learn(r))
        assert not result.diagnostics.failed.any()
        runs[label] = (q, *hand_errors(r, q, targets))
    assert runs["weighted"][1] > runs["plain"][1] + 0.005 or runs["weighted"][2] > runs["plain"][2] + 0.05
    assert runs["first"][1] <= runs["plain"][1] + 0.001, (runs["first"][1:], runs["plain"][1:])
    assert runs["first"][2] <= runs["plain"][2] + np.radians(0.3), (runs["first"][1:], runs["plain"][1:])
    assert np.abs(runs["first"][0] - runs["plain"][0]).max() > 0.05


def test_hands_first_puts_a_stack_s_own_mink_tasks_after_the_hands(takes):
    """``--solver mink`` with a strong ``PostureTask`` (toward home) from a stack's ``[mink]``: it
    pulls the weighted QP's hands off reachable targets; with ``hands_first`` the hands stay as
    the QP without it keeps them (within 1 mm) and the arm still moves toward home (the task's
    own measure, the squared distance)."""
    from hlik.solvers import mink_stack
    from hlik.solvers.settings import MinkSettings

    r = load_robot("armar6")
    motion, targets, placement = reachable_stretch(r, takes[0], 2.0, 2.5)
    plain = MinkSettings(position_cost=10.0, orientation_cost=1.0)
    posture = replace(plain, tasks=({"type": "PostureTask", "cost": 3.0},))
    runs = {}
    for label, settings in (
        ("plain", plain),
        ("weighted", posture),
        ("first", replace(posture, hands_first=True)),
    ):
        q, _ = solve_problem(mink_stack.solve, r, motion, targets, placement, settings)
        runs[label] = (q, *hand_errors(r, q, targets), np.mean(np.sum((q - r.home) ** 2, axis=1)))
    assert runs["weighted"][1] > runs["plain"][1] + 0.01, runs["weighted"][1:]
    assert runs["first"][1] <= runs["plain"][1] + 0.001, (runs["first"][1:], runs["plain"][1:])
    assert runs["first"][3] < 0.95 * runs["plain"][3], (runs["first"][3], runs["plain"][3])  # 12.9 < 14.4


def test_targets_out_of_the_band_s_reach_lag_without_failing(takes):
    """Targets 1.5 m beyond reach: the band cannot be met; each step comes as near it as the body's
    rows allow, no frame fails, the limits hold, and the hands stay as near the targets as without
    the band (within 1 cm)."""
    r = load_robot("armar6")
    motion = load_motion(takes[0], rate=100).crop(2.0, 2.5)
    placement = shoulder_placement(r, forward_kinematics(motion))
    near = HandTargets(*tcp_poses(r, joint_mapping(r, motion)))
    far = replace(near, pos=near.pos + np.array([0.0, 1.5, 0.0]))
    settings = QPSettings(position_band=0.005, orientation_band=np.radians(3.0))
    q, result = solve_problem(qp.solve, r, motion, far, placement, settings)
    assert np.all(np.isfinite(q)) and not np.any(result.diagnostics.failed)
    assert np.all(q >= r.lower - 1e-9) and np.all(q <= r.upper + 1e-9)
    gap = np.linalg.norm(robot_state(r, q).tcp - far.pos, axis=-1)
    plain, _ = solve_problem(qp.solve, r, motion, far, placement, QPSettings())
    plain_gap = np.linalg.norm(robot_state(r, plain).tcp - far.pos, axis=-1)
    assert np.mean(gap) <= np.mean(plain_gap) + 0.01, (np.mean(gap), np.mean(plain_gap))


def test_the_trunk_term_holds_armar3_upright_and_is_absent_elsewhere(takes):
    """``trunk_cost`` adds the extra joints toward home: ARMAR-III (hip) leans less with it; the
    robots without extra joints get no term."""
    from hlik.criteria.joints import TrunkUpright
    from hlik.posture import robot_posture
    from hlik.solvers.qp import build_terms

    for name in ("armar6", "dual_panda"):
        r = load_robot(name)
        assert not any(
            isinstance(t, TrunkUpright) for t, _ in build_terms(r, QPSettings(trunk_cost=1.0), None)
        )
    r = load_robot("armar3")
    assert any(isinstance(t, TrunkUpright) for t, _ in build_terms(r, QPSettings(trunk_cost=1.0), None))
    motion = load_motion(takes[1], rate=100.0).crop(1.0, 2.5)
    lean = {}
    for cost in (0.0, 10.0):
        settings = QPSettings(criteria=("SYN", "HJA_r"), trunk_cost=cost)
        traj = retarget(motion, r, qp_solver(settings), learned=learn(r))
        lean[cost] = np.median(np.abs(robot_posture(r, traj.q).lean))
    assert lean[10.0] < 0.7 * lean[0.0], lean  # measured 27.5 -> 15.7 deg


@pytest.mark.parametrize("name", ["armar6", "dual_panda"])
def test_the_band_moves_a_robot_that_starts_far_from_its_targets(takes, name):
    """The Cut take from its first frame, where the mapped pose starts ARMAR-6's hands 0.6 m from
    their targets: with the band (soft rows at a priority penalty) daqp called every step
    infeasible and the robot never moved, reported converged. It must reach its targets, no frame
    failed or in contact."""
    from hlik.robot.model import self_contacts

    r = load_robot(name)
    motion = load_motion(takes[1], rate=100.0).crop(0.0, 0.5)
    traj = retarget(motion, r, qp_solver(QPSettings(position_band=0.005, orientation_band=np.radians(5.0))))
    assert not traj.diagnostics.failed.any()
    assert np.abs(np.diff(traj.q, axis=0)).max() > 1e-3  # it moves
    err = np.linalg.norm(traj.tcp_pos - traj.targets.pos, axis=-1)
    assert err[-10:].max() < 0.01, err[-10:].max()
    assert not any(len(self_contacts(r, q)) for q in traj.q[::10])


@pytest.mark.parametrize("name", ["armar3", "armar6", "dual_panda"])
def test_the_qp_is_its_stack_of_least_squares_terms_on_mink(name):
    """The QP (:func:`qp.build_solver`: every term a CriterionTask, solved by MinkSolver) steps with
    mink's objective, which equals the stack written out by hand, ``H = damping I + sum (W J)'(W J)``,
    ``g = sum (W J)'(W e)`` over :func:`qp.build_terms`, the first frame's stack and the others';
    the hands' band is a HandBandLimit whose rows bound each target term's weighted error."""
    from hlik.solvers.mink_tasks import HandBandLimit

    r = load_robot(name)
    learned = learn(r)
    settings = replace(
        load_stack("ee_pose").with_criteria(["SYN", "HJA_r", "MJE"]).settings("qp"),
        position_band=0.005,
        orientation_band=0.05,
    )
    solver = qp.build_solver(r, settings, learned)
    rng = np.random.default_rng(0)
    q = np.clip(r.home + rng.normal(0, 0.2, r.dof), r.lower, r.upper)
    frame = _frame(r, np.clip(q + rng.normal(0, 0.1, r.dof), r.lower, r.upper))
    config = mink.Configuration(r.model, q)
    state = robot_state(r, q, jacobians=True)
    for first, tasks in ((True, solver.first_tasks), (False, solver.tasks)):
        terms = qp.build_terms(r, settings, learned, first=first)
        assert [type(t.term) for t in tasks] == [type(t) for t, _ in terms]
        for task in tasks:
            task.set_sample(frame)
        objective = mink.build_ik(config, tasks, frame.dt, settings.damping, limits=[])
        hessian, gradient = settings.damping * np.eye(r.dof), np.zeros(r.dof)
        for term, cost in terms:
            e, jac = term(state, frame)
            w = np.broadcast_to(np.asarray(cost, dtype=float), e.shape)
            hessian += (w[:, None] * jac).T @ (w[:, None] * jac)
            gradient += (w[:, None] * jac).T @ (w * e)
        np.testing.assert_allclose(objective.P, hessian, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(objective.q, gradient, rtol=1e-9, atol=1e-9)
        (band,) = [lim for lim in solver.limits if isinstance(lim, HandBandLimit)]
        band.set_tasks(tasks)
        rows = band.compute_qp_inequalities(config, frame.dt)
        dq = rng.normal(0, 1e-3, r.dof)
        for (task, b), g, h in zip(
            band.tasks, np.split(rows.G, len(band.tasks)), np.split(rows.h, len(band.tasks))
        ):
            e, jac = task.term(state, frame)
            w = np.asarray(task.cost)
            inside = np.all(np.abs(w * (e + jac @ dq)) <= w * b / np.sqrt(3.0) + 1e-12)
            assert np.all(g @ dq <= h + 1e-12) == inside
        assert {type(t.term) for t, _ in band.tasks} == {fPOS, fORI}


def test_a_users_mink_limit_is_never_dropped_by_the_fallbacks():
    """MinkSolver's fallbacks give way on hlik's rows first and on the caller's limits only last,
    reporting the frame: with a limit no step can meet, every frame fails and says so, unconverged
    (it passed for converged when the last fallback was the box alone)."""
    from mink.limits import Constraint, Limit

    from hlik.solvers.mink_ik import MinkSolver

    r = load_robot("armar6")

    class Impossible(Limit):  # dq_0 >= 1 and dq_0 <= -1
        def compute_qp_inequalities(self, configuration, dt):
            g = np.zeros((2, r.dof))
            g[:, 0] = (-1.0, 1.0)
            return Constraint(G=g, h=np.array([-1.0, -1.0]))

    motion = demo_motion().crop(2.0, 2.3)
    hands = [mink.FrameTask(f"{s}_tcp", "site", position_cost=10.0, orientation_cost=2.0) for s in SIDES]
    traj = retarget(motion, r, MinkSolver(hands, [Impossible()]))
    assert traj.diagnostics.failed.all() and not traj.diagnostics.converged.any()
    free = retarget(motion, r, MinkSolver(hands))
    assert not free.diagnostics.failed.any()


def _elbow_below(r, bound):
    """A user's ``mink.Limit`` keeping ARMAR-6's left elbow (``ArmL6_Elb2``) at most ``bound`` less
    the braking margin v^2 / (2 a), as the README says; the limit, the joint's index and the margin."""
    from mink.limits import Constraint, Limit

    j = r.joint_names.index("ArmL6_Elb2")
    margin = r.velocity_limit[j] ** 2 / (2.0 * r.acceleration_limit[j])

    class Below(Limit):
        def compute_qp_inequalities(self, configuration, dt):
            g = np.zeros((1, r.dof))
            g[0, j] = 1.0
            return Constraint(G=g, h=np.array([bound - margin - configuration.q[j]]))

    return Below(), j, margin


@pytest.mark.parametrize("bound", [1.5, 1.2])
def test_a_users_bound_with_a_braking_margin_holds_where_the_joint_arrives_at_speed(bound):
    """A caller's upper bound on ARMAR-6's left elbow (which rises to 1.94 rad on this stretch of
    the demo), kept ``v^2 / (2 a)`` inside it as the README says: the joint arrives at the row faster
    than its acceleration limit can stop it there, so the row gives way as little as the box allows
    (frames reported failed) and the bound itself holds in every frame. A frame with no step had
    carried the joint on at its speed, 1.9 rad past (found by a new user). At 1.2 the first frame
    starts above the row (the mapped pose) and is brought inside."""
    r = load_robot("armar6")
    below, j, margin = _elbow_below(r, bound)

    motion = demo_motion().crop(0.0, 2.0)
    settings = QPSettings(criteria=("SYN", "HJA_r"))
    at = placement_from_spec("reach", r, motion)  # where the elbow rises (ARMAR-6's default until issue 28)
    free = retarget(motion, r, qp.build_solver(r, settings, learn(r)), at)
    traj = retarget(motion, r, qp.build_solver(r, settings, learn(r), limits=[below]), at)
    assert free.q[:, j].max() > bound + 0.3  # the bound binds
    assert np.all(traj.q[:, j] <= bound), traj.q[:, j].max()
    over = traj.q[:, j] > bound - margin + 1e-9
    assert over.any() and np.all(traj.diagnostics.failed[over])  # each frame past the row is reported
    assert traj.diagnostics.failed.mean() < 0.2
    assert np.median(np.linalg.norm(traj.tcp_pos - traj.targets.pos, axis=-1)) < 0.01


def test_the_qps_collision_settings_reach_its_collision_rows():
    """``collision_margin``, ``collision_detect`` and ``collision_gain`` of QPSettings act on the
    QP's steps (MinkSolver's SelfCollisionLimit once ran with its own defaults whatever they said;
    found in review): a wider margin moves 2-Panda's arms, the defaults do not."""
    r = load_robot("dual_panda")
    motion = demo_motion().crop(2.0, 2.3)
    plain = retarget(motion, r, qp_solver(QPSettings()))
    same = retarget(motion, r, qp_solver(QPSettings(collision_margin=0.01, collision_detect=0.10)))
    wide = retarget(
        motion, r, qp_solver(QPSettings(collision_margin=0.08, collision_detect=0.3, collision_gain=0.1))
    )
    np.testing.assert_array_equal(same.q, plain.q)
    assert np.abs(wide.q - plain.q).max() > 0.05


@pytest.mark.parametrize("name", ["jv", "slsqp"])
def test_jv_and_slsqp_keep_a_users_mink_limit_as_the_qp_does(name):
    """A ``mink.Limit`` is written once and every optimising solver keeps it: JV as rows of its
    constrained step (at each step), SLSQP as linear constraints taken at each frame's start. The
    bound on ARMAR-6's left elbow from the test above (1.2 rad, the row v^2/(2a) inside it, below
    the first frame's mapped pose) binds without it and holds with it; a frame past the row is
    reported failed."""
    from hlik.solvers import jv, slsqp

    r = load_robot("armar6")
    bound = 1.2
    below, j, margin = _elbow_below(r, bound)

    module, settings = {"jv": (jv, jv.JVSettings), "slsqp": (slsqp, slsqp.SLSQPSettings)}[name]
    factory = getattr(module, f"{name}_solver")
    motion = demo_motion().crop(0.0, 2.0)
    s = settings(criteria=("SYN", "HJA_r"))
    free = retarget(motion, r, factory(s), learned=learn(r))
    traj = retarget(motion, r, factory(s, limits=[below]), learned=learn(r))
    assert free.q[:, j].max() > bound  # measured: JV 1.24, SLSQP 1.64 rad
    assert np.all(traj.q[:, j] <= bound), traj.q[:, j].max()
    over = traj.q[:, j] > bound - margin + 1e-6
    assert np.all(traj.diagnostics.failed[over]) and traj.diagnostics.failed.mean() < 0.05
    assert np.median(np.linalg.norm(traj.tcp_pos - traj.targets.pos, axis=-1)) < 0.01


def test_error_damping_settles_the_joints_chattering_at_targets_out_of_reach():
    """KIT-ML take 00001 (the subject walks 1.4 m away from ARMAR-6, its hands 20 cm out of reach
    on average): undamped, the wrists' steps overshoot between iterations and their accelerations
    turn from one limit to the other frame after frame; the hand targets' own error damping
    (Sugihara's) settles them, with the hands as far off."""
    from conftest import data_file
    from hlik.pipeline import RunSpec, run

    robot = load_robot("armar6")
    learned = learn(robot)
    flips, error = {}, {}
    for damping in (0.0, 20.0):
        spec = RunSpec(motion=data_file("kit_ml/00001_mmm.xml"), robot="armar6", span=(1.0, 3.5),
                       settings={"error_damping": damping})  # fmt: skip
        traj = run(spec, robot=robot, learned=learned).trajectory
        a = np.diff(traj.q, n=2, axis=0) / traj.period**2
        flips[damping] = np.mean(np.any(np.abs(np.diff(a, axis=0)) > robot.acceleration_limit, axis=1))
        error[damping] = np.mean(np.linalg.norm(traj.tcp_pos - traj.targets.pos, axis=-1))
    assert error[0.0] > 0.1, "the targets should be out of reach"
    assert flips[20.0] < 0.6 * flips[0.0], flips  # 0.86 -> 0.40 measured
    assert error[20.0] < error[0.0] + 0.01, error
