"""The criterion registry: every registered criterion's Jacobian, its cost in evaluate and in the
solvers, and a new criterion registered from outside running through every solver and evaluate."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import central_differences, random_frame
from hlik.criteria import registry
from hlik.criteria.base import Criterion
from hlik.criteria.learned import learn
from hlik.human.demo import demo_motion
from hlik.metrics import costs, evaluate
from hlik.problem.problem import build_problem
from hlik.retarget import retarget
from hlik.robot.state import robot_state
from hlik.solvers import SOLVER_NAMES, SPECS, get_solver
from hlik.solvers.frames import sample_at
from hlik.solvers.gradients import gradient, metric, part_gradients, part_metric
from hlik.solvers.jv import JVSettings
from hlik.solvers.qp import QPSettings
from hlik.solvers.slsqp import SLSQPSettings
from hlik.solvers.stack_file import load_stack
from hlik.util.errors import SettingsError

ALL = registry.human_likeness() + registry.functional()


def test_registry_lists_the_papers_criteria_once():
    papers = ("EEA", "SOA_x", "SOA_q", "HJL", "SYN", "MIS", "MJE", "HJA_r", "SYN_r", "EEA_r", "MAN_r")
    listed = registry.human_likeness()
    assert listed[: len(papers)] == papers and len(set(listed)) == len(listed)  # the paper's first, once
    assert registry.functional() == ("fJLA", "fPOS", "fORI", "fPOS_off", "fORI_off")
    assert sum(registry.criterion_class(n).weight for n in registry.human_likeness()) == pytest.approx(1.0)
    with pytest.raises(KeyError, match="unknown criterion 'NOPE'"):
        registry.criterion_class("NOPE")
    with pytest.raises(ValueError, match="registered already"):
        registry.register(type("Clash", (Criterion,), {"name": "SYN"}))


def test_a_built_in_is_found_by_its_name_attribute_not_its_class_name():
    """A module listed in ``_BUILTIN`` may call its class anything: the class whose ``name`` is the
    criterion's is found, and a module with none is named in one line."""
    import types

    module = types.ModuleType("toy_module")
    module.ElbowDown = type("ElbowDown", (Criterion,), {"name": "ELB"})
    assert registry._named(module, "ELB") is module.ElbowDown
    with pytest.raises(SettingsError, match="module toy_module has no class with name = 'XYZ'"):
        registry._named(module, "XYZ")


@pytest.mark.parametrize("name", ALL)
def test_every_exact_jacobian_matches_central_differences(robot, name):
    crit = registry.criterion(name, robot, learn(robot))
    sample, q = random_frame(robot, 3)
    state = robot_state(robot, q, jacobians=True)
    jac = crit.jacobian(state, sample)[0]
    e = crit.residual(state, sample)[0]
    assert np.all(np.isfinite(e)) and np.all(np.isfinite(jac)) and jac.shape == (len(e), robot.dof)
    if not crit.exact_jacobian:
        return  # a prediction held fixed (EEA, SOA) or first order (fORI): tested in their own modules
    fd = central_differences(lambda x: crit.residual(robot_state(robot, x, jacobians=True), sample)[0], q)
    np.testing.assert_allclose(jac, fd, atol=2e-5 * max(1.0, np.abs(fd).max()))
    if crit.solver_form is not None:
        return  # the solvers minimise a stand-in (MIS: a velocity penalty); they report crit.cost
    h, dh_de = metric(crit, e)  # the solvers' h and dh/de equal the vectorised cost's
    assert h == pytest.approx(float(crit.cost(e[None])[0]))
    np.testing.assert_allclose(dh_de, central_differences(lambda x: crit.cost(x[None]), e)[0], atol=1e-5)


