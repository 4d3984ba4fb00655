"""SLSQP retargeting (the paper's OPT): groove loss, exact gradients, bounds, failures, tracking."""

from __future__ import annotations

from dataclasses import replace

import nlopt
import numpy as np
import pytest

from conftest import ROBOTS, hand_errors, random_frame, reachable_stretch, solve_problem
from hlik import load_motion, load_robot, retarget
from hlik.criteria import registry
from hlik.criteria.functional import relative_errors
from hlik.criteria.learned import learn
from hlik.criteria.smoothness import VELOCITY, Smoothness
from hlik.human.kinematics import forward_kinematics
from hlik.problem.placement import shoulder_placement
from hlik.problem.problem import build_problem
from hlik.problem.reference import human_reference
from hlik.problem.targets import hand_targets
from hlik.robot.collision import collision_pairs
from hlik.robot.state import robot_state
from hlik.solvers import frames, get_solver
from hlik.solvers.frames import JointBox, joint_box, sample_at
from hlik.solvers.gradients import metric, part_metric
from hlik.solvers.slsqp import (
    BandConstraint,
    BoxConstraint,
    Chart,
    CollisionConstraint,
    Loss,
    Objective,
    SLSQPSettings,
    build_losses,
    groove,
    groove_curvature,
    loss_curvature,
    make_optimizer,
    slsqp_solver,
    solve,
    solve_frame,
)
from hlik.util.paths import demo_motion_path


def _problem(robot: str, start: float = 2.0, stop: float = 2.5):
    """Robot, demo motion crop at 100 Hz, placement and hand targets."""
    r = load_robot(robot)
    motion = load_motion(demo_motion_path(), rate=100.0).crop(start, stop)
    placement = shoulder_placement(r, forward_kinematics(motion))
    return r, motion, placement, hand_targets(forward_kinematics(motion), placement)


def _fpos(r, q, target_pos) -> np.ndarray:
    """(T,) fPOS: mean distance of the two TCPs to their targets (T, 2, 3)."""
    return np.linalg.norm(robot_state(r, q).tcp - target_pos, axis=-1).mean(axis=-1)


def test_groove_is_the_papers_loss_and_its_derivative_is_exact():
    x = np.linspace(-0.5, 0.8, 27)
    for kw in ({}, dict(c=0.3, r=2.0, s=0.1), dict(d=4, g=4, s=-0.2)):
        value, slope = groove(x, **kw)
        eps = 1e-6
        fd = (groove(x + eps, **kw)[0] - groove(x - eps, **kw)[0]) / (2 * eps)
        np.testing.assert_allclose(slope, fd, rtol=1e-6, atol=1e-6)
    value, slope = groove(np.array([0.0, 0.3]))
    np.testing.assert_allclose(value, [-1.0, -np.exp(-4.5) + 0.9])  # paper: n = 1, c = 0.1, r = 10
    assert slope[0] == 0.0


def test_groove_curvature_is_the_second_derivative_inside_the_bump():
    x = np.linspace(-0.09, 0.09, 19)  # |x| < c: no floor
    eps = 1e-4
    fd = (groove(x + eps)[0] - 2 * groove(x)[0] + groove(x - eps)[0]) / eps**2
    np.testing.assert_allclose(groove_curvature(x), fd, rtol=1e-5)
    assert np.all(groove_curvature(np.linspace(-2, 2, 41)) >= 20.0)  # floored at 2r


