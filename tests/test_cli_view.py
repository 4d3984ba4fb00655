"""What a user meets on the command line (issue 16): default output names that differ for runs
that differ, no silent overwrites, warnings at the end of ``hlik run``, progress callbacks, a quick
``hlik --help``, flags shown as flags, an unbroken ``rerun <path>`` line, a configurable corpus."""

from __future__ import annotations

import itertools
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import hlik
from conftest import data_file, kit_takes
from hlik.cli import app
from hlik.cli.run import _run_tag
from hlik.criteria.functional import position_error
from hlik.findings import below_floor, run_warnings
from hlik.human.load import load_motion
from hlik.human.mmm_format import write_mmm
from hlik.problem.placement import Placement
from hlik.trajectory import load_trajectory
from hlik.util.errors import SettingsError
from hlik.util.paths import corpus_setting, tasks_dir

WARNING = re.compile(
    r"warning: (left|right) hand more than 5 cm off its target in (\d+) of (\d+) frames \(\d+ %\), "
    r"up to (\d+\.\d) cm"
)


def invoke(*args: object, env: dict | None = None):
    return CliRunner().invoke(app, [str(a) for a in args], env=env)


def one_line_error(result, *named: str) -> str:
    err = result.stderr.strip()
    assert result.exit_code == 2, (result.exit_code, result.output)
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    for part in named:
        assert part in err, (part, err)
    return err


@pytest.fixture(scope="module")
def short_take(tmp_path_factory) -> Path:
    """Two seconds of a KIT take (10 Hz), as its own MMM file."""
    path = tmp_path_factory.mktemp("take") / "short.xml"
    write_mmm(load_motion(kit_takes()[0]).crop(0.0, 2.0), path)
    return path


# --- 1. default names and --force --------------------------------------------------------------

BASE = dict(
    solver="qp",
    stack="ee_pose",
    default_stack=True,
    criteria=("SYN", "HJA_r"),  # ee_pose's own
    stack_criteria=("SYN", "HJA_r"),
    gradients="analytic",
    placement=None,
    scenario=None,
    metric=None,
    rate=100.0,
    layout="side",
    corpus=None,
)
VARIANTS = {
    "solver": ["jm", "jv", "slsqp"],
    "stack": [("my", False), ("relative_pose", False)],
    "criteria": [(), ("SYN",), ("SYN", "HJA_r", "EEA")],
    "gradients": ["fd"],
    "placement": ["mapped", "0.5,1,90"],
    "scenario": ["relative"],
    "metric": [Path("study/metric.toml")],
    "rate": [0.0, 50.0],
    "layout": ["overlay"],
    "corpus": [Path("/data/kit")],
    "span": [(1.0, 3.0)],
    "time_scale": [2.0, 0.5],
    "whole_take": [True],
}


def _tag(**changes) -> str:
    options = {**BASE, **changes}
    if isinstance(options["stack"], tuple):
        options["stack"], options["default_stack"] = options["stack"]
    return _run_tag(**options)


def test_default_names_differ_for_runs_that_differ():
    """Every option that changes the result changes the name, alone and in pairs."""
    single = [{k: v} for k, values in VARIANTS.items() for v in values]
    pairs = [a | b for a, b in itertools.combinations(single, 2) if a.keys() != b.keys()]
    runs = [{}, *single, *pairs]
    tags = [_tag(**run) for run in runs]
    assert len(set(tags)) == len(tags), [t for t in tags if tags.count(t) > 1]
    assert _tag() == "qp"  # the defaults add nothing
    assert all(re.fullmatch(r"[\w.,+-]+", t) for t in tags)


def test_default_name_says_the_whole_take_where_the_run_differs_from_its_stack():
    """``--whole-take`` / ``--no-whole-take`` change the name only against what the stack does for
    the solver and robot (ee_pose: the stage after the QP on 2-Panda, not on ARMAR-6)."""
    assert _tag(whole_take=None) == _tag(whole_take=False) == "qp" and _tag(whole_take=True) == "qp-whole"
    staged = {"whole_take_default": True}
    assert _tag(whole_take=None, **staged) == _tag(whole_take=True, **staged) == "qp"
    assert _tag(whole_take=False, **staged) == "qp-alone"


def test_default_name_leaves_out_the_stacks_own_criteria():
    assert _tag() == "qp" and _tag(criteria=()) == "qp_nocriteria" and _tag(criteria=("SYN",)) == "qp_SYN"
    # a stack of the user's always names its criteria; one without any names none
    assert _tag(stack=("my", False)) == "qp_my_SYN_HJA_r"
    assert _tag(stack=("my", False), criteria=(), stack_criteria=()) == "qp_my"
    assert _tag(solver="jm", criteria=(), stack_criteria=()) == "jm"  # jm adds no criteria


