"""hlik.pipeline: one run from files to scores, the same for the library, the command line and the
study."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

import hlik
import hlik.pipeline
from hlik.cli import app
from hlik.criteria.learned import learn
from hlik.human.load import load_motion
from hlik.metrics import evaluate
from hlik.pipeline import RunSpec, run
from hlik.problem.placement import placement_from_spec
from hlik.problem.scale import scale_subject
from hlik.retarget import retarget
from hlik.robot.model import load_robot
from hlik.solvers import get_solver
from hlik.solvers.settings import settings_for
from hlik.solvers.stack_file import load_stack
from hlik.solvers.whole_take import WholeTake
from hlik.study.approaches import Approach
from hlik.study.dataset import Cell, run_cell
from hlik.util.errors import HlikError


@pytest.mark.parametrize(
    ("change", "said"),
    [
        ({"solver": "ik"}, "unknown solver 'ik'"),
        ({"solver": "jm", "criteria": ("SYN",)}, "jm maps joints and cannot add criteria"),
        ({"solver": "qp", "criteria": ("SYNN",)}, "SYNN"),
        ({"solver": "qp", "gradients": "fd"}, "--gradients fd is for --solver slsqp"),
        ({"solver": "slsqp", "gradients": "numeric"}, "unknown gradients 'numeric'"),
        ({"scenario": "grasp"}, "unknown scenario 'grasp'"),
        ({"rate": -5.0}, "--rate must be positive"),
        ({"rate": float("nan")}, "--rate must be positive"),
        ({"placement": "nan,0,0"}, "must be finite numbers"),
        ({"stack": "no_such_stack"}, "no_such_stack"),
        ({"stack": None}, "RunSpec.stack must be a name or a path, got None"),
        ({"robot": 6}, "RunSpec.robot must be a name or a path"),
        ({"solver": "qp", "criteria": "SYN"}, "RunSpec.criteria must be a sequence of names"),
    ],
)
def test_a_bad_setting_fails_in_one_line_before_anything_is_read(change, said, monkeypatch, cut_take):
    def read(*args, **kwargs):
        raise AssertionError("the motion was read")

    monkeypatch.setattr(hlik.pipeline, "load_motion", read)
    spec = RunSpec(motion=cut_take, **change)
    with pytest.raises(HlikError) as err:
        run(spec)
    assert said in str(err.value) and "\n" not in str(err.value)


def test_a_run_is_its_stages(cut_take):
    """run(spec) = read, scale, place, retarget, evaluate, composed by hand (the same numbers)."""
    spec = RunSpec(motion=cut_take, robot="armar3", solver="qp", criteria=("SYN",), span=(1.0, 1.4))
    result = run(spec)
    robot = load_robot("armar3")
    motion = scale_subject(load_motion(cut_take, rate=100.0).crop(1.0, 1.4), robot)
    learned = learn(robot)
    where = placement_from_spec(robot.placement, robot, motion)
    stack = load_stack("ee_pose").with_criteria(["SYN"])
    settings = stack.settings("qp", robot.name)  # its own table
    # then the whole take, as ee_pose chooses for the QP on ARMAR-III ([whole_take.robot.armar3] after)
    stage = settings_for(settings, stack.settings("whole_take", robot.name))
    traj = retarget(motion, robot, WholeTake(get_solver("qp", settings), stage), where, learned)
    ev = evaluate(traj, robot, learned)
    np.testing.assert_array_equal(result.trajectory.q, traj.q)
    assert result.evaluation.m_hl == ev.m_hl and result.evaluation.m_f == ev.m_f
    np.testing.assert_array_equal(result.evaluation.fpos, ev.fpos)
    m_hl, m_f = result.evaluation.unified_curves()
    assert np.isclose(m_hl.mean(), ev.m_hl) and np.isclose(m_f.mean(), ev.m_f)
    assert result.motion.n_frames == 41 and result.scenario == "pose" and result.solve_cpu > 0


def test_the_command_line_and_a_study_cell_run_the_pipeline(cut_take, tmp_path):
    """The same spec through ``hlik run`` and a study cell gives the library's trajectory."""
    spec = RunSpec(motion=cut_take, robot="armar6", solver="qp", stack="paper_opt", criteria=("HJA_r",))
    cell = Cell(cut_take, "armar6", Approach("qp", ("HJA_r",)), seconds=0.3)
    result = run(replace(spec, span=(1.0, 1.3)))
    robot = result.robot
    table = run_cell(cell, robot, result.learned)
    np.testing.assert_allclose(table.column("fpos_left").to_numpy(), result.evaluation.fpos[:, 0])
    out = tmp_path / "x.rrd"
    args = ["run", str(cut_take), "-r", "armar6", "-s", "qp", "--stack", "paper_opt", "--criteria", "HJA_r"]
    done = CliRunner().invoke(app, [*args, "--rate", "50", "-o", str(out)])
    assert done.exit_code == 0, done.output
    whole = run(replace(spec, rate=50.0), robot=robot, learned=result.learned)
    np.testing.assert_array_equal(hlik.load_trajectory(out.with_suffix(".npz")).q, whole.trajectory.q)