@pytest.mark.parametrize("name", ALL)
def test_every_criterion_declares_the_sites_it_reads(robot, name):
    """The solvers compute only the site Jacobians the terms declare (``sites`` for the Jacobian,
    ``value_sites`` for the residual) and leave the others zero: with only the declared ones, each
    criterion's residual, Jacobian and exact Jacobian equal those computed from every site's."""
    crit = registry.criterion(name, robot, learn(robot))
    sample, q = random_frame(robot, 4)
    full = robot_state(robot, q, jacobians=True)
    declared = robot_state(
        robot, q, jacobians=True, jacobian_sites=tuple(sorted({*crit.sites, *crit.value_sites}))
    )
    e, jac = crit(declared, sample)
    e_full, jac_full = crit(full, sample)
    np.testing.assert_array_equal(e, e_full)
    np.testing.assert_array_equal(jac, jac_full)
    np.testing.assert_array_equal(crit.exact(declared, sample)[1], crit.exact(full, sample)[1])
    values = robot_state(robot, q, jacobians=True, jacobian_sites=tuple(crit.value_sites))
    np.testing.assert_array_equal(crit.residual(values, sample), crit.residual(full, sample))


@pytest.mark.parametrize("name", registry.human_likeness())
def test_every_criterion_gradient_matches_central_differences_of_its_cost(robot, name):
    """SLSQP and JV differentiate h through ``gradient``: exact for every criterion, also where the
    QP's Jacobian holds a prediction fixed (EEA, EEA_r, SOA_x, SOA_q chain it through)."""
    crit = registry.criterion(name, robot, learn(robot))
    if crit.solver_form is not None:
        pytest.skip(f"{name}: the solvers minimise a stand-in ({crit.solver_form})")
    assert crit.numeric_gradient_cap is None  # no criterion of the paper's needs numeric gradients

    def cost(x, sample):
        return np.array([metric(crit, crit(robot_state(robot, x, jacobians=True), sample)[0])[0]])

    for seed in (3, 4):
        sample, q = random_frame(robot, seed)
        h, grad = gradient(crit, robot_state(robot, q, jacobians=True), sample)
        fd = central_differences(lambda x, s=sample: cost(x, s), q)[0]
        assert h == pytest.approx(cost(q, sample)[0])
        np.testing.assert_allclose(grad, fd, atol=2e-5 * max(1.0, np.abs(fd).max()))