def test_criteria_none_and_jm_beside_a_stack_with_criteria(short_take, tmp_path, monkeypatch):
    """ee_pose adds SYN, HJA_r: --criteria none drops them, jm runs without them, and criteria named
    for jm are still refused."""
    monkeypatch.chdir(tmp_path)
    common = ("--rate", "0", "--placement", "mapped")
    bare = invoke("run", short_take, "--criteria", "none", *common)
    jm = invoke("run", short_take, "--solver", "jm", *common)
    assert bare.exit_code == 0 and jm.exit_code == 0, (bare.output, jm.output)
    assert load_trajectory(tmp_path / "recordings" / "short_armar6_qp_nocriteria_native.npz").solver == "qp"
    assert load_trajectory(tmp_path / "recordings" / "short_armar6_jm_native.npz").solver == "jm"
    assert bare.stdout.startswith("short -> armar6 (qp, no criteria)\n")
    assert jm.stdout.startswith("short -> armar6 (jm)\n")
    default = invoke("run", short_take, *common)
    assert default.exit_code == 0 and default.stdout.startswith("short -> armar6 (qp + SYN, HJA_r)\n")
    assert (tmp_path / "recordings" / "short_armar6_qp_native.npz").is_file()
    one_line_error(invoke("run", short_take, "--solver", "jm", "--criteria", "SYN", *common), "jm")
    # an empty value (an unset shell variable) and none beside names are refused; NONE is none
    one_line_error(invoke("run", short_take, "--criteria", " , ", *common), "--criteria is empty")
    one_line_error(invoke("run", short_take, "--criteria", "none,SYN", *common), "none means no criteria")
    again = invoke("run", short_take, "--criteria", "NONE", "--force", *common)
    assert again.exit_code == 0 and again.stdout.startswith("short -> armar6 (qp, no criteria)\n")