@pytest.mark.parametrize("robot_name", ["armar6", "dual_panda"])
def test_each_preconditioner_converges_in_fewer_evaluations_to_no_worse_objectives(takes, robot_name):
    """The paper's ftol 1e-6 on a KIT take (0.3 s), each frame from the same start and history: the
    raw objective, the objective divided by its Gauss-Newton scale, then the frame in Gauss-Newton
    variables take fewer evaluations each, to objective values no worse."""
    r = load_robot(robot_name)
    motion = load_motion(takes[1], rate=100.0).crop(2.0, 2.3)
    problem = build_problem(motion, r, shoulder_placement(r, forward_kinematics(motion)))
    path = solve(problem, SLSQPSettings()).q  # the starts and histories every preconditioner shares
    losses = build_losses(r, SLSQPSettings(), None)
    check = Objective(r, losses)
    runs = []
    for precondition in ("none", "scale", "gauss_newton"):
        objective, opt = Objective(r, losses, precondition=precondition), make_optimizer(r, SLSQPSettings())
        collision = CollisionConstraint(r, collision_pairs(r), SLSQPSettings())
        values, evaluations, history = [], [], np.tile(path[0], (3, 1))
        for k in range(1, problem.n_frames):
            history = np.vstack([path[k - 1], history[:2]])
            frame = sample_at(problem.reference, problem.targets, k, history, problem.dt)
            box = joint_box(r, path[k - 1], problem.dt)
            q, status = solve_frame(opt, objective, frame, box.clip(path[k - 1]), 100, box, collision)
            assert status > 0 and np.all(q >= box.lower - 1e-7) and np.all(q <= box.upper + 1e-7)
            check.reset(frame)
            values.append(check.value(q))
            evaluations.append(objective.evaluations)
        runs.append((np.array(values), np.mean(evaluations)))
    for (f0, evals0), (f1, evals1) in zip(runs, runs[1:]):
        assert evals1 < evals0, [e for _, e in runs]
        assert np.all(f1 <= f0 + 1e-5 * np.abs(f0)), np.max(f1 - f0)
    assert runs[2][1] < 8, runs[2][1]  # a Gauss-Newton step, then a few to confirm it


def test_a_chart_makes_the_hessian_the_identity_and_maps_the_joint_box():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(5, 5))
    hessian = a @ a.T + np.diag([1e4, 1.0, 1e-2, 3.0, 1e2])
    chart = Chart.at(rng.normal(size=5), hessian)
    assert chart is not None
    np.testing.assert_allclose(
        chart.T.T @ hessian @ chart.T, np.eye(5), atol=1e-3
    )  # up to the regularisation
    assert Chart.at(np.zeros(2), np.array([[1.0, 0.0], [0.0, -1.0]])) is None  # not positive definite
    box = JointBox(chart.origin - 0.1, np.where(np.arange(5) == 2, np.inf, chart.origin + 0.2))
    rows = BoxConstraint(chart, box)
    assert len(rows) == 9  # the unlimited upper bound has no row
    for x in rng.normal(scale=0.5, size=(50, 5)):
        result = np.empty(len(rows))
        rows(result, x, np.empty(0))
        q = chart.q(x)
        inside = np.all(q >= box.lower) and np.all(q <= box.upper)
        assert inside == bool(np.all(result <= 0))

    pose = SLSQPSettings()
    assert (
        pose.position_cost,
        pose.orientation_cost,
        pose.velocity_cost,
        pose.acceleration_cost,
        pose.jerk_cost,
    ) == (10, 9, 7, 2, 1)
    assert pose.criterion_cost == 10 and pose.position_gamma == 10 and dict(pose.gamma) == {}
    rel = SLSQPSettings.relative(("SYN",), max_eval=50)
    assert (
        rel.relative_position_cost,
        rel.relative_orientation_cost,
        rel.position_cost,
        rel.orientation_cost,
    ) == (3, 15, 0, 0)
    assert (rel.velocity_cost, rel.acceleration_cost, rel.jerk_cost, rel.criterion_cost) == (40, 10, 5, 100)
    assert rel.scenario == "relative" and rel.criteria == ("SYN",) and rel.max_eval == 50
    with pytest.raises(ValueError, match="gradients"):
        SLSQPSettings(gradients="exact")
    with pytest.raises(ValueError, match="scenario"):
        SLSQPSettings(scenario="absolute")


