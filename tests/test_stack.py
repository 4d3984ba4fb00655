"""Task-stack files: the bundled stacks, their settings, and one-line errors for bad files."""

from __future__ import annotations

from dataclasses import replace

import pytest
from typer.testing import CliRunner

from hlik.cli import app
from hlik.solvers.qp import QPSettings
from hlik.solvers.stack_file import bundled_stacks, load_stack
from hlik.util.errors import HlikError, SettingsError
from hlik.util.paths import tasks_dir


def test_bundled_stacks_load_for_every_solver():
    assert set(bundled_stacks()) >= {"ee_pose", "relative_pose"}
    for name in bundled_stacks():
        stack = load_stack(tasks_dir() / f"{name}.toml")
        assert dict(stack.gamma) == {}  # Table II's gamma come from the criteria themselves
        for solver in ("qp", "jv", "slsqp"):
            settings = stack.settings(solver)
            assert settings.scenario == stack.scenario and settings.criteria == stack.criteria
    assert load_stack("ee_pose").criteria == ("SYN", "HJA_r")  # hlik run's default: the hands and SYN, HJA_r


def test_ee_pose_stack_is_the_qp_default():
    """The file a user copies and the defaults of the Python API are the same stack, but for the
    criteria the file adds (the settings' default is the bare solver)."""
    assert load_stack("ee_pose").with_criteria([]).settings("qp") == QPSettings()