def test_copied_stack_and_plain_run_write_different_files(short_take, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    shutil.copy(tasks_dir() / "ee_pose.toml", tmp_path / "my.toml")
    plain = invoke("run", short_take, "--solver", "qp", "--rate", "0", "--placement", "mapped")
    copied = invoke(
        "run", short_take, "--solver", "qp", "--rate", "0", "--placement", "mapped", "--stack", "my.toml"
    )
    assert plain.exit_code == 0 and copied.exit_code == 0, (plain.output, copied.output)
    written = sorted(p.name for p in (tmp_path / "recordings").iterdir())
    assert len(written) == 4, written  # two .rrd, two .npz
    assert [n for n in written if "_qp_my_ee_pose_" in n], written  # the copy keeps its name inside


def test_overwrite_refused_without_force(short_take, tmp_path):
    out = tmp_path / "x.rrd"
    args = ("run", short_take, "--solver", "jm", "--rate", "0", "--placement", "mapped", "--out", out)
    assert invoke(*args).exit_code == 0
    out.write_bytes(b"mine")
    one_line_error(invoke(*args), str(out), "--force", "--out")
    assert out.read_bytes() == b"mine"  # refused before solving, nothing written
    out.unlink()  # the trajectory beside it is protected as well
    one_line_error(invoke(*args), str(out.with_suffix(".npz")), "--force")
    result = invoke(*args, "--force")
    assert result.exit_code == 0, result.output
    assert out.read_bytes()[:4] == b"RRF2" and load_trajectory(out.with_suffix(".npz")).solver == "jm"


# --- 2. warnings -------------------------------------------------------------------------------


def test_a_base_given_off_its_floor_is_warned_about(short_take, tmp_path):
    """``--placement X,Y,YAW,Z`` puts the base at Z and says the robot does not stand on its floor;
    ``X,Y,YAW`` stands it on the floor, without the warning."""
    base = ("run", short_take, "--solver", "jm", "--rate", "0", "--robot", "dual_panda")
    raised = invoke(*base, "--placement", "0.5,-1,90,0.05", "--out", tmp_path / "up.rrd")
    assert raised.exit_code == 0, raised.output
    said = [line for line in raised.stderr.splitlines() if "does not stand on its floor" in line]
    assert len(said) == 1 and said[0].startswith("warning:") and "0.050 m above" in said[0], said
    floor = invoke(*base, "--placement", "0.5,-1,90", "--out", tmp_path / "floor.rrd")
    assert floor.exit_code == 0 and "does not stand on its floor" not in floor.stderr, floor.stderr


def test_walk_out_of_reach_is_warned_with_its_share_and_max(tmp_path):
    walk = data_file("kit_ml/00001_mmm.xml")
    out = tmp_path / "walk.rrd"
    result = invoke(
        "run",
        walk,
        "--robot",
        "armar3",
        "--solver",
        "qp",
        "--rate",
        "10",
        "--placement",
        "mapped",
        "--out",
        out,
    )
    assert result.exit_code == 0, result.output
    warned = {m[1]: m for m in WARNING.finditer(result.stderr)}
    assert warned, result.stderr
    traj = load_trajectory(out.with_suffix(".npz"))
    fpos = position_error(traj.tcp_pos, traj.targets.pos)
    for i, side in enumerate(("left", "right")):
        off = int(np.count_nonzero(fpos[:, i] > 0.05))
        assert (side in warned) == (off > 0.1 * traj.n_frames)
        if side in warned:
            assert int(warned[side][2]) == off and int(warned[side][3]) == traj.n_frames
            assert float(warned[side][4]) == pytest.approx(100 * fpos[:, i].max(), abs=0.06)
    assert max(float(m[4]) for m in warned.values()) > 40  # the walk leaves ARMAR-III far behind
    assert "out of reach" in result.stderr


def test_low_native_rate_and_limits_are_warned_as_the_scores_say(tmp_path):
    stir = next(t for t in kit_takes() if "Stir" in t.name)
    out = tmp_path / "stir.rrd"
    result = invoke("run", stir, "--solver", "qp", "--rate", "0", "--placement", "mapped", "--out", out)
    assert result.exit_code == 0, result.output
    # a stage that takes a while says so in plain lines when stderr is no terminal ("hlik: ...")
    lines = [line for line in result.stderr.splitlines() if line and not line.startswith("hlik: ")]
    assert all(line.startswith("warning: ") for line in lines), lines
    assert any("--rate 0 keeps the motion's 10 Hz" in line and "100 Hz" in line for line in lines), lines
    scores = json.loads(invoke("evaluate", out.with_suffix(".npz"), "--json").stdout)
    speeding = any("joint speeds exceed their limits" in line for line in lines)
    assert speeding == (scores["max_speed_ratio"] > 1 + 1e-6)
    touching = [line for line in lines if "self-collision" in line]
    assert bool(touching) == (scores["collisions"] > 0)
    if touching:
        assert f"in {scores['collisions']} of " in touching[0]


def _errors(traj) -> dict:
    """The evaluation's tracking errors of a stand-in trajectory (as :func:`hlik.metrics.evaluate`)."""
    from hlik.criteria.functional import position_error, rotation_angle

    return {
        "fpos": position_error(traj.tcp_pos, traj.targets.pos),
        "fori": rotation_angle(traj.tcp_rot, traj.targets.rot),
    }


# a base 1 m below the hands' targets at the origin: on the floor, the targets above it
_ON_THE_FLOOR = Placement(np.eye(3), np.array([0.0, 0.0, 1.0]), "given")


def test_hand_targets_below_the_floor_are_warned_about_once():
    """Targets the placement puts under the floor (a stoop, a subject scaled down) get one line
    with how many frames, how low and where; targets above it none."""
    n = 50
    pos, rot = np.zeros((n, 2, 3)), np.broadcast_to(np.eye(3), (n, 2, 3, 3))
    pos[20:30, 1, 2] = -1.47  # the right hand's 47 cm under the floor for 0.1 s
    traj = SimpleNamespace(n_frames=n, times=np.arange(n) * 0.01, placement=_ON_THE_FLOOR,
                           targets=SimpleNamespace(pos=pos, rot=rot))  # fmt: skip
    assert below_floor(traj) == (
        "the hand targets go below the floor in 10 of 50 frames, down to -0.47 m (right, 0.20 s): the "
        "subject reaches lower than the robot can (a stoop, or the scaling to its arms); no hand can "
        "follow them there"
    )
    pos[20:30, 1, 2] = -0.995  # within the 1 cm the floor check allows
    assert below_floor(traj) == ""


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(1, 500),
    failed=st.integers(0, 500),
    capped=st.integers(0, 500),
    touching=st.integers(0, 500),
    speed=st.floats(0.0, 3.0),
    rate=st.sampled_from([0.0, 100.0]),
    native=st.floats(1.0, 200.0),
    solver=st.sampled_from(["jm", "qp"]),
    scenario=st.sampled_from(["pose", "relative"]),
)
def test_solver_and_body_warnings_count_frames(
    n, failed, capped, touching, speed, rate, native, solver, scenario
):
    failed, capped, touching = min(failed, n), min(capped, n - min(failed, n)), min(touching, n)
    on_target, rot = np.zeros((n, 2, 3)), np.broadcast_to(np.eye(3), (n, 2, 3, 3))
    far = on_target.copy()
    far[:, 1, 2] = 0.3  # the right hand 30 cm off in every frame, the left on target
    diag = SimpleNamespace(n_failed=failed, n_unconverged=capped)
    traj = SimpleNamespace(
        n_frames=n,
        times=np.arange(n) * 0.01,
        placement=_ON_THE_FLOOR,
        solver=solver,
        tcp_pos=far,
        tcp_rot=rot,
        targets=SimpleNamespace(pos=on_target, rot=rot),
        diagnostics=diag,
    )
    ev = SimpleNamespace(
        collisions=np.arange(n) < touching,
        max_speed_ratio=speed,
        scenario=scenario,
        controller=_checks(n),
        **_errors(traj),
    )
    notes = run_warnings(traj, SimpleNamespace(rate=native), ev, rate)
    assert all("\n" not in note for note in notes)
    expected = [(failed, "failed"), (capped, "iteration cap"), (touching, "self-collision")]
    for count, word in expected:
        said = [note for note in notes if word in note]
        assert len(said) == (count > 0)
        if count:
            assert f"{count} of {n} frames" in said[0]
    # jm maps the joints: by design it tracks no hand and keeps no speed limit; one line says so
    # where it breaks one (the default solver: a new user must hear that it is not for a robot)
    tracking = solver != "jm"
    assert any("exceed their limits" in note for note in notes) == (tracking and speed > 1 + 1e-6)
    mapped = [note for note in notes if "maps the joint angles and keeps no speed" in note]
    assert len(mapped) == (not tracking and speed > 1 + 1e-6)
    assert all(f"up to {speed:.2f} x a speed limit; not for a robot" in note for note in mapped)
    # pose: each hand against its target; relative: the hands against each other (paper Eq. 3)
    hands = [note for note in notes if "hand more than 5 cm" in note]
    relative = [note for note in notes if "relative position is more than 5 cm" in note]
    assert len(hands) == (tracking and scenario == "pose")
    assert len(relative) == (tracking and scenario == "relative")
    assert all(f"{n} of {n} frames (100 %), up to 30.0 cm" in h for h in hands + relative)
    assert all(h.startswith("right hand") for h in hands)
    assert not any("turned more than" in note for note in notes)  # both hands as their targets turn
    assert any("--rate 0" in note for note in notes) == (rate == 0 and native < 50)