def test_losses_weights_and_the_first_frame_of_the_relative_scenario():
    r = load_robot("armar3")
    learned = learn(r)
    names = lambda losses: {loss.term.name: (loss.weight, loss.gamma) for loss in losses}  # noqa: E731
    pose = names(build_losses(r, SLSQPSettings(criteria=("SYN", "HJA_r")), learned))
    assert pose == {
        "fPOS": (10, 10),
        "fORI": (9, 1),
        "velocity": (7, 1),
        "acceleration": (2, 1),
        "jerk": (1, 1),
        "SYN": (5, 6),
        "HJA_r": (5, 2),
    }
    settings = SLSQPSettings.relative(("SYN",))
    assert set(names(build_losses(r, settings, learned))) == {
        "fPOS_off",
        "fORI_off",
        "velocity",
        "acceleration",
        "jerk",
        "SYN",
    }
    first = names(build_losses(r, settings, learned, first=True))
    assert first["fPOS"] == (10, 10) and first["SYN"] == (10, 6)
    # nothing moved before the first frame: no minimum velocity, acceleration or jerk
    assert not {"velocity", "acceleration", "jerk"} & set(first)
    assert "fPOS_off" not in first


@pytest.mark.parametrize("scenario", ["pose", "relative"])
@pytest.mark.parametrize("criteria", [("SYN", "HJA_r"), ("EEA", "MAN_r"), ("SOA_x", "SOA_q")], ids="-".join)
@pytest.mark.parametrize("robot", ROBOTS)
def test_analytic_gradient_is_the_objectives(robot, criteria, scenario):
    """Away from every target and with a moving history, so that each loss has a slope."""
    rng = np.random.default_rng(3)
    r, motion, placement, targets = _problem(robot, 2.0, 2.2)
    settings = SLSQPSettings(criteria=criteria)
    if scenario == "relative":
        settings = SLSQPSettings.relative(criteria)
    objective = Objective(r, build_losses(r, settings, learn(r)))
    ref = human_reference(r, motion, placement)
    q = np.clip(ref.q_map[10] + rng.normal(0, 0.1, r.dof), r.lower, r.upper)
    history = np.clip(q + rng.normal(0, 0.05, (3, r.dof)), r.lower, r.upper)
    objective.reset(sample_at(ref, targets, 10, history, 0.01))
    f, grad = objective.value_and_gradient(q)
    assert f == pytest.approx(objective.value(q), abs=1e-12)
    eps = 1e-6
    fd = np.array(
        [(objective.value(q + d) - objective.value(q - d)) / (2 * eps) for d in eps * np.eye(r.dof)]
    )
    scale = np.max(np.abs(fd))
    np.testing.assert_allclose(grad, fd, atol=1e-6 * scale)
    # the paper's forward differences agree to their own accuracy
    np.testing.assert_allclose(objective.fd_gradient(q, f), fd, atol=1e-3 * scale)
    # NLopt's first call (x = 0, the start) is served from the Gauss-Newton pass: the same value,
    # and the gradient in the chart's variables
    objective.reset(sample_at(ref, targets, 10, history, 0.01), q)
    assert objective.chart is not None
    first = np.empty(r.dof)
    assert objective(np.zeros(r.dof), first) == pytest.approx(f, rel=1e-12)
    np.testing.assert_allclose(first, grad @ objective.chart.T, rtol=1e-10, atol=1e-12 * scale)


ALL_TERMS = (*registry.human_likeness(), *registry.functional(), "velocity")


def _terms(r, learned):
    """Every criterion and functional term, and RelaxedIK's minimum velocity."""
    names = (*registry.human_likeness(), *registry.functional())
    return [*(registry.criterion(n, r, learned) for n in names), Smoothness(VELOCITY, r, "velocity")]