def test_shared_stage_outputs_are_used_not_recomputed(cut_take, monkeypatch):
    """A caller's motion, placement and learned pieces go straight to the solver (the study's
    approaches of one take share them)."""
    robot = load_robot("armar6")
    spec = RunSpec(motion=cut_take, span=(1.0, 1.2))
    first = run(spec, robot=robot)

    def fail(*args, **kwargs):
        raise AssertionError("recomputed")

    for name in ("load_motion", "learn", "place"):
        monkeypatch.setattr(hlik.pipeline, name, fail)
    stages: list[str] = []
    again = run(
        spec,
        lambda stage, done, total: stages.append(stage),
        robot=robot,
        motion=first.motion,
        learned=first.learned,
        placement=first.trajectory.placement,
    )
    np.testing.assert_array_equal(again.trajectory.q, first.trajectory.q)
    assert stages[0].startswith("retargeting to ARMAR-6") and stages[-1] == "evaluating the criteria"


@pytest.mark.parametrize("solver", ["jv", "qp", "slsqp"])
def test_a_solver_never_learns_given_a_built_problem(solver, tmp_path, monkeypatch):
    """The learned pieces come with the problem: a solver with learning criteria runs with the
    cache folder read-only, no corpus and ``learn`` itself broken."""
    import hlik.criteria.learned
    import hlik.problem.problem
    from hlik.human.demo import demo_motion
    from hlik.problem.problem import build_problem

    robot = load_robot("armar6")
    motion = demo_motion().crop(1.0, 1.2)
    criteria = ("SYN", "EEA", "MAN_r")
    problem = build_problem(motion, robot, learned=learn(robot), criteria=criteria)

    def never(*args, **kwargs):
        raise AssertionError("a solver learned")

    monkeypatch.setattr(hlik.criteria.learned, "learn", never)
    monkeypatch.setattr(hlik.problem.problem, "learn", never)
    monkeypatch.setenv("HLIK_CORPUS", str(tmp_path / "no corpus"))
    monkeypatch.setenv("HLIK_CACHE", str(tmp_path))
    tmp_path.chmod(0o500)
    try:
        settings = load_stack("ee_pose").with_criteria(list(criteria)).settings(solver)
        result = get_solver(solver, settings)(problem)
    finally:
        tmp_path.chmod(0o700)
    assert result.q.shape == (motion.n_frames, robot.dof) and not result.diagnostics.failed.any()


def test_the_problem_learns_once_and_only_for_criteria_that_learn(monkeypatch):
    """build_problem learns where a criterion is built from learned pieces, not for plain tracking
    or JM; a problem without them refuses such a criterion by name."""
    import hlik.problem.problem
    from hlik.human.demo import demo_motion
    from hlik.problem.problem import build_problem
    from hlik.util.errors import SettingsError

    robot = load_robot("armar3")
    motion = demo_motion().crop(1.0, 1.1)
    calls: list[str] = []
    real = hlik.problem.problem.learn
    monkeypatch.setattr(hlik.problem.problem, "learn", lambda r, corpus=None: calls.append(r.name) or real(r))
    assert build_problem(motion, robot, criteria=("HJA_r", "MJE")).learned is None and calls == []
    assert build_problem(motion, robot, criteria=("HJA_r", "SYN")).learned is not None and calls == ["armar3"]
    traj = retarget(
        motion, robot, get_solver("qp", load_stack("ee_pose").with_criteria(["MIS"]).settings("qp"))
    )
    assert calls == ["armar3", "armar3"] and traj.n_frames == motion.n_frames
    bare = build_problem(motion, robot)
    settings = load_stack("ee_pose").with_criteria(["EEA"]).settings("qp")
    with pytest.raises(SettingsError, match="criterion EEA is built from learned swivel"):
        get_solver("qp", settings)(bare)


def test_a_callers_limit_runs_through_the_whole_pipeline(cut_take):
    """``hlik.run(spec, limits=[...])``: a user's ``mink.Limit`` (ARMAR-6's left elbow at most 0.6
    rad, kept the braking margin v^2 / (2 a) inside as the README says) holds in every frame of the
    run ``hlik run`` would make; JM, which keeps no limits, refuses one."""
    from mink.limits import Constraint, Limit

    robot = load_robot("armar6")
    j, bound = robot.joint_names.index("ArmL6_Elb2"), 0.6
    margin = robot.velocity_limit[j] ** 2 / (2.0 * robot.acceleration_limit[j])

    class Below(Limit):
        def compute_qp_inequalities(self, configuration, dt):
            g = np.zeros((1, robot.dof))
            g[0, j] = 1.0
            return Constraint(G=g, h=np.array([bound - margin - configuration.q[j]]))

    spec = RunSpec(motion=cut_take, robot="armar6", solver="qp", span=(1.0, 2.0))
    free = run(spec, robot=robot).trajectory
    held = run(spec, robot=robot, limits=[Below()]).trajectory
    assert free.q[:, j].max() > bound  # the premise: without it the elbow passes the bound
    assert held.q[:, j].max() <= bound + 1e-6
    with pytest.raises(HlikError, match="keeps no limits"):
        get_solver("jm", limits=[Below()])


def test_a_time_scaled_run_is_the_same_joint_path_at_a_fraction_of_the_speed():
    """JM of the demo's first second played twice as long: every other frame is the plain run's
    frame (the same poses), and the joints move at half the speed."""
    spec = RunSpec(robot="armar6", solver="jm", placement="mapped", span=(0.0, 1.0))
    plain = run(spec).trajectory
    slow = run(replace(spec, time_scale=2.0)).trajectory
    assert slow.n_frames == 2 * plain.n_frames - 1
    np.testing.assert_allclose(slow.q[::2], plain.q, atol=1e-9)
    speed = lambda t: np.abs(np.diff(t.q, axis=0)).max() / t.period  # noqa: E731
    assert speed(slow) == pytest.approx(speed(plain) / 2, rel=0.1)