@pytest.mark.parametrize("name", ALL)
def test_every_criterion_splits_into_parts_whose_mean_is_its_cost(robot, name):
    """SLSQP puts each arm's part of a two-arm cost through its own groove loss: the parts' mean is
    h, each is zero when its arm's rows are, and each part's gradient is exact."""
    crit = registry.criterion(name, robot, learn(robot))
    sample, q = random_frame(robot, 5)
    state = robot_state(robot, q, jacobians=True)
    e = crit(state, sample)[0]
    parts, d_parts = part_metric(crit, e)
    assert parts.shape == (crit.parts,) and d_parts.shape == (crit.parts, len(e))
    assert parts.mean() == pytest.approx(metric(crit, e)[0], rel=1e-12, abs=1e-15)
    for p, rows in enumerate(crit.part_rows(len(e))):
        kept = np.zeros_like(e)
        kept[rows] = e[rows]
        assert part_metric(crit, kept)[0][p] == pytest.approx(parts[p], rel=1e-12, abs=1e-15)
    if crit.solver_form is not None:
        return  # its gradient is the stand-in's, checked above through metric
    h, grad = part_gradients(crit, state, sample)
    fd = central_differences(
        lambda x: part_metric(crit, crit(robot_state(robot, x, jacobians=True), sample)[0])[0], q
    )
    np.testing.assert_allclose(h, parts, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(grad, fd, atol=2e-5 * max(1.0, np.abs(fd).max()))


def test_evaluate_reports_the_cost_the_solvers_compute(robot):
    """Per frame, evaluate's h equals the criterion's cost on that frame's configuration and sample."""
    learned = learn(robot)
    traj = retarget(
        demo_motion().crop(1.0, 1.3), robot, get_solver("qp", QPSettings(max_iter=3)), learned=learned
    )
    h = costs(traj, robot, learned)
    problem = build_problem(traj.motion, robot, traj.placement)
    for k in (0, 1, 2, 5, traj.n_frames - 1):
        history = np.stack([traj.q[max(k - i, 0)] for i in (1, 2, 3)])
        sample = sample_at(problem.reference, problem.targets, k, history, problem.dt)
        state = robot_state(robot, traj.q[k], jacobians=True)
        for name in ALL:
            crit = registry.criterion(name, robot, learned)
            assert crit.cost(crit.residual(state, sample))[0] == pytest.approx(
                h[name][k], rel=1e-9, abs=1e-12
            ), (
                name,
                k,
            )


class Toy(Criterion):
    """A toy criterion registered from outside hlik: the first arm joint toward 0.3 rad."""

    name, gamma, x0, weight = "TOY", 1.0, 0.05, 0.0
    needs_sample, sites = False, ()

    def __init__(self, robot, learned=None):
        self.joint = robot.index(robot.arm_joints["left"][0])
        self.constant_jacobian = np.zeros((1, robot.dof))
        self.constant_jacobian[0, self.joint] = 1.0

    def residual(self, state, sample):
        return state.q[:, [self.joint]] - 0.3


@pytest.fixture()
def toy():
    registry.register(Toy)
    yield Toy
    registry.unregister("TOY")


def test_a_registered_criterion_runs_through_every_solver_and_evaluate(toy):
    from hlik.robot.model import load_robot

    r = load_robot("dual_panda")
    learned = learn(r)
    motion = demo_motion().crop(1.0, 1.3)
    stack = load_stack("ee_pose").with_criteria(["TOY"])  # stack files accept it by name
    settings = {
        "jv": replace(stack.settings("jv"), max_iter=20),
        "qp": replace(stack.settings("qp"), criterion_cost=5.0),
        "slsqp": replace(stack.settings("slsqp"), max_eval=30),
        "mink": replace(stack.settings("mink"), criterion_cost=5.0),
    }
    for name in SOLVER_NAMES:
        if not SPECS[name].takes_criteria:
            continue
        plain = retarget(motion, r, get_solver(name, replace(settings[name], criteria=())), learned=learned)
        with_toy = retarget(motion, r, get_solver(name, settings[name]), learned=learned)
        ev, ev0 = evaluate(with_toy, r, learned), evaluate(plain, r, learned)
        assert "TOY" in ev.m and np.isfinite(ev.h["TOY"]).all(), name
        assert ev.m_hl == pytest.approx(ev0.m_hl, abs=0.2)  # weight 0: scored, not in m_hl's sum
        if name in ("qp", "mink"):  # where the null space allows it, the criterion acts
            assert np.mean(ev.h["TOY"]) < np.mean(ev0.h["TOY"]), name
    assert isinstance(get_solver("jv", JVSettings(criteria=("TOY",))), object)
    assert isinstance(SLSQPSettings(criteria=("TOY",)), SLSQPSettings)


def test_the_readmes_toy_criterion_does_what_it_says():
    """README "Extending hlik": its ElbowDown, registered from a script, has the Jacobian of its
    residual (central differences, on a robot whose shoulders move: ARMAR-III's hip) and, added to
    the QP, brings the elbows down (the example first pulled them up to the shoulders)."""
    from pathlib import Path

    import hlik
    from hlik.robot.model import load_robot
    from hlik.robot.state import robot_state

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    start = text.index("import numpy as np\nfrom hlik.criteria import registry")
    namespace: dict = {}
    exec(text[start : text.index("```", start)], namespace)  # noqa: S102 - the README's own block
    try:
        robot = load_robot("armar3")
        crit = registry.criterion("ELB", robot)
        rng = np.random.default_rng(3)
        q = robot.home + rng.uniform(-0.3, 0.3, (4, robot.dof))
        state = robot_state(robot, q, jacobians=True)
        numeric = central_differences(lambda x: crit.residual(robot_state(robot, x), None), q)
        np.testing.assert_allclose(crit.jacobian(state, None), numeric, atol=1e-6)
        # where reach stands ARMAR-6 (unscaled) it raises its elbows; its default keeps them down
        spec = dict(motion=None, robot="armar6", solver="qp", span=(2.0, 3.0), placement="reach", scale=1.0)
        plain = hlik.run(hlik.RunSpec(**spec, criteria=()))
        down = hlik.run(hlik.RunSpec(**spec, criteria=("ELB",)))

        def above(result) -> float:  # mean elbow height over the shoulder minus 20 cm, where above
            s = robot_state(result.robot, result.trajectory.q)
            return float(np.maximum(s.elbow[..., 2] - s.shoulder[..., 2] + 0.2, 0.0).mean())

        assert (
            above(down) < above(plain) and down.evaluation.h["ELB"].mean() < plain.evaluation.h["ELB"].mean()
        )
    finally:
        registry.unregister("ELB")