def test_a_solver_gamma_table_overrides_the_stack_gamma_for_that_solver_alone(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text("[gamma]\nSYN = 3.0\nEEA = 1.0\n[slsqp.gamma]\nSYN = 8.0\n")
    stack = load_stack(path)
    assert dict(stack.settings("slsqp").gamma) == {"SYN": 8.0, "EEA": 1.0}
    assert dict(stack.settings("jv").gamma) == {"SYN": 3.0, "EEA": 1.0}
    # on top of the solver's own: the QP doubles HJA_r's Table II gamma
    assert dict(stack.settings("qp").gamma) == {"HJA_r": 4.0, "SYN": 3.0, "EEA": 1.0}


def test_a_robot_table_overrides_the_solver_table_for_that_robot_alone(tmp_path):
    """``[qp.robot.NAME]`` over ``[qp]`` for the robot named NAME, in the QP and the mink stack
    that starts from it; other robots and solvers keep the solver's table."""
    path = tmp_path / "mine.toml"
    path.write_text("[qp]\norientation_cost = 2.0\n[qp.robot.armar6]\norientation_cost = 3.0\n")
    stack = load_stack(path)
    assert tuple(stack.robots["qp"]) == ("armar6",)
    assert stack.settings("qp", "armar6").orientation_cost == 3.0
    assert stack.settings("mink", "armar6").orientation_cost == 3.0
    assert stack.settings("qp", "armar3").orientation_cost == 2.0
    assert stack.settings("qp").orientation_cost == 2.0
    ee = load_stack("ee_pose")
    assert (
        ee.settings("slsqp", "armar6").orientation_cost > ee.settings("slsqp", "dual_panda").orientation_cost
    )


def test_a_robot_table_named_like_the_robot_but_misspelt_is_noted(tmp_path):
    """A table for ``armar7`` on an ARMAR-6 run is left unused with a note (a typo, likely); one
    for another robot (``dual_panda``) or for the robot itself says nothing."""
    path = tmp_path / "mine.toml"
    path.write_text(
        "[qp.robot.armar7]\norientation_cost = 3.0\n[qp.robot.dual_panda]\norientation_cost = 4.0\n"
    )
    stack = load_stack(path)
    notes = stack.near_misses("qp", "armar6")
    assert len(notes) == 1 and "[qp.robot.armar7] is not used for robot 'armar6'" in notes[0]
    assert stack.near_misses("mink", "armar6") == notes  # the mink stack starts from [qp]
    assert stack.near_misses("qp", "dual_panda") == [] and stack.near_misses("slsqp", "armar6") == []
    # a bundled robot's table is meant for it: the bundled ee_pose's [qp.robot.armar6] on ARMAR-III
    assert load_stack("ee_pose").near_misses("qp", "armar3") == []
    assert stack.settings("qp", "armar6").orientation_cost == stack.settings("qp").orientation_cost
    # a user's robot named after the bundled one it copies: the bundled robot's tables do not tune it
    # (a reviewer's copy lost 2-Panda's look-ahead and stage silently: the left hand 3.7 -> 11.3 deg)
    copied = load_stack("ee_pose").near_misses("qp", "dual_panda_raised")
    assert [n.split("] ")[0].split("[")[1] for n in copied] == [
        "qp.robot.dual_panda",
        "whole_take.robot.dual_panda",
    ]
    assert all("copy the table as [" in n and "dual_panda_raised]" in n for n in copied), copied


def test_a_run_reads_its_robot_s_table():
    """The pipeline gives the solver the stack's settings for the robot it retargets to."""
    from hlik.pipeline import RunSpec, solver_settings

    spec = RunSpec(robot="armar6", solver="qp")
    stack = load_stack("ee_pose")
    assert solver_settings(spec, stack, "armar6") == stack.settings("qp", "armar6") != stack.settings("qp")


def test_relative_stack_scales_criteria_by_ten():
    pose, relative = load_stack("ee_pose"), load_stack("relative_pose")
    assert relative.scenario == "relative"
    ratio = relative.settings("qp").criterion_cost / pose.settings("qp").criterion_cost
    assert ratio == pytest.approx(10.0)


def test_with_criteria_replaces_the_list():
    stack = load_stack("ee_pose").with_criteria(["SYN", "HJA_r"])
    assert stack.settings("qp").criteria == ("SYN", "HJA_r")
    with pytest.raises(HlikError, match="unknown criteria FOO"):
        stack.with_criteria(["FOO"])


@pytest.mark.parametrize(
    "text, problem",
    [
        ("scenario = 'sideways'", "unknown scenario 'sideways'"),
        ("criteria = ['SYN', 'XYZ']", "unknown criteria XYZ"),
        ("criteria = 'SYN'", "criteria must be a list"),
        ("[qp]\nposition_cost = 'high'", "[qp] position_cost must be a number"),
        ("[qp]\nspeed = 1.0", "unknown key 'speed' in [qp]"),
        ("[gamma]\nSYN = true", "[gamma] SYN must be a number"),
        ("[qp.gamma]\nXYZ = 1.0", "unknown criteria XYZ"),
        ("[qp]\ngamma = 3", "[qp.gamma] must be a table"),
        ("[qp.gamma]\nSYN = 'x'", "[qp.gamma] SYN must be a number"),
        ("[qp]\nself_collision = 1", "[qp] self_collision must be true or false"),
        ("colour = 'red'", "unknown key 'colour' in the top level"),
        ("hands_first = true", "hands_first is a solver's setting: put it in [qp] or [mink]"),
        ("[qp.robot.armar6]\nspeed = 1.0", "unknown key 'speed' in [qp.robot.armar6]"),
        ("[qp.robot.armar6]\norientation_cost = 'x'", "[qp.robot.armar6] orientation_cost must be a number"),
        ("[qp.robot.armar6.gamma]\nSYN = 1.0", "unknown key 'gamma' in [qp.robot.armar6]"),
        ("[qp]\nrobot = 3", "[qp.robot] must hold one table per robot name"),
        ("scenario = ", "not valid TOML"),
        # the whole-take stage's solvers to follow (hlik run without --whole-take / --no-whole-take)
        ('[whole_take]\nafter = "qp"', "after must be a list of solvers"),
        ('[whole_take.robot.armar3]\nafter = ["jm"]', "after must be a list of solvers"),
        ('[whole_take]\nafter = ["qp", 3]', "after must be a list of solvers"),
        ('scenario = "relative"\n[whole_take]\nafter = ["qp"]', "tracks their relative pose"),
        ('after = ["qp"]', "put it in [whole_take]"),
    ],
)
def test_bad_stack_files_name_the_file_and_the_problem(tmp_path, text, problem):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(HlikError, match="bad.toml") as err:
        load_stack(path)
    assert str(err.value).startswith(str(path)), err.value
    assert problem in str(err.value) and "\n" not in str(err.value)


def test_missing_stack_lists_the_bundled_ones(tmp_path):
    with pytest.raises(HlikError, match="no such stack file.*ee_pose"):
        load_stack(tmp_path / "nothing.toml")


def test_cli_rejects_a_bad_stack_before_solving(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[qp]\nspeed = 1.0")
    out = tmp_path / "x.rrd"
    result = CliRunner().invoke(app, ["run", "--solver", "qp", "--stack", str(bad), "--out", str(out)])
    assert result.exit_code == 2
    assert "bad.toml" in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not out.exists() and not out.with_suffix(".npz").exists()


def test_stack_slsqp_settings_are_the_papers():
    from hlik.solvers.settings import SLSQPSettings

    assert load_stack("paper_opt").settings("slsqp") == SLSQPSettings()  # the paper's OPT
    tuned = load_stack("ee_pose").with_criteria([]).settings("slsqp")
    assert tuned.gamma == {"SYN": 3.0, "SOA_x": 2.0, "EEA": 2.0, "MIS": 0.25}  # hands first: README
    paper = replace(tuned, criterion_cost=10.0, max_eval=100, orientation_cost=9.0, elbow_cost=0.0, gamma={})
    assert paper == SLSQPSettings()
    relative = load_stack("relative_pose").settings("slsqp")
    assert relative == SLSQPSettings.relative()


@pytest.mark.parametrize(
    "solver, extra",
    [
        ("jv", ["--criteria", "HJA_r"]),
        ("slsqp", ["--criteria", "SYN,HJA_r"]),
        ("slsqp", ["--gradients", "fd", "--no-whole-take"]),
        ("qp", ["--stack", "relative_pose", "--criteria", "SYN"]),
    ],
)
def test_cli_runs_every_solver_from_a_stack(takes, tmp_path, solver, extra):
    from hlik.trajectory import load_trajectory

    out = tmp_path / "r.rrd"
    args = ["run", str(takes[4]), "--rate", "10", "--robot", "armar3", "--solver", solver, *extra]
    result = CliRunner().invoke(app, [*args, "--out", str(out)])
    assert result.exit_code == 0, result.output
    traj = load_trajectory(out.with_suffix(".npz"))
    # ee_pose follows the QP and SLSQP with the whole-take stage on ARMAR-III ([whole_take] after)
    staged = solver in ("qp", "slsqp") and "relative_pose" not in extra and "--no-whole-take" not in extra
    assert traj.solver == solver + ("+whole" if staged else "") and out.is_file()
    assert ("(the stack's [whole_take] after" in result.stdout) == staged, result.stdout
    # and the recording's result panel, also where the stage did not run
    from rerun.chunk import RrdReader

    (panel,) = [
        c.to_record_batch().to_pylist()[-1]["TextDocument:text"][0]
        for c in RrdReader(out).stream().to_chunks()
        if c.is_static and c.entity_path == "/result"
    ]
    said = "yes (the stack's [whole_take] after)" if staged else "no (--no-whole-take)"
    said = said if staged or "--no-whole-take" in extra else "no (the stack's choice)"
    assert f"| whole take | {said} |" in panel, panel
    assert ("(relative)" in result.stdout) == ("relative_pose" in extra)  # scored as its stack says


@pytest.mark.parametrize(("solver", "said"), [("qp", True), ("mink", True), ("slsqp", False)])
def test_a_run_says_when_it_held_the_hands_first(takes, tmp_path, solver, said):
    """``hands_first = true`` in ``[qp]`` (which ``[mink]`` starts from): the summary's solver row
    says so (a new user could not tell it was on); SLSQP has no such setting, and says nothing."""
    stack = tmp_path / "first.toml"
    stack.write_text('name = "first"\ncriteria = ["SYN"]\n[qp]\nhands_first = true\n')
    out = tmp_path / "r.rrd"
    args = ["run", str(takes[4]), "--rate", "10", "--span", "1:3", "--robot", "armar6", "--solver", solver]
    result = CliRunner().invoke(app, [*args, "--stack", str(stack), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert ("the hands first (hands_first" in result.stdout) == said, result.stdout


@pytest.mark.parametrize(
    ("robot", "solver", "stack", "said", "pull"),
    [
        ("dual_panda", "qp", "ee_pose", True, "look-ahead pulled at 8 per rad"),
        ("armar6", "qp", "ee_pose", False, "look-ahead pulled at 3 per rad"),
        ("dual_panda", "slsqp", "ee_pose", False, "look-ahead pulled at 30 (preview_cost)"),
        ("armar6", "slsqp", "paper_opt", False, "one pass, no look-ahead (preview_cost)"),
    ],
)
def test_a_run_says_when_its_look_ahead_held_the_hands_first(
    takes, tmp_path, robot, solver, stack, said, pull
):
    """``ee_pose`` sets ``preview_hands_first`` for the QP on 2-Panda only (``[qp.robot.dual_panda]``):
    the summary's solver row says so there, and not on ARMAR-6; and it names each robot's pull,
    SLSQP's too, and that the paper's OPT (``paper_opt``) has none."""
    out = tmp_path / "r.rrd"
    args = ["run", str(takes[4]), "--rate", "10", "--span", "1:2", "--robot", robot, "--solver", solver]
    result = CliRunner().invoke(app, [*args, "--stack", stack, "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert ("look-ahead's path from the hands first" in result.stdout) == said, result.stdout
    assert pull in result.stdout, result.stdout


@pytest.mark.parametrize("hands_first", [False, True])
@pytest.mark.parametrize("preview_hands_first", [False, True])
@pytest.mark.parametrize("preview_cost", [0.0, 3.0])
def test_priority_names_what_the_qp_ranks_first(hands_first, preview_hands_first, preview_cost):
    """``QPSettings.priority``: every step's hands first wins; the look-ahead's hands first only
    counts with a pull (without one there is no first pass); else weighted."""
    from hlik.solvers.settings import QPSettings

    s = QPSettings(
        hands_first=hands_first, preview_hands_first=preview_hands_first, preview_cost=preview_cost
    )
    expected = (
        "hands_first"
        if hands_first
        else "preview_hands_first"
        if preview_hands_first and preview_cost > 0
        else "weighted"
    )
    assert s.priority == expected


def test_cli_rejects_fd_gradients_outside_slsqp():
    result = CliRunner().invoke(app, ["run", "--solver", "qp", "--gradients", "fd"])
    assert result.exit_code == 2 and "--gradients fd is for --solver slsqp" in result.stderr


def test_stack_jv_settings_are_the_defaults():
    from hlik.solvers.jv import JVSettings

    assert load_stack("ee_pose").with_criteria([]).settings("jv") == JVSettings()


def test_switches_and_collision_settings_read_from_a_stack_file(tmp_path):
    path = tmp_path / "s.toml"
    text = "[qp]\nself_collision = false\ncollision_margin = 0.02\n[slsqp]\nself_collision = false\n"
    path.write_text(text + "[jv]\nself_collision = false\ncollision_margin = 0.03\n")
    stack = load_stack(path)
    assert stack.settings("qp").self_collision is False and stack.settings("qp").collision_margin == 0.02
    assert stack.settings("slsqp").self_collision is False and stack.settings("jv").max_iter == 100
    jv = stack.settings("jv")
    assert jv.self_collision is False and jv.collision_margin == 0.03
    assert load_stack("ee_pose").settings("jv").self_collision is True


@pytest.mark.parametrize("value", ["no", 0, 1, 1.0, None])
@pytest.mark.parametrize("key", ["hands_first", "self_collision", "torque_limits", "acceleration_limits"])
def test_a_switch_given_from_python_is_true_or_false(key, value):
    """As a stack file's: ``hands_first="no"`` had turned the strict priority on (a new user)."""
    from hlik.solvers.settings import JVSettings, SLSQPSettings

    for settings in (QPSettings, SLSQPSettings, JVSettings):
        if key in settings.__dataclass_fields__:
            with pytest.raises(SettingsError, match=f"{settings.__name__}.{key} must be true or false"):
                settings(**{key: value})
    assert QPSettings(**{key: True}) != QPSettings(**{key: False})


@pytest.mark.parametrize(
    ("table", "key", "said"),
    [
        ("slsqp", "orientation", "now 'orientation_cost'"),
        ("jv", "weight", "now 'criterion_cost'"),
        ("qp", "velocity", "now 'velocity_cost'"),
        ("qp", "position_csot", "did you mean 'position_cost'?"),
    ],
)
def test_a_weight_by_its_old_or_a_misspelt_name_is_refused_with_the_name_to_use(tmp_path, table, key, said):
    """One name per weight across the solvers (``<what>_cost``): a stack file written with a
    solver's former name, or a typo, is refused naming the file, the table and the key to use."""
    path = tmp_path / "old.toml"
    path.write_text(f"[{table}]\n{key} = 1.0\n")
    with pytest.raises(SettingsError) as err:
        load_stack(path)
    message = str(err.value)
    assert (
        message.startswith(str(path)) and f"unknown key {key!r} in [{table}]" in message and said in message
    )


def test_a_velocity_limit_without_velocities_takes_the_robots():
    """mink's VelocityLimit limits nothing unless given speeds: from a stack file it gets the
    robot's joint speed limits, and speeds the file gives replace them."""
    import numpy as np

    import hlik
    from hlik.solvers.mink_specs import build

    for name in ("armar3", "dual_panda"):
        robot = hlik.load_robot(name)
        limit = build(robot, {"type": "VelocityLimit"})
        np.testing.assert_array_equal(limit.limit, robot.velocity_limit[limit.indices])
        assert len(limit.indices) == np.count_nonzero(np.isfinite(robot.velocity_limit)) > 0
        given = build(robot, {"type": "VelocityLimit", "velocities": {robot.joint_names[1]: 0.3}})
        assert list(given.indices) == [1] and list(given.limit) == [0.3]


def test_a_stack_file_names_mink_tasks_and_limits_beside_hlik_s(tmp_path):
    """``[mink]`` starts from ``[qp]`` and adds mink's own classes by name: ``--solver mink`` is the
    QP (the same joint angles without extras), and a PostureTask pulls the robot toward home; an
    unknown class or parameter is refused naming the file and the class."""
    import numpy as np

    import hlik
    from hlik.criteria.learned import learn
    from hlik.human.demo import demo_motion
    from hlik.solvers import get_solver

    path = tmp_path / "posture.toml"
    path.write_text(
        'criteria = ["HJA_r"]\n[qp]\nposition_cost = 20.0\n[mink]\n'
        'tasks = [{ type = "PostureTask", cost = 1.0 }]\nlimits = [{ type = "ConfigurationLimit" }]\n'
    )
    stack = load_stack(path)
    settings = stack.settings("mink")
    assert settings.position_cost == 20.0 and [t["type"] for t in settings.tasks] == ["PostureTask"]
    robot, motion = hlik.load_robot("armar6"), demo_motion().crop(2.0, 2.4)
    learned = learn(robot)
    qp = hlik.retarget(motion, robot, get_solver("qp", stack.settings("qp")), learned=learned)
    plain = replace(settings, tasks=(), limits=())
    same = hlik.retarget(motion, robot, get_solver("mink", plain), learned=learned)
    np.testing.assert_allclose(same.q, qp.q, atol=1e-9)
    posture = hlik.retarget(motion, robot, get_solver("mink", settings), learned=learned)
    home = lambda t: np.linalg.norm(t.q - robot.home, axis=1).mean()  # noqa: E731
    assert posture.solver == "mink" and home(posture) < home(qp)
    # the same stack under another solver says that [mink]'s own objects go unused
    assert stack.near_misses("mink", "armar6") == []
    assert stack.near_misses("qp", "armar6") == [
        f"{stack.path}: [mink] tasks and limits are used by --solver mink only, not qp"
    ]
    for text, said in (
        ('[mink]\ntasks = [{ type = "PostureTsk", cost = 1.0 }]', "unknown mink Task 'PostureTsk'"),
        ('[mink]\ntasks = [{ type = "PostureTask", costs = 1 }]', "it takes: cost, gain, lm_damping, target"),
        ('[mink]\ntasks = [{ type = "FrameTask", target = 1.0 }]', "FrameTask takes no 'target'"),
        ('[mink]\nlimits = [{ type = "PostureTask" }]', "unknown mink Limit 'PostureTask'"),
    ):
        path.write_text(text)
        with pytest.raises(SettingsError) as err:
            load_stack(path)
        assert str(err.value).startswith(f"{path}: [mink]") and said in str(err.value), str(err.value)


@pytest.mark.parametrize(
    "table, says",
    [
        ('tasks = [{ type = "PostureTask", cost = -0.05 }]', "[mink] tasks: PostureTask: PostureTask cost"),
        ('tasks = [{ type = "PostureTask", cost = 0.05, gain = 2.0 }]', "[mink] tasks: PostureTask:"),
        (
            'tasks = [{ type = "PostureTask", cost = 0.05, target = [0.1, 0.2] }]',
            "[mink] tasks: PostureTask:",
        ),
        (
            'tasks = [{ type = "FrameTask", frame_name = "left_elbow", frame_type = "site", '
            "position_cost = 1.0, orientation_cost = 0.0 }]",
            "[mink] tasks: FrameTask needs a target",
        ),
        ('limits = [{ type = "CollisionAvoidanceLimit" }]', "[mink] limits: CollisionAvoidanceLimit:"),
        ('limits = [{ type = "ConfigurationLimit", gain = 5.0 }]', "[mink] limits: ConfigurationLimit:"),
        # mink's KeyError for a joint it does not know (a traceback before; a new user's trial)
        (
            'limits = [{ type = "VelocityLimit", velocities = { foo = 1.0 } }]',
            "[mink] limits: VelocityLimit: Invalid name 'foo'",
        ),
    ],
)
def test_a_value_mink_refuses_is_one_line_naming_the_file_before_the_work(tmp_path, table, says):
    """mink's own checks (a negative cost, a gain past 1, a target of the wrong shape, a missing
    parameter) and a task whose target a stack file cannot give: one line naming the stack file,
    ``[mink]`` and the list, exit 2, nothing written (it was a traceback after placement and
    learning, a new user's trial)."""
    stack = tmp_path / "mine.toml"
    stack.write_text((tasks_dir() / "ee_pose.toml").read_text() + f"\n[mink]\n{table}\n")
    out = tmp_path / "out" / "r.rrd"
    out.parent.mkdir()
    args = ["run", "--solver", "mink", "--stack", str(stack), "--span", "0:0.2", "--out", str(out)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {stack}: ") and says in lines[0], lines
    assert list(out.parent.iterdir()) == []


def test_a_frame_task_on_a_tcp_follows_the_hands(tmp_path):
    """A mink FrameTask on ``left_tcp`` needs no target in the file: the solver aims it at the left
    hand's every frame (and the run keeps that hand on its target)."""
    stack = tmp_path / "tcp.toml"
    task = (
        '{ type = "FrameTask", frame_name = "left_tcp", frame_type = "site", position_cost = 1.0, '
        "orientation_cost = 0.5 }"
    )
    stack.write_text((tasks_dir() / "ee_pose.toml").read_text() + f"\n[mink]\ntasks = [{task}]\n")
    out = tmp_path / "r.rrd"
    args = ["run", "--solver", "mink", "--stack", str(stack), "--span", "0:0.5", "--out", str(out)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert out.exists() and "mink's own FrameTask ([mink])" in result.stdout