@pytest.mark.parametrize("name", ALL_TERMS)
def test_each_losss_curvature_is_its_hessian_in_the_residual(name):
    """loss_curvature's closed forms (norms, squares) and its numerical one equal the Hessian of the
    loss in the residual (by central differences of its gradient), inside the groove's bump where
    no curvature is clipped, split into arms or not; at a zero part it stays finite."""
    r = load_robot("armar6")
    learned = learn(r)
    term = next(t for t in _terms(r, learned) if t.name == name)
    sample, q = random_frame(r, 7)
    state = robot_state(r, q, True)
    e = term(state, sample)[0]
    for split in (True, False) if term.parts > 1 else (True,):
        loss = Loss(term, 3.0, 2.0)

        def gradient(x, split=split, loss=loss):
            h, dh_de = (
                part_metric(term, x) if split else (np.array([metric(term, x)[0]]), metric(term, x)[1][None])
            )
            slope = groove(loss.gamma * h)[1] * loss.gamma * loss.weight / len(h)
            return slope @ dh_de

        base = e / max(1.0, 40.0 * float(np.abs(e).max()))  # gamma |e_p| well inside c
        exact = np.array([(gradient(base + d) - gradient(base - d)) / 2e-7 for d in 1e-7 * np.eye(len(e))])
        phi = loss_curvature(loss, base, split)
        assert np.allclose(phi, phi.T) and np.linalg.eigvalsh(phi).min() > -1e-9 * np.abs(phi).max()
        w, v = np.linalg.eigh(0.5 * (exact + exact.T))
        psd = (v * np.maximum(w, 0.0)) @ v.T  # the norms and squares are convex: psd = exact
        np.testing.assert_allclose(phi, psd, atol=1e-4 * np.abs(exact).max())
        zero = base.copy()
        zero[term.part_rows(len(e))[0]] = 0.0
        assert np.all(np.isfinite(loss_curvature(loss, zero, split)))


def test_unlimited_joints_keep_infinite_bounds_and_limited_joints_stay_within_theirs():
    r, motion, placement, targets = _problem("armar6", 2.0, 2.3)
    unlimited = ~np.isfinite(r.lower)
    assert unlimited.sum() == 6
    opt = make_optimizer(r, SLSQPSettings())
    assert np.all(np.isinf(np.asarray(opt.get_lower_bounds())[unlimited]))
    q, info = solve_problem(solve, r, motion, targets, placement, SLSQPSettings(criteria=("SYN",)))
    assert np.all(np.isfinite(q)) and not np.any(info.diagnostics.failed)
    assert np.all(q[:, ~unlimited] >= r.lower[~unlimited]) and np.all(q[:, ~unlimited] <= r.upper[~unlimited])
    assert np.median(_fpos(r, q, targets.pos)) < 0.05


def test_a_frame_with_nan_targets_fails_alone_and_keeps_the_last_configuration(monkeypatch):
    r, motion, placement, targets = _problem("dual_panda", 2.0, 2.2)

    def nan_at_3(ref, targets, k, history, dt):
        frame = sample_at(ref, targets, k, history, dt)
        return replace(frame, target_pos=frame.target_pos * np.nan) if k == 3 else frame

    monkeypatch.setattr(frames, "sample_at", nan_at_3)
    q, info = solve_problem(solve, r, motion, targets, placement)
    assert tuple(np.flatnonzero(info.diagnostics.failed)) == (3,) and info.info["status"][3] == nlopt.FAILURE
    assert np.all(np.isfinite(q))
    # nothing finite was evaluated: the start, the last good one moved on at its speed
    np.testing.assert_allclose(q[3], 2 * q[2] - q[1], atol=1e-12)
    after = _fpos(r, q[4:], targets.pos[4:])  # and the run goes on, the hands on their targets
    assert not info.diagnostics.failed[4:].any() and after.max() < 0.01


@pytest.mark.parametrize(
    "error", [nlopt.RoundoffLimited, nlopt.runtime_error, RuntimeError], ids=lambda e: e.__name__
)
def test_an_nlopt_exception_keeps_the_best_configuration_evaluated(monkeypatch, error):
    r, motion, placement, targets = _problem("armar3", 2.0, 2.2)
    reference, _ = solve_problem(solve, r, motion, targets, placement)
    optimize, calls = nlopt.opt.optimize, []

    def raising(self, x0):
        calls.append(x0)
        x = optimize(self, x0)  # evaluate as usual, then fail at frame 3 as NLopt may
        if len(calls) == 4:
            raise error("nlopt failure")
        return x

    monkeypatch.setattr(nlopt.opt, "optimize", raising)
    q, info = solve_problem(solve, r, motion, targets, placement)
    # NLopt's roundoff limit "still typically returns a useful result": unconverged, not failed
    roundoff = error is nlopt.RoundoffLimited
    code = nlopt.ROUNDOFF_LIMITED if roundoff else nlopt.FAILURE
    assert tuple(np.flatnonzero(info.diagnostics.failed)) == (() if roundoff else (3,))
    assert info.info["status"][3] == code and not info.diagnostics.converged[3]
    assert np.all(np.isfinite(q))
    # the best point SLSQP evaluated is (nearly) the optimum it would have returned
    np.testing.assert_allclose(q, reference, atol=1e-6)