def _turned_notes(solver: str, turn, scenario: str = "pose") -> list[str]:
    """The "turned" warnings of a 40-frame run whose hands sit on their targets' positions, turned
    by ``turn(tcp_rot)`` (40, 2, 3, 3) in place."""
    n = 40
    pos, rot = np.zeros((n, 2, 3)), np.broadcast_to(np.eye(3), (n, 2, 3, 3))
    turned = rot.copy()
    turn(turned)
    traj = SimpleNamespace(
        n_frames=n,
        times=np.arange(n) * 0.01,
        placement=_ON_THE_FLOOR,
        solver=solver,
        tcp_pos=pos,
        tcp_rot=turned,
        targets=SimpleNamespace(pos=pos, rot=rot),
        diagnostics=SimpleNamespace(n_failed=0, n_unconverged=0),
    )
    ev = SimpleNamespace(
        collisions=np.zeros(n, bool),
        max_speed_ratio=1.0,
        scenario=scenario,
        controller=_checks(n),
        **_errors(traj),
    )
    return [note for note in run_warnings(traj, SimpleNamespace(rate=100.0), ev, 100.0) if "turned" in note]


def test_a_hand_turned_away_from_its_target_is_warned_about():
    def half(rot):
        rot[:20, 0] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]  # left hand 90° about x, half the frames

    for scenario in ("pose", "relative"):
        notes = _turned_notes("slsqp", half, scenario)
        # relative runs follow the other hand, not the human's hand orientations
        expected = ["left hand turned more than 30° from its target in 20 of 40 frames (50 %), up to 90°"]
        assert [note.split(" (out of")[0] for note in notes] == (expected if scenario == "pose" else [])


@pytest.mark.parametrize("angle", [8.0, 17.0, 29.0])
def test_a_hand_turned_a_little_in_every_frame_is_warned_about(angle):
    """A hand turned less than 30 deg but in every frame (ARMAR-6's SLSQP left hand on the Cut
    take, 17 deg) is warned about once its median passes 10 deg; the other hand, on target, not."""
    c, s = np.cos(np.radians(angle)), np.sin(np.radians(angle))

    def every(rot):
        rot[:, 1] = [[1, 0, 0], [0, c, -s], [0, s, c]]  # right hand about x in every frame

    notes = _turned_notes("qp", every)
    expected = (
        [f"right hand turned {angle:.0f}° from its target's orientation (median)"] if angle > 10 else []
    )
    assert [note.split(", ")[0] for note in notes] == expected


# --- 3. progress -------------------------------------------------------------------------------


def test_slsqp_with_finite_differences_reports_every_frame(short_take):
    from dataclasses import replace

    from hlik.criteria.learned import learn
    from hlik.problem.placement import placement_from_spec
    from hlik.retarget import retarget
    from hlik.robot.model import load_robot
    from hlik.solvers import get_solver
    from hlik.solvers.slsqp import SLSQPSettings

    robot = load_robot("armar6")
    motion = load_motion(short_take).crop(0.0, 0.4)
    learned = learn(robot)
    seen: list[int] = []
    fd = replace(SLSQPSettings(), gradients="fd")
    where = placement_from_spec("mapped", robot, motion)
    retarget(motion, robot, get_solver("slsqp", fd, seen.append), where, learned)
    assert seen == list(range(motion.n_frames))


def test_learning_and_reachability_report_progress(short_take, tmp_path):
    from hlik.criteria.learned import learn
    from hlik.robot.model import load_robot
    from hlik.robot.reachability import reachability_map

    robot = load_robot("dual_panda")
    corpus = tmp_path / "corpus"
    corpus.mkdir()
    for name in ("a.xml", "b.xml"):
        shutil.copy(short_take, corpus / name)
    calls: list[tuple[int, int]] = []
    learn(robot, corpus, cache=False, progress=lambda k, n: calls.append((k, n)))
    assert calls == [(1, 2), (2, 2)]
    sampled: list[tuple[int, int]] = []
    reachability_map(robot, cache=False, n_samples=2500, progress=lambda k, n: sampled.append((k, n)))
    assert sampled == [(1000, 2500), (2000, 2500), (2500, 2500)]