def test_tracks_a_kit_take_on_armar3_with_analytic_and_fd_gradients(takes, reachable_targets):
    """Reachable targets from the first take (the robot's TCP along its clipped joint mapping)."""
    r = load_robot("armar3")
    motion = load_motion(takes[0], rate=100.0).crop(2.0, 2.5)
    placement = shoulder_placement(r, forward_kinematics(motion))
    targets = reachable_targets(r, motion)
    medians = {}
    for gradients in ("analytic", "fd"):
        q, info = solve_problem(solve, r, motion, targets, placement, SLSQPSettings(gradients=gradients))
        medians[gradients] = np.median(_fpos(r, q, targets.pos))
        assert not np.any(info.diagnostics.failed) and np.all(info.diagnostics.iterations[1:] <= 100)
    assert medians["analytic"] < 1e-3, medians
    assert abs(medians["analytic"] - medians["fd"]) < 1e-3, medians


def test_relative_scenario_tracks_the_relative_pose():
    """Measured on ARMAR-III: median fPOS^off 1.5 mm, fORI^off 0.023 rad, hands free to drift."""
    r, motion, placement, targets = _problem("armar3", 2.0, 3.0)
    q, info = solve_problem(solve, r, motion, targets, placement, SLSQPSettings.relative())
    state = robot_state(r, q)
    pos_off, ori_off = relative_errors(state.tcp, state.tcp_rot, targets.pos, targets.rot)
    assert not np.any(info.diagnostics.failed)
    assert np.median(pos_off) < 0.01 and np.median(ori_off) < 0.1, (np.median(pos_off), np.median(ori_off))
    assert _fpos(r, q[:1], targets.pos[:1])[0] < 0.01  # the first frame tracks the hand poses


def test_solver_plugs_into_retarget():
    r, motion, _, _ = _problem("dual_panda", 2.0, 2.1)
    solver = slsqp_solver(SLSQPSettings(max_eval=30))
    assert solver.name == "slsqp"
    traj = retarget(motion, r, solver)
    assert traj.solver == "slsqp" and traj.q.shape == (motion.n_frames, r.dof)
    assert get_solver("slsqp", SLSQPSettings(max_eval=30)).name == "slsqp"


def test_the_first_frame_reaches_its_targets_from_the_mapped_pose(cut_take):
    # The Cut take starts where 2-Panda's mapped pose puts the left hand 12 cm off its target. The
    # first frame has no motion before it: with the minimum velocity, acceleration and jerk toward
    # that start it stayed 11.7 cm off and took 30 frames to catch up.
    from hlik.criteria.functional import position_error
    from hlik.solvers.stack_file import load_stack

    robot = load_robot("dual_panda")
    motion = load_motion(cut_take, rate=100.0).crop(0.0, 0.1)
    settings = replace(load_stack("ee_pose").settings("slsqp"), criteria=("SYN", "HJA_r"))
    traj = retarget(motion, robot, get_solver("slsqp", settings), learned=learn(robot))
    assert np.all(position_error(traj.tcp_pos[:1], traj.targets.pos[:1]) < 0.02)


@pytest.mark.parametrize("scenario", ["pose", "relative"])
@pytest.mark.parametrize("robot", ROBOTS)
def test_the_bands_gradient_is_its_rows_and_the_start_is_feasible(robot, scenario):
    """Each band row is a hand's error (norm of its residual) minus its bound: the analytic gradient
    equals central differences, in q and in a chart's variables; relaxed, the start meets every row."""
    rng = np.random.default_rng(5)
    r, motion, placement, targets = _problem(robot, 2.0, 2.2)
    settings = SLSQPSettings(scenario=scenario, position_band=0.005, orientation_band=0.05)
    if scenario == "relative":
        settings = SLSQPSettings.relative(position_band=0.005, orientation_band=0.05)
    objective = Objective(r, build_losses(r, settings, None))
    band = BandConstraint(r, objective.losses, settings)
    assert len(band) == 2 if scenario == "relative" else len(band) == 4
    ref = human_reference(r, motion, placement)
    q = np.clip(ref.q_map[10] + rng.normal(0, 0.1, r.dof), r.lower, r.upper)
    frame = sample_at(ref, targets, 10, np.tile(q, (3, 1)), 0.01)
    band.reset(frame, q, None, strict=False)
    values, grad = np.empty(len(band)), np.empty((len(band), r.dof))
    band(values, q, grad)
    assert np.all(values <= 1e-12)  # relaxed to the start: the start is feasible
    eps = 1e-6
    fd = np.empty((len(band), r.dof))
    for j, d in enumerate(eps * np.eye(r.dof)):
        hi, lo = np.empty(len(band)), np.empty(len(band))
        band(hi, q + d, np.empty((0,)))
        band(lo, q - d, np.empty((0,)))
        fd[:, j] = (hi - lo) / (2 * eps)
    np.testing.assert_allclose(grad, fd, atol=1e-6 * max(1.0, np.abs(fd).max()))
    chart = Chart.at(q, np.eye(r.dof) * 4.0 + 0.1)
    band.reset(frame, q, chart, strict=True)
    x = rng.normal(0, 0.01, r.dof)
    in_q, in_x = np.empty(len(band)), np.empty(len(band))
    g_x = np.empty((len(band), r.dof))
    band.chart = None
    band(in_q, chart.q(x), grad)
    band.chart = chart
    band(in_x, x, g_x)
    np.testing.assert_allclose(in_x, in_q, atol=1e-12)
    np.testing.assert_allclose(g_x, grad @ chart.T, atol=1e-10)


@pytest.mark.parametrize("name", ROBOTS)
def test_the_band_keeps_reachable_hands_on_target_while_the_criteria_shape_the_arm(takes, name):
    """Reachable targets (the robot's own TCP along its joint mapping, 3x slower) and strong
    criteria: without the band SLSQP turns the hands off their targets; with it every hand stays
    within 5 mm and 3 deg of its target after the first frame, and the arm still moves away from
    the mapping (the criteria act inside the band and in the null space)."""
    from hlik.robot.model import joint_mapping

    r = load_robot(name)
    motion, targets, placement = reachable_stretch(r, takes[0], 2.0, 2.3)
    strong = SLSQPSettings(criteria=("SYN", "HJA_r"), criterion_cost=40.0, orientation_cost=1.0)
    banded = replace(strong, position_band=0.005, orientation_band=np.radians(3.0))
    errors = {}
    for label, settings in (("free", strong), ("band", banded)):
        q, result = solve_problem(solve, r, motion, targets, placement, settings, learned=learn(r))
        assert not np.any(result.diagnostics.failed)
        errors[label] = (*hand_errors(r, q, targets), np.abs(q - joint_mapping(r, motion)).max())
    assert errors["free"][0] > 0.006 or errors["free"][1] > np.radians(4.0), errors
    assert errors["band"][0] <= 0.005 + 1e-3 and errors["band"][1] <= np.radians(3.0) + 2e-3, errors
    assert errors["band"][2] > 0.05, errors