def test_the_summary_always_says_whether_a_hand_lagged(short_take, tmp_path, monkeypatch):
    """One ``lagging`` row, with the spans where a hand was more than 5 cm off, or saying there
    were none: a row left out read as a check not made."""
    monkeypatch.chdir(tmp_path)
    said = {}
    for solver in ("jm", "qp"):  # the first second: the QP keeps both hands on (at 1.8 s one lags)
        args = ("run", short_take, "--robot", "armar6", "--solver", solver, "--placement", "mapped")
        result = invoke(*args, "--span", "0:1")
        assert result.exit_code == 0, result.output
        rows = [line.strip() for line in result.stdout.splitlines() if line.strip().startswith("lagging")]
        assert len(rows) == 1, result.stdout
        said[solver] = rows[0]
    assert "jm maps the joints and does not track the hands" in said["jm"]
    assert said["qp"] == "lagging         none: no hand more than 5 cm off its target in any frame"


def test_a_piped_stage_that_reports_no_count_is_still_heard(monkeypatch, capsys):
    """Piped, a long stage prints a plain line after QUIET_FOR and then every EVERY seconds even
    when nothing updates it (reading a take, learning without a count); none once it has ended."""
    from hlik.cli.app import _PlainProgress

    monkeypatch.setattr(_PlainProgress, "QUIET_FOR", 0.2)
    monkeypatch.setattr(_PlainProgress, "EVERY", 0.5)
    with _PlainProgress() as bar:
        task = bar.add_task("learning the criteria")
        time.sleep(1.5)  # due at 0.2, 0.7, 1.2 s
        bar.update(task, description="placing", total=4, completed=3)
        time.sleep(0.8)
    time.sleep(0.6)
    lines = capsys.readouterr().err.splitlines()
    learning = [line for line in lines if line.startswith("hlik: learning the criteria (")]
    assert len(learning) >= 2, lines
    placing = [line for line in lines if line.startswith("hlik: placing (3/4, ")]
    assert placing and lines[-len(placing) :] == placing and len(placing) <= 2, lines
    assert len(lines) == len(learning) + len(placing), lines


# --- 4. startup --------------------------------------------------------------------------------


def test_help_imports_no_heavy_module():
    code = (
        "import sys\n"
        "from hlik.cli import app\n"
        "for args in (['--help'], ['run', '--help']):\n"
        "    try:\n"
        "        app(args)\n"
        "    except SystemExit:\n"
        "        pass\n"
        "heavy = ('rerun', 'mink', 'sklearn', 'nlopt', 'mujoco', 'scipy', 'ray')\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "[]", done.stdout[-2000:]


def test_package_attributes_still_import_on_use():
    import hlik

    assert hlik.load_robot("armar6").name == "armar6"
    assert set(hlik.__all__) <= set(dir(hlik))
    with pytest.raises(AttributeError):
        hlik.no_such_thing  # noqa: B018


# --- 5. flags ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "command,flag", [("evaluate", "--json"), ("calibrate", "--toml"), ("run", "--force")]
)
def test_on_off_options_show_as_flags(command, flag):
    result = invoke(command, "--help", env={"COLUMNS": "120"})
    assert result.exit_code == 0
    line = next(line for line in result.stdout.splitlines() if flag in line)
    assert "<bool>" not in line, line
    one_line_error(invoke(command, f"{flag}=yes", "x"), flag)


# --- 6. the summary ----------------------------------------------------------------------------


def test_rerun_command_is_one_unbroken_last_line(short_take, tmp_path):
    deep = tmp_path / ("a-rather-long-folder-name-" * 3) / "and another one with spaces"
    deep.mkdir(parents=True)
    out = deep / "recording.rrd"
    result = invoke(
        "run", short_take, "--solver", "jm", "--rate", "0", "--placement", "mapped", "--out", out,
        env={"COLUMNS": "80"},
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    last = result.stdout.strip().splitlines()[-1]
    assert last == f"open with: rerun '{out}'", last
    assert len(last) > 80


# --- 7. the corpus -----------------------------------------------------------------------------


@pytest.fixture
def corpus(short_take, tmp_path) -> Path:
    folder = tmp_path / "my corpus"
    folder.mkdir()
    shutil.copy(short_take, folder / "one.xml")
    return folder


def test_corpus_from_the_environment_or_hlik_toml(corpus, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("HLIK_CORPUS", raising=False)
    monkeypatch.setenv("HLIK_DATA", str(tmp_path / "no data"))
    assert corpus_setting() == (None, "")
    (tmp_path / "hlik.toml").write_text('corpus = "my corpus"\n')
    found, source = corpus_setting()
    assert found is not None and found.resolve() == corpus.resolve() and source == "corpus in hlik.toml"
    monkeypatch.setenv("HLIK_CORPUS", str(corpus))
    assert corpus_setting() == (corpus, "HLIK_CORPUS")
    monkeypatch.setenv("HLIK_CORPUS", str(tmp_path / "gone"))
    with pytest.raises(SettingsError, match="gone.*HLIK_CORPUS.*no such corpus folder"):
        corpus_setting()
    monkeypatch.delenv("HLIK_CORPUS")
    (tmp_path / "hlik.toml").write_text("corpus = 3\n")
    with pytest.raises(SettingsError, match="hlik.toml: corpus must be a folder"):
        corpus_setting()
    (tmp_path / "hlik.toml").write_text("corpus = \n")
    with pytest.raises(SettingsError, match="hlik.toml: cannot read"):
        corpus_setting()


def test_the_default_corpus_is_remembered_else_the_shared_takes_else_the_demo(
    corpus, short_take, tmp_path, monkeypatch
):
    """Issue 32: ``hlik learn --corpus DIR`` changes later runs (remembered in the user's config);
    without any setting the shared KIT takes are the corpus where they are; ``--corpus demo``
    names the demo."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("HLIK_CORPUS", raising=False)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    kit = tmp_path / "data" / "kit_bimanual"
    kit.mkdir(parents=True)
    shutil.copy(short_take, kit / "take.xml")
    monkeypatch.setenv("HLIK_DATA", str(kit.parent))
    assert corpus_setting() == (kit, "the shared KIT takes")
    learned = invoke("learn", "dual_panda", "--corpus", corpus)
    assert learned.exit_code == 0, learned.output
    config = tmp_path / "config" / "hlik" / "config.toml"
    assert f"remembered in {config}" in learned.stdout
    found, source = corpus_setting()
    assert found == corpus.resolve() and source == f"corpus in {config}"
    (tmp_path / "hlik.toml").write_text('corpus = "my corpus"\n')  # the working folder's first
    assert corpus_setting()[1] == "corpus in hlik.toml"
    run = invoke(
        "run", short_take, "--robot", "dual_panda", "--corpus", "demo", "--rate", "0", env={"COLUMNS": "200"}
    )
    assert run.exit_code == 0, run.output
    assert "criteria learned from: the bundled demo" in run.stdout and "--corpus demo" in run.stdout
    assert "_corpus-" not in run.stdout and "warning: criteria learned" not in run.stderr
    monkeypatch.setenv("HLIK_DATA", str(tmp_path / "no data"))
    (tmp_path / "hlik.toml").unlink()
    config.unlink()
    # a mistyped HLIK_DATA is not replaced by the ../shared beside the working folder
    beside = tmp_path / "shared" / "motion_data" / "kit_bimanual"
    beside.mkdir(parents=True)
    shutil.copy(short_take, beside / "take.xml")
    (tmp_path / "checkout").mkdir()
    monkeypatch.chdir(tmp_path / "checkout")
    fallen = invoke(
        "run", short_take, "--robot", "dual_panda", "--rate", "0", "--force", env={"COLUMNS": "300"}
    )
    assert fallen.exit_code == 0, fallen.output
    assert "warning: criteria learned from the bundled demo" in fallen.stderr
    assert f"HLIK_DATA={tmp_path / 'no data'} holds no kit_bimanual takes" in fallen.stdout
    monkeypatch.delenv("HLIK_DATA")
    assert corpus_setting() == (beside, "the shared KIT takes")  # unset: the folder beside
    # from a folder with none beside it, the takes beside the checkout hlik is installed from
    (tmp_path / "elsewhere" / "deeper").mkdir(parents=True)
    monkeypatch.chdir(tmp_path / "elsewhere" / "deeper")
    checkout = Path(hlik.__file__).resolve().parents[2]
    shared = checkout.parent / "shared" / "motion_data" / "kit_bimanual"
    if (checkout / "pyproject.toml").is_file() and shared.is_dir():
        assert corpus_setting() == (shared, "the shared KIT takes")
    else:  # an installed wheel: no checkout to look beside
        assert corpus_setting() == (None, "")


def test_piped_output_never_breaks_a_path(short_take, tmp_path, monkeypatch):
    """At 80 columns (piped), the recording, trajectory and corpus lines and the commands to copy
    each hold their whole path on one line; the summary's rows are not wrapped or padded either."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / ("a_folder_with_a_long_name_" * 3) / "and_a_recording_whose_name_is_long_too.rrd"
    out.parent.mkdir()
    args = ("run", short_take, "--solver", "jm", "--rate", "0", "--placement", "mapped", "--out", out)
    result = invoke(*args, env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    for path in (out, out.with_suffix(".npz")):
        assert any(str(path) in line for line in lines), (path, result.stdout)
    assert any(line.startswith("open with: rerun ") and str(out) in line for line in lines)
    assert not [line for line in lines if line.endswith(" ")]
    controller = [line for line in lines if line.lstrip().startswith("controller")]
    assert len(controller) == 1 and controller[0].rstrip().endswith("an export adds the braking)")
    scored = invoke("evaluate", out.with_suffix(".npz"), env={"COLUMNS": "80"})  # its table's title
    assert scored.exit_code == 0, scored.output
    assert any(out.with_suffix(".npz").name in line for line in scored.stdout.splitlines()), scored.stdout


def test_run_says_which_corpus_the_criteria_came_from(corpus, short_take, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = ("run", short_take, "--solver", "jm", "--rate", "0", "--placement", "mapped")
    result = invoke(*args, env={"HLIK_CORPUS": str(corpus), "COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    assert f"criteria learned from: {corpus} (1 file, from HLIK_CORPUS)" in result.stdout
    demo = invoke(*args, env={"HLIK_CORPUS": "demo", "COLUMNS": "200"})
    assert demo.exit_code == 0, demo.output  # another corpus, another default name: no --force needed
    said = "criteria learned from: the bundled demo (demo_pour_wipe.xml, chosen by HLIK_CORPUS)"
    assert said in demo.stdout
    assert "warning: criteria learned" not in result.stderr + demo.stderr  # chosen, not fallen back on
    missing = invoke(*args, env={"HLIK_CORPUS": str(tmp_path / "none")})
    one_line_error(missing, "none", "HLIK_CORPUS", "corpus")


def test_robots_lists_what_the_models_say_and_then_needs_no_model(tmp_path, monkeypatch):
    """The first listing loads the robots; later ones read the cache (keyed by the robot files'
    bytes), importing neither MuJoCo nor NumPy; a changed robot file is loaded again."""
    from hlik.robot import summary
    from hlik.robot.files import available_robots
    from hlik.robot.model import load_robot

    monkeypatch.setenv("HLIK_CACHE", str(tmp_path))
    cold = summary.robot_summaries()
    for s, name in zip(cold, available_robots(), strict=True):
        r = load_robot(name)
        assert (s.name, s.dof, s.extra_joints, s.unlimited) == (
            r.name,
            r.dof,
            r.extra_joints,
            len(r.unlimited),
        )
        assert s.arms == (len(r.arm_joints["left"]), len(r.arm_joints["right"]))
    assert summary.robot_summaries() == cold and len(list(tmp_path.glob("robots-*.json"))) == 1
    code = (
        "import sys\n"
        "from hlik.cli import app\n"
        "try:\n"
        "    app(['robots'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(sorted(m for m in ('mujoco', 'numpy', 'rerun', 'scipy') if m in sys.modules))\n"
    )
    env = {**os.environ, "HLIK_CACHE": str(tmp_path)}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env)
    assert done.returncode == 0 and "ARMAR-6" in done.stdout, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "[]", done.stdout[-500:]
    monkeypatch.setattr(summary, "_key", lambda: "another set of robot files")
    loads = []
    real = load_robot
    monkeypatch.setattr("hlik.robot.model.load_robot", lambda name: loads.append(name) or real(name))
    assert summary.robot_summaries() == cold and loads == list(available_robots())


def test_the_printed_evaluate_command_gives_the_runs_scores(tmp_path, takes):
    """Scenario and corpus change the scores: the summary's ``details:`` command passes them on."""
    import json
    import shlex

    from typer.testing import CliRunner

    from hlik.cli import app

    corpus = tmp_path / "corpus"
    corpus.mkdir()
    (corpus / takes[0].name).symlink_to(takes[0])
    out = tmp_path / "x.rrd"
    args = ["run", str(takes[1]), "--solver", "jm", "--scenario", "relative", "--corpus", str(corpus)]
    run = CliRunner().invoke(app, [*args, "--out", str(out)])
    assert run.exit_code == 0, run.output
    line = next(x for x in run.stdout.splitlines() if x.startswith("details: "))
    command = shlex.split(line.removeprefix("details: "))
    assert command[:2] == ["hlik", "evaluate"] and "--corpus" in command and "relative" in command
    scores = json.loads(CliRunner().invoke(app, [*command[1:], "--json"]).stdout)
    shown = next(x for x in run.stdout.splitlines() if x.startswith("human likeness"))
    assert f"m_hl = {scores['m_hl']:.3f}" in shown and f"m_hl,f = {scores['m_hl_f']:.3f}" in shown, shown
    # the file knows its scenario: without --scenario hlik evaluate scores the run's, not pose
    at = command.index("--scenario")
    bare = json.loads(CliRunner().invoke(app, [*command[1:at], *command[at + 2 :], "--json"]).stdout)
    assert bare["m_f"] == scores["m_f"] and bare["m_hl_f"] == scores["m_hl_f"]
    assert bare["corpus"].startswith(f"{corpus} (1 file")  # which corpus the scores came from
    table = CliRunner().invoke(app, command[1:])
    assert f"criteria learned from: {corpus} (1 file" in table.stdout
    posed = json.loads(
        CliRunner().invoke(app, [*command[1:at], *command[at + 2 :], "--scenario", "pose", "--json"]).stdout
    )
    assert posed["m_f"] != scores["m_f"]


def _checks(n: int, **changes):
    """ControllerChecks of ``n`` frames of a one-joint robot that keeps every limit, with ``changes``."""
    from dataclasses import replace

    from hlik.executable import ControllerChecks

    quiet = ControllerChecks(
        joint_names=("j",),
        acceleration=np.zeros((n, 1)),
        acceleration_ratio=np.zeros(n),
        jerk=np.zeros(n),
        jerk_ratio=np.zeros(n),
        jerk_joint="j",
        torque=np.zeros((n, 1)),
        torque_ratio=np.zeros(n),
        at_stop=np.zeros(n, bool),
        at_margin=np.zeros((n, 1), bool),
        lowest=np.zeros(n),
        base_height=0.0,
        end_speed=np.zeros(1),
        acceleration_limit=np.ones(1),
        jerk_limit=np.ones(1),
        effort_limit=np.ones(1),
    )
    return replace(quiet, **changes)


@pytest.mark.parametrize("solver", ["jm", "qp"])
def test_each_exceeded_controller_limit_gets_one_warning(solver):
    from hlik.findings import controller_warnings

    n = 100
    share = lambda k: f"{k} of {n} frames"  # noqa: E731
    tracking = solver != "jm"
    assert controller_warnings(_checks(n), tracking, share) == []
    over = np.where(np.arange(n) < 7, 1.5, 0.5)
    cases = {
        "accelerations exceed": dict(acceleration_ratio=over, acceleration=over[:, None]),
        "jerks exceed": dict(jerk_ratio=over, jerk=over),
        "torques exceed": dict(torque_ratio=over, torque=over[:, None]),
        "of a stop": dict(at_stop=np.arange(n) < 7),
        "below the floor": dict(lowest=np.full(n, -0.05)),
    }
    for words, change in cases.items():
        notes = controller_warnings(_checks(n, **change), tracking, share)
        # jm maps the joints: its accelerations and jerks are not warned about, its torques are
        expected = 0 if (words in ("accelerations exceed", "jerks exceed") and not tracking) else 1
        assert len(notes) == expected and all(words in note for note in notes), (words, notes)
        if expected and words in ("accelerations exceed", "jerks exceed", "torques exceed", "of a stop"):
            assert "7 of 100 frames" in notes[0]


def test_the_controller_row_says_how_the_motion_ends():
    """A trajectory that ends moving needs time to stop beyond its last frame (|v| / a_max)."""
    from hlik.cli.summary import controller_line

    moving = _checks(10, end_speed=np.array([0.5]), acceleration_limit=np.array([2.0]))
    assert moving.stop_time == pytest.approx(0.25)
    assert "ends moving at up to 0.50 rad/s (0.25 s to stop" in controller_line(moving)
    assert _checks(10).stop_time == 0.0 and "ends at rest" in controller_line(_checks(10))
    backward = _checks(10, end_speed=np.array([-0.5]), acceleration_limit=np.array([2.0]))
    assert backward.stop_time == pytest.approx(0.25)  # a joint moving the other way stops as long
    unlimited = _checks(10, end_speed=np.array([0.5]), acceleration_limit=np.array([np.inf]))
    assert "(no acceleration limits given; an export adds the braking)" in controller_line(unlimited)
    mixed = _checks(
        10,
        joint_names=("a", "b"),
        acceleration=np.zeros((10, 2)),
        torque=np.zeros((10, 2)),
        end_speed=np.array([0.5, 1e-3]),
        acceleration_limit=np.array([2.0, np.inf]),
        jerk_limit=np.ones(2),
        effort_limit=np.ones(2),
    )
    assert "(a joint without an acceleration limit among them; an export adds" in controller_line(mixed)


def test_the_json_has_no_ratio_to_a_limit_not_given():
    """A robot without jerk (acceleration, effort) limits has null ratios and time to stop in
    ``hlik evaluate --json``, not 0 or Infinity (which no JSON parser must accept)."""
    import json

    given = _checks(10, end_speed=np.array([0.5]), jerk_ratio=np.full(10, 0.3)).to_json()
    assert given["max_jerk_ratio"] == 0.3 and given["stop_time"] == 0.5
    none = _checks(
        10,
        end_speed=np.array([0.5]),
        acceleration_limit=np.array([np.inf]),
        jerk_limit=np.array([np.inf]),
        effort_limit=np.array([np.inf]),
    ).to_json()
    for key in ("max_acceleration_ratio", "max_jerk_ratio", "max_torque_ratio", "stop_time"):
        assert none[key] is None, key
    json.loads(json.dumps(none, allow_nan=False))


def test_a_span_past_the_take_is_refused_and_one_past_its_end_is_cut(short_take, tmp_path, monkeypatch):
    """A span that starts after the (2 s) take ends is an error naming the file and the take's
    length, with nothing written (it once ran another span under the asked-for name); one that
    ends after it is cut there, warned."""
    monkeypatch.chdir(tmp_path)
    args = ("run", short_take, "--solver", "jm", "--rate", "0", "--placement", "mapped")
    refused = invoke(*args, "--span", "3:5")
    assert refused.exit_code == 2, refused.output
    err = refused.stderr.strip()
    assert err == f"error: {short_take}: motion: --span 3:5 starts after the take ends (2.00 s)", err
    assert not list(tmp_path.rglob("*.rrd")) and not list(tmp_path.rglob("*.npz"))
    cut = invoke(*args, "--span", "1:5")
    assert cut.exit_code == 0, cut.output
    assert f"{short_take}: span 1-5 s cut to 1-2.00 s (the take is shorter)" in cut.stderr