def test_targets_out_of_the_band_s_reach_lag_without_failing(takes):
    """Targets 1.5 m beyond reach: the band cannot be met; each frame falls back to "no worse than
    its start", no more frames fail than without the band (NLopt's roundoff on the first, in
    both), the limits hold, and the hands stay as near the targets as without the band (1 cm)."""
    from hlik.problem.targets import HandTargets
    from hlik.robot.model import joint_mapping, tcp_poses

    r = load_robot("armar6")
    motion = load_motion(takes[0], rate=100).crop(2.0, 2.3)
    placement = shoulder_placement(r, forward_kinematics(motion))
    near = HandTargets(*tcp_poses(r, joint_mapping(r, motion)))
    far = replace(near, pos=near.pos + np.array([0.0, 1.5, 0.0]))
    banded = SLSQPSettings(position_band=0.005, orientation_band=np.radians(3.0))
    q, result = solve_problem(solve, r, motion, far, placement, banded)
    plain, unbanded = solve_problem(solve, r, motion, far, placement, SLSQPSettings())
    assert np.all(np.isfinite(q)) and not np.any(result.diagnostics.failed[1:])
    assert result.diagnostics.failed.sum() <= unbanded.diagnostics.failed.sum()
    assert np.all(q >= r.lower - 1e-9) and np.all(q <= r.upper + 1e-9)
    gap = np.linalg.norm(robot_state(r, q).tcp - far.pos, axis=-1)
    plain_gap = np.linalg.norm(robot_state(r, plain).tcp - far.pos, axis=-1)
    assert np.mean(gap) <= np.mean(plain_gap) + 0.01, (np.mean(gap), np.mean(plain_gap))


def test_the_trunk_loss_is_there_only_for_a_trunk_and_only_when_weighted():
    from hlik.criteria.joints import TrunkUpright

    def trunks(name, weight):
        losses = build_losses(load_robot(name), SLSQPSettings(trunk_cost=weight), None)
        return [loss for loss in losses if isinstance(loss.term, TrunkUpright)]

    assert not trunks("armar3", 0.0) and not trunks("armar6", 5.0) and not trunks("dual_panda", 5.0)
    (loss,) = trunks("armar3", 5.0)
    assert loss.weight == 5.0


def test_a_bug_in_a_callback_stops_the_run_instead_of_failing_a_frame(monkeypatch):
    """A RuntimeError that is not NLopt's ("nlopt failure") propagates: a bug in a criterion must not
    pass for a failed frame."""
    from hlik.criteria.functional import fPOS

    r, motion, placement, targets = _problem("armar3", 2.0, 2.1)
    real = fPOS.residual

    def broken(self, state, sample):
        if state.q.shape[0] == 1 and broken.calls > 40:
            raise RuntimeError("a bug in the criterion")
        broken.calls += 1
        return real(self, state, sample)

    broken.calls = 0
    monkeypatch.setattr(fPOS, "residual", broken)
    with pytest.raises(RuntimeError, match="a bug in the criterion"):
        solve_problem(solve, r, motion, targets, placement)


def test_the_fallback_point_misses_the_body_constraints_least_then_has_the_lowest_objective():
    """Where NLopt stops without a result the frame keeps, of the points it evaluated, the one that
    missed the collision and box constraints least (beyond their tolerances), the lowest objective
    among equals; not the lowest objective alone, which had put 2-Panda's arm into its chest."""
    from hlik.solvers.slsqp.solver import Evaluated

    seen = Evaluated()
    objective = seen.objective(lambda x, grad: float(x[0]))
    constraint = seen.constraint(lambda result, x, grad: result.__setitem__(slice(None), x[1]), 0.01)
    points = {"deep": (-5.0, 0.3), "shallow": (2.0, 0.02), "kept a": (4.0, 0.0), "kept b": (3.0, -1.0)}
    for x0, x1 in points.values():
        x = np.array([x0, x1])
        objective(x, np.empty(0))
        constraint(np.empty(1), x, np.empty((0, 2)))
    x, miss = seen.best()
    np.testing.assert_array_equal(x, [3.0, -1.0])
    assert miss == 0.0
    for key in ("kept a", "kept b"):  # without the points that keep it: the smallest miss wins
        seen.violation[np.array(points[key]).tobytes()] = 1.0
    x, miss = seen.best()
    np.testing.assert_array_equal(x, [2.0, 0.02])
    assert miss == pytest.approx(0.01)
