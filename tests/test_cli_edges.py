"""CLI edges: every bad option, setting or file read ends in one line on stderr and exit code 2, with
nothing written; a run's two outputs appear together or not at all, also when it is interrupted,
terminated, out of disk space or racing another run for the same ``--out``."""

from __future__ import annotations

import dataclasses
import errno
import os
import re
import signal
import threading
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from conftest import kit_takes
from hlik.cli import app, write_outputs
from hlik.human.load import load_motion
from hlik.human.mmm_format import write_mmm
from hlik.problem.placement import placement_from_spec
from hlik.retarget import retarget
from hlik.robot.model import load_robot
from hlik.solvers.jv import JVSettings
from hlik.solvers.qp import QPSettings
from hlik.solvers.slsqp import SLSQPSettings
from hlik.solvers.stack_file import load_stack
from hlik.trajectory import load_trajectory
from hlik.util import atomic
from hlik.util.atomic import atomic_path, atomic_paths, pair_lock
from hlik.util.errors import RobotError, SettingsError, TrajectoryFormatError
from hlik.util.paths import robots_dir


@pytest.fixture(scope="module")
def take(tmp_path_factory) -> Path:
    """0.3 s (4 frames) of a real KIT take, as an MMM file."""
    motion = load_motion(kit_takes()[5])
    path = tmp_path_factory.mktemp("take") / "stir.xml"
    write_mmm(motion.crop(1.0, 1.3), path)
    return path


@pytest.fixture(scope="module")
def robot():
    return load_robot("armar6")


@pytest.fixture(scope="module")
def traj(take, robot):
    """JM's trajectory of the take (placed by the mapped pose: no reachability map to sample)."""
    motion = load_motion(take)
    return retarget(motion, robot, placement=placement_from_spec("mapped", robot, motion))


@pytest.fixture(scope="module")
def saved(traj, tmp_path_factory) -> dict[str, np.ndarray]:
    """The arrays of the trajectory's .npz file."""
    path = traj.save(tmp_path_factory.mktemp("npz") / "t.npz")
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def invoke(*args: str):
    return CliRunner().invoke(app, [str(a) for a in args])


def one_line_error(result, *named: str) -> str:
    """The error line of a refused command: exit 2, one line naming ``named``, no traceback."""
    err = result.stderr.strip()
    assert result.exit_code == 2, (result.exit_code, result.output)
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert "Traceback" not in result.output and ".tmp" not in err, err
    for part in named:
        assert part in err, (part, err)
    return err


def files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# --- options ---------------------------------------------------------------------------------


@pytest.mark.parametrize("rate", ["nan", "inf", "-inf", "1e-9", "0.5", "1e6", "10001"])
def test_rates_outside_1_to_10000_hz_are_refused_before_reading(take, tmp_path, rate):
    err = one_line_error(invoke("run", take, "--rate", rate, "--out", tmp_path / "x.rrd"), "--rate", "Hz")
    assert "got" in err and files(tmp_path) == []


@pytest.mark.parametrize(
    "args, named",
    [
        (["run", "--rat", "5"], ["No such option: --rat", "run --help"]),
        (["run", "--rate", "fast"], ["'--rate'", "run --help"]),
        (["calibrate"], ["Missing argument", "calibrate --help"]),
        (["frobnicate"], ["No such command 'frobnicate'"]),
    ],
)
def test_usage_errors_are_one_line_not_a_box(args, named):
    one_line_error(invoke(*args), *named)


@pytest.mark.parametrize(
    "args, named",
    [
        (["--placement", "nan,0,0"], ["--placement nan,0,0", "finite"]),
        (["--placement", "0,inf,90"], ["--placement 0,inf,90", "finite"]),
        (["--solver", "qp", "--criteria", "SYN,HJA_r,SYN"], ["SYN listed twice"]),
    ],
)
def test_options_that_would_score_nan_or_twice_are_refused(take, tmp_path, args, named):
    one_line_error(invoke("run", take, "--rate", "0", *args, "--out", tmp_path / "x.rrd"), *named)
    assert files(tmp_path) == []


def test_study_seconds_must_be_finite(take):
    one_line_error(invoke("study", take, "--seconds", "nan"), "--seconds", "nan")


def test_help_is_unchanged():
    result = invoke("run", "--help")
    assert result.exit_code == 0 and "--rate" in result.stdout and "Usage" in result.stdout


# --- output paths ----------------------------------------------------------------------------


def test_out_equal_to_the_input_is_refused_and_the_input_kept(take, tmp_path):
    motion = tmp_path / "take.rrd"  # an MMM file with the name a recording would have
    motion.write_bytes(take.read_bytes())
    one_line_error(invoke("run", motion, "--rate", "0", "--out", motion), str(motion), "input")
    assert motion.read_bytes() == take.read_bytes() and files(tmp_path) == ["take.rrd"]
    stack = tmp_path / "s.npz"  # a stack file where the trajectory would go
    stack.write_text('name = "s"\n')
    one_line_error(
        invoke("run", take, "--rate", "0", "--stack", stack, "--out", tmp_path / "s.rrd"), str(stack), "input"
    )
    assert stack.read_text() == 'name = "s"\n'


@pytest.mark.parametrize("name", ["x.npz", "x", "x.rrd.bak", "x.RRD"])
def test_out_must_name_the_recording(take, tmp_path, name):
    one_line_error(invoke("run", take, "--rate", "0", "--out", tmp_path / name), name, ".rrd")
    assert files(tmp_path) == []


def test_a_stack_name_cannot_lead_the_default_output_out_of_recordings(take, tmp_path, monkeypatch):
    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    stack = work / "s.toml"
    stack.write_text('name = "x/../../../escaped"\n')
    result = invoke("run", take, "--rate", "0", "--placement", "mapped", "--stack", stack)
    assert result.exit_code == 0, result.output
    written = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.suffix in (".rrd", ".npz"))
    assert [p.parent for p in written] == [Path("a/b/recordings")] * 2, written
    assert all("escaped" in p.name for p in written)


# --- messages: text, never markup ----------------------------------------------------------


def test_bracketed_names_print_as_written(take, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    odd = Path("[red]take.xml")
    odd.write_bytes(take.read_bytes())
    result = invoke("info", odd)
    assert result.exit_code == 0 and "[red]take.xml" in result.stdout
    one_line_error(invoke("info", tmp_path / "[bold]gone.xml"), "[bold]gone.xml: no such file")
    bad = tmp_path / "[qp].toml"
    bad.write_text("[qp]\nfoo = 1\n")
    one_line_error(invoke("run", take, "--stack", bad), "[qp].toml", "unknown key 'foo' in [qp]")


# --- settings --------------------------------------------------------------------------------

BAD_SETTINGS = [
    ("[qp]\nposition_cost = -1.0", "[qp] position_cost"),
    ("[qp]\norientation_cost = nan", "[qp] orientation_cost"),
    ("[qp]\nvelocity_cost = inf", "[qp] velocity_cost"),
    ("[qp]\nmax_iter = 0", "[qp] max_iter"),
    ("[qp]\nmax_iter = -3", "[qp] max_iter"),
    ("[qp]\nmax_iter = 2.5", "[qp] max_iter"),
    ("[qp]\ntol = nan", "[qp] tol"),
    ("[qp]\ntol = 0.0", "[qp] tol"),
    ("[qp]\nsolver = 'no_such_qp'", "[qp] solver 'no_such_qp'"),
    ("[qp]\ncollision_gain = 1.5", "[qp] collision_gain"),
    ("[qp]\ncollision_detect = 0.001", "[qp] collision_detect"),
    ("[jv]\nk = 0.5", "[jv] k"),
    ("[jv]\nstep = -inf", "[jv] step"),
    ("[jv]\nrcond = 0.0", "[jv] rcond"),
    ("[slsqp]\nftol_rel = nan", "[slsqp] ftol_rel"),
    ("[slsqp]\nftol_rel = -1e-3", "[slsqp] ftol_rel"),
    ("[slsqp]\nmax_eval = 0", "[slsqp] max_eval"),
    ("[slsqp]\nfirst_eval = 1.5", "[slsqp] first_eval"),
    ("[slsqp]\ncriterion_cost = -10.0", "[slsqp] criterion_cost"),
    ("[gamma]\nSYN = -1.0", "[gamma] SYN"),
    ("[gamma]\nSYN = nan", "[gamma] SYN"),
    ("[qp.gamma]\nHJA_r = inf", "[qp.gamma] HJA_r"),
    ("name = 3", "name must be text"),
    ("criteria = ['SYN', 'HJA_r', 'SYN']", "SYN listed twice"),
]


@pytest.mark.parametrize("text, named", BAD_SETTINGS)
def test_values_that_make_no_sense_in_a_stack_name_file_table_and_key(tmp_path, text, named):
    path = tmp_path / "stack.toml"
    path.write_text(text + "\n")
    with pytest.raises(SettingsError) as err:
        load_stack(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ") and named in message and "\n" not in message, message


def test_the_cli_refuses_a_bad_stack_before_reading_the_motion(tmp_path):
    path = tmp_path / "stack.toml"
    path.write_text("[qp]\nmax_iter = 2.5\n")
    broken = tmp_path / "broken.xml"  # there (a missing file is refused first, quickly) but never read
    broken.write_text("<MMM><Motion")
    one_line_error(invoke("run", broken, "--solver", "qp", "--stack", path), "stack.toml: [qp] max_iter")


finite = st.floats(allow_nan=False, allow_infinity=False)
bad_weight = st.one_of(
    st.just(float("nan")),
    st.just(float("inf")),
    st.just(-float("inf")),
    st.floats(max_value=-1e-300, allow_infinity=False),
)
bad_count = st.one_of(st.integers(max_value=0), st.floats(0.1, 1e3).filter(lambda x: not x.is_integer()))


@settings(max_examples=60, deadline=None)
@given(
    cls=st.sampled_from([QPSettings, JVSettings, SLSQPSettings]),
    value=bad_weight,
    count=bad_count,
    data=st.data(),
)
def test_settings_classes_refuse_bad_values_in_python_too(cls, value, count, data):
    weights = {
        QPSettings: ["position_cost", "criterion_cost", "velocity_cost", "damping", "collision_margin"],
        JVSettings: ["criterion_cost", "jla_gamma", "damping", "orientation_cost"],
        SLSQPSettings: [
            "position_cost",
            "orientation_cost",
            "velocity_cost",
            "jerk_cost",
            "criterion_cost",
            "position_gamma",
        ],
    }[cls]
    counts = {QPSettings: ["max_iter"], JVSettings: ["max_iter"], SLSQPSettings: ["max_eval", "first_eval"]}[
        cls
    ]
    key = data.draw(st.sampled_from(weights))
    with pytest.raises(SettingsError, match=rf"^{cls.__name__}\.{key} must be"):
        cls(**{key: value})
    key = data.draw(st.sampled_from(counts))
    with pytest.raises(SettingsError, match=rf"^{cls.__name__}\.{key} must be a whole number"):
        cls(**{key: count})
    with pytest.raises(SettingsError, match="gamma SYN"):
        cls(gamma={"SYN": value})
    good = data.draw(st.floats(0.0, 1e6))
    assert getattr(dataclasses.replace(cls(), **{weights[0]: good}), weights[0]) == good


def test_a_qp_backend_must_be_installed():
    import qpsolvers

    for name in ("daqp", *qpsolvers.available_solvers):
        assert QPSettings(solver=name).solver == name
    with pytest.raises(SettingsError, match="QPSettings.solver 'gurobi_x' is not an installed QP solver"):
        QPSettings(solver="gurobi_x")


# --- robot descriptions ----------------------------------------------------------------------


def _robot_text() -> str:
    """ARMAR-6's description, its model named by absolute path so that a copy loads anywhere."""
    text = (robots_dir() / "armar6.toml").read_text()
    return text.replace('model = "mjcf/armar6.xml"', f'model = "{robots_dir() / "mjcf/armar6.xml"}"')


ROBOT_FAULTS = {
    "home not a number": (
        lambda t: t.replace("ArmL1_Cla1 = 0.0368", 'ArmL1_Cla1 = "up"'),
        "[home] ArmL1_Cla1",
    ),
    "home nan": (lambda t: t.replace("ArmL1_Cla1 = 0.0368", "ArmL1_Cla1 = nan"), "[home] ArmL1_Cla1"),
    "home unknown joint": (lambda t: t.replace("[home]\n", "[home]\nElbow = 1.0\n"), "[home] names joints"),
    "home outside limits": (
        lambda t: t.replace("ArmL5_Elb1 = 1.31845", "ArmL5_Elb1 = 99.0"),
        "ArmL5_Elb1 = 99",
    ),
    "invalid utf-8": (lambda t: t.replace('title = "ARMAR-6"', 'title = "ARMAR-\udcff"'), "not UTF-8"),
    "not toml": (lambda t: t + "\n[home\n", "not valid TOML"),
    "arms not a table": (
        lambda t: re.sub(r"\[arms.left\]\njoints = .*\n", "", t).replace("[arms.right]", "arms = 1\n[x]"),
        "arms",
    ),
    "joints not a list": (
        lambda t: t.replace('joints = ["ArmL1_Cla1"', 'joints = "ArmL1_Cla1"  # ["ArmL1_Cla1"'),
        "arms.left joints",
    ),
    "model missing": (lambda t: re.sub(r"model = .*\n", "", t), "missing key 'model'"),
    "model not a file": (
        lambda t: re.sub(r"model = .*\n", 'model = "nowhere.xml"\n', t),
        "model 'nowhere.xml' not found",
    ),
    "mapping gain text": (lambda t: t.replace("gain = 0.147", 'gain = "x"'), "offset gain"),
    "mapping not a table": (
        lambda t: t.replace("ArmL1_Cla1 = { a = 0.0, b = 0.0 }", "ArmL1_Cla1 = 3"),
        "[mapping.left] ArmL1_Cla1",
    ),
    "mapping unknown joint": (
        lambda t: t.replace("[mapping.left]\n", "[mapping.left]\nFoo = { a = 1.0 }\n"),
        "Foo",
    ),
    "mapping misspelt key": (
        lambda t: t.replace("ArmL1_Cla1 = { a = 0.0, b = 0.0 }", "ArmL1_Cla1 = { aa = 0.0, b = 0.0 }"),
        "unknown key 'aa' in [mapping.left] ArmL1_Cla1 (did you mean 'a'?)",
    ),
    "mapping misspelt joint": (
        lambda t: t.replace("ArmL1_Cla1 = { a = 0.0, b = 0.0 }", "ArmL1_Cla = { a = 0.0, b = 0.0 }"),
        "not a joint of the model (did you mean 'ArmL1_Cla1'?)",
    ),
    "velocity limits not a table": (
        lambda t: t.replace("[velocity_limits]", "velocity_limits = 2\n[vl]"),
        "velocity_limits",
    ),
    "name with a separator": (
        lambda t: t.replace('name = "armar6"', 'name = "../armar6"'),
        "name '../armar6'",
    ),
}


@pytest.mark.parametrize("fault", ROBOT_FAULTS)
def test_bad_robot_descriptions_are_one_line_robot_errors(tmp_path, fault):
    edit, named = ROBOT_FAULTS[fault]
    path = tmp_path / "mine.toml"
    text = edit(_robot_text())
    assert text != _robot_text()
    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    with pytest.raises(RobotError) as err:
        load_robot(str(path))
    message = str(err.value)
    assert "\n" not in message and named in message, message
    assert str(path) in message or "MJCF" in message, message
    one_line_error(invoke("calibrate", path), named)


def test_robot_names_never_reach_other_folders():
    with pytest.raises(RobotError, match="unknown robot '../robots/armar6'"):
        load_robot("../robots/armar6")


# --- trajectory files (hlik evaluate) ------------------------------------------------------


def _with(saved: dict, **changes) -> dict:
    return {**saved, **changes}


def _nan_at(array: np.ndarray, k: int = 1) -> np.ndarray:
    bad = array.astype(float).copy()
    bad.reshape(len(bad), -1)[min(k, len(bad) - 1), 0] = np.nan
    return bad


FLOAT_T = ["times", "q", "tcp_pos", "tcp_rot", "target_pos", "target_rot", "ref.joints", "ref.root_position",
           "ref.root_rotation", "human.q_map", "human.manip", "diag.solve_time"]  # fmt: skip
T_ARRAYS = [*FLOAT_T, "human.psi", "diag.iterations", "diag.converged", "diag.failed", "ref.times"]

NPZ_FAULTS = {
    **{f"nan in {k}": (lambda a, k=k: _with(a, **{k: _nan_at(a[k])}), k) for k in FLOAT_T},
    **{f"inf in {k}": (lambda a, k=k: _with(a, **{k: _nan_at(a[k]) * 0 + np.inf}), k) for k in FLOAT_T[1:3]},
    **{f"a frame short: {k}": (lambda a, k=k: _with(a, **{k: a[k][:-1]}), "has shape") for k in T_ARRAYS},
    "reversed times": (lambda a: _with(a, times=a["times"][::-1].copy()), "times not increasing"),
    "duplicated time": (
        lambda a: _with(a, times=np.r_[a["times"][:2], a["times"][1:-1]]),
        "times not increasing",
    ),
    "ref.times differ": (lambda a: _with(a, **{"ref.times": a["ref.times"] + 0.5}), "ref.times"),
    "q as text": (lambda a: _with(a, q=a["q"].astype(str)), "q holds"),
    "q 1-d": (lambda a: _with(a, q=a["q"][:, 0].copy()), "q has shape"),
    "base_pose not a rotation": (
        lambda a: _with(a, base_pose=a["base_pose"] * 2),
        "base_pose is not a rotation",
    ),
    "tcp_rot scaled": (lambda a: _with(a, tcp_rot=a["tcp_rot"] * 1.1), "tcp_rot is not a rotation"),
    "height zero": (lambda a: _with(a, **{"ref.height": np.array(0.0)}), "ref.height"),
    "height an array": (lambda a: _with(a, **{"ref.height": np.ones(3)}), "ref.height has shape"),
    "no frames": (lambda a: {k: (v[:0] if k in T_ARRAYS else v) for k, v in a.items()}, "no frames"),
    "missing q": (lambda a: {k: v for k, v in a.items() if k != "q"}, "missing array 'q'"),
    "missing an object's markers": (
        lambda a: {k: v for k, v in a.items() if k != "obj.0.markers"},
        "obj.0.markers",
    ),
    "joints of another robot": (
        lambda a: _with(a, robot=np.array("dual_panda")),
        "not those of robot 'dual_panda'",
    ),
    "one joint renamed": (
        lambda a: _with(a, joint_names=np.r_[a["joint_names"][:-1], ["Elbow"]]),
        "joint 15 is 'Elbow'",
    ),
    "unknown robot": (lambda a: _with(a, robot=np.array("armar7")), "unknown robot 'armar7'"),
    "robot a path": (lambda a: _with(a, robot=np.array("../../x.toml")), "x.toml"),
    "object array": (lambda a: _with(a, q=a["q"].astype(object)), "Python objects"),
    "other format": (lambda a: _with(a, format=np.array("hlik.trajectory/9")), "hlik.trajectory/9"),
}


@pytest.mark.parametrize("fault", NPZ_FAULTS)
def test_every_damaged_trajectory_is_one_line_naming_the_file_and_array(tmp_path, saved, fault):
    mutate, named = NPZ_FAULTS[fault]
    path = tmp_path / "t.npz"
    arrays = mutate(saved)
    with open(path, "wb") as f:
        np.savez(f, **arrays, allow_pickle=True) if fault == "object array" else np.savez(f, **arrays)
    err = one_line_error(invoke("evaluate", path), str(path), named)
    assert "pickle" not in err and files(tmp_path) == ["t.npz"]


@pytest.mark.parametrize("keep", [0.0, 0.01, 0.3, 0.7, 0.99])
def test_truncated_trajectories_are_refused(tmp_path, traj, keep):
    whole = traj.save(tmp_path / "whole.npz").read_bytes()
    path = tmp_path / "t.npz"
    path.write_bytes(whole[: int(keep * len(whole))])
    with pytest.raises(TrajectoryFormatError, match=re.escape(str(path))):
        load_trajectory(path)
    one_line_error(invoke("evaluate", path), str(path))


def test_a_recording_is_not_a_trajectory(tmp_path):
    rrd = tmp_path / "run.rrd"
    rrd.write_bytes(b"RRF2" + bytes(40))
    err = one_line_error(invoke("evaluate", rrd), str(rrd), str(tmp_path / "run.npz"))
    assert "pickle" not in err and "beside" in err


def test_other_files_are_no_trajectory(tmp_path, take):
    np.save(tmp_path / "a.npy", np.zeros(3))
    for path in (take, tmp_path / "a.npy", tmp_path):
        err = one_line_error(invoke("evaluate", path), str(path))
        assert "pickle" not in err


def _unreadable(path: Path, monkeypatch) -> None:
    """``path`` without read permission; as root (which reads anyway) its reads are refused."""
    path.chmod(0)
    if os.access(path, os.R_OK):
        real_open = open

        def guarded(file, *args, **kwargs):
            if isinstance(file, str | os.PathLike) and Path(file) == path:
                raise PermissionError(errno.EACCES, "Permission denied", str(path))
            return real_open(file, *args, **kwargs)

        monkeypatch.setattr("builtins.open", guarded)
        monkeypatch.setattr("io.open", guarded)


def test_files_without_read_permission_are_named(tmp_path, traj, take, monkeypatch):
    npz = traj.save(tmp_path / "t.npz")
    stack = tmp_path / "s.toml"
    stack.write_text('name = "s"\n')
    motion = tmp_path / "take.xml"
    motion.write_bytes(take.read_bytes())
    for path in (npz, stack, motion):
        _unreadable(path, monkeypatch)
    one_line_error(invoke("evaluate", npz), str(npz), "Permission denied")
    one_line_error(invoke("run", take, "--stack", stack), str(stack), "Permission denied")
    err = one_line_error(invoke("info", motion), str(motion))
    assert "ermission denied" in err and "Usage" not in err


# --- the cache folder ------------------------------------------------------------------------


def test_a_cache_that_is_a_file_is_one_line(take, tmp_path, monkeypatch):
    blocker = tmp_path / "cache"
    blocker.write_text("")
    out = tmp_path / "out"
    out.mkdir()
    for where in (blocker, blocker / "below"):
        monkeypatch.setenv("HLIK_CACHE", str(where))
        one_line_error(invoke("run", take, "--rate", "0", "--out", out / "x.rrd"), str(where), "HLIK_CACHE")
        one_line_error(invoke("learn", "armar6"), str(where))
    assert files(out) == []


# --- both outputs or neither -----------------------------------------------------------------


def test_a_failed_recording_leaves_neither_file(take, tmp_path, monkeypatch):
    import hlik.recording

    def broken(path, *args, **kwargs):
        Path(path).write_bytes(b"RRF2 half")
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(hlik.recording, "write_recording", broken)
    one_line_error(
        invoke("run", take, "--rate", "0", "--placement", "mapped", "--out", tmp_path / "x.rrd"),
        f"{tmp_path / 'x.rrd'}: cannot write",
        "No space left",
    )
    assert files(tmp_path) == []


def test_a_full_disk_at_the_trajectory_names_it_and_leaves_nothing(take, tmp_path, monkeypatch):
    import hlik.trajectory

    def full(f, **arrays):
        f.write(b"PK\x03\x04 partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(hlik.trajectory.np, "savez", full)
    monkeypatch.setattr(hlik.trajectory.np, "savez_compressed", full)
    err = one_line_error(
        invoke("run", take, "--rate", "0", "--placement", "mapped", "--out", tmp_path / "x.rrd"),
        f"{tmp_path / 'x.npz'}: cannot write",
    )
    assert "No space left" in err and files(tmp_path) == []


def test_a_rerun_failure_is_a_failed_write(take, tmp_path, monkeypatch):
    import hlik.recording

    def rerun_failed(*args, **kwargs):
        raise RuntimeError("Failed to encode LogMsg: Failed to write: No space left on device (os error 28)")

    monkeypatch.setattr(hlik.recording, "write_recording", rerun_failed)
    one_line_error(
        invoke("run", take, "--rate", "0", "--placement", "mapped", "--out", tmp_path / "x.rrd"),
        "x.rrd: cannot write",
        "os error 28",
    )
    assert files(tmp_path) == []


def test_a_failure_keeps_the_previous_pair(tmp_path):
    pair = (tmp_path / "x.npz", tmp_path / "x.rrd")
    with atomic_paths(*pair) as tmps:
        for tmp, text in zip(tmps, ("old npz", "old rrd")):
            tmp.write_text(text)
    for failure in (OSError(errno.ENOSPC, "full"), KeyboardInterrupt(), SystemExit(143)):
        with pytest.raises(type(failure)), atomic_paths(*pair) as tmps:
            tmps[0].write_text("new npz")
            raise failure
        assert [p.read_text() for p in pair] == ["old npz", "old rrd"] and files(tmp_path) == [
            "x.npz",
            "x.rrd",
        ]


def test_an_interrupt_between_the_renames_waits_for_the_second(tmp_path, monkeypatch):
    """Ctrl-C right after the first rename: both files are renamed, then the interrupt is raised."""
    real_replace = os.replace
    calls = []

    def replace_then_interrupt(src, dst):
        real_replace(src, dst)
        calls.append(dst)
        if len(calls) == 1:
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(atomic.os, "replace", replace_then_interrupt)
    # Python's own Ctrl-C handler, whatever the runner left (a shell's background job ignores SIGINT)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    pair = (tmp_path / "x.npz", tmp_path / "x.rrd")
    try:
        with pytest.raises(KeyboardInterrupt), atomic_paths(*pair) as tmps:
            for tmp in tmps:
                tmp.write_text("new")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert calls == list(pair) and files(tmp_path) == ["x.npz", "x.rrd"]


def test_renames_wait_for_the_lock(tmp_path):
    """A writer that finished its temporaries renames only once another holds the lock no more."""
    pair = (tmp_path / "x.npz", tmp_path / "x.rrd")
    written = threading.Event()

    def write():
        with atomic_paths(*pair) as tmps:
            for tmp in tmps:
                tmp.write_text("mine")
        written.set()

    with pair_lock(pair[0]):
        worker = threading.Thread(target=write)
        worker.start()
        assert not written.wait(0.5)
        assert [p.exists() for p in pair] == [False, False]
    worker.join(10)
    assert written.is_set() and files(tmp_path) == ["x.npz", "x.rrd"]


def _fork(job) -> int:
    """Run ``job()`` in a forked child; its exit status is 0 if it returned, 1 if it raised."""
    pid = os.fork()
    if pid == 0:  # pragma: no cover (child)
        code = 1
        try:
            job()
            code = 0
        finally:
            os._exit(code)
    return pid


def _state(folder: Path) -> str:
    names = files(folder)
    assert not [n for n in names if n.startswith(".")], names  # no temporary, no lock left
    assert names in ([], ["x.npz", "x.rrd"]), names
    return "both" if names else "none"


def _fork_writes():
    if not hasattr(os, "fork"):
        pytest.skip("needs os.fork")


def test_sigterm_or_sigint_at_any_point_leaves_both_files_or_neither(tmp_path, traj, robot):
    _fork_writes()
    start = time.perf_counter()  # how long a child takes to write, uninterrupted
    os.waitpid(_fork(lambda: write_outputs(tmp_path / "x.npz", tmp_path / "x.rrd", traj, robot)), 0)
    duration = time.perf_counter() - start
    assert _state(tmp_path) == "both"
    rng = np.random.default_rng(15)
    for trial, delay in enumerate(rng.uniform(0.0, 1.3 * duration, size=10)):
        folder = tmp_path / f"t{trial}"
        folder.mkdir()
        pid = _fork(lambda f=folder: write_outputs(f / "x.npz", f / "x.rrd", traj, robot))
        time.sleep(delay)
        os.kill(pid, signal.SIGTERM if trial % 2 == 0 else signal.SIGINT)
        os.waitpid(pid, 0)
        _state(folder)  # both or none, and no temporary or lock


def test_concurrent_runs_leave_a_pair_from_one_run(tmp_path, traj, robot):
    _fork_writes()
    mine = {name: dataclasses.replace(traj, solver=name) for name in ("jm_first", "jm_second")}
    npz, rrd = tmp_path / "x.npz", tmp_path / "x.rrd"
    for _ in range(3):
        pids = [_fork(lambda t=t: write_outputs(npz, rrd, t, robot)) for t in mine.values()]
        codes = [os.waitpid(pid, 0)[1] for pid in pids]
        assert codes == [0, 0]
        solver = str(load_trajectory(npz).solver)
        recorded = [name for name in mine if f"-{robot.name}-{name}".encode() in rrd.read_bytes()]
        assert recorded == [solver], (solver, recorded)
        assert _state(tmp_path) == "both"


def test_an_npz_inside_the_archive_is_whole(tmp_path, traj, robot):
    write_outputs(tmp_path / "x.npz", tmp_path / "x.rrd", traj, robot)
    assert zipfile.is_zipfile(tmp_path / "x.npz") and _state(tmp_path) == "both"
    assert (tmp_path / "x.npz").stat().st_mode & 0o777 == 0o644


def test_a_full_disk_inside_an_atomic_write_names_the_file(tmp_path):
    """A failed write() names no file (the study's metric.toml and cells said only "No space left
    on device"): the error names the file being written."""
    target = tmp_path / "metric.toml"
    with pytest.raises(OSError) as e, atomic_path(target):
        raise OSError(errno.ENOSPC, "No space left on device")
    assert e.value.filename == str(target) and files(tmp_path) == []


def test_a_termination_raised_where_python_ignores_it_prints_no_traceback(capsys, monkeypatch):
    """SIGTERM's handler may run inside a weakref callback or ``__del__`` (a study's CI run met it in
    importlib's module lock), where Python prints the SystemExit as "Exception ignored" with a
    traceback and goes on; the block stays quiet there and still ends with 128 + 15."""
    import signal
    import sys

    from hlik.util.atomic import raising_on_sigterm

    if signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        pytest.skip("a SIGTERM handler is set by the test runner")
    monkeypatch.setattr(sys, "unraisablehook", sys.__unraisablehook__)  # Python's, not pytest's

    class Dies:
        def __init__(self, handler):
            self.handler = handler

        def __del__(self):
            self.handler(signal.SIGTERM, None)

    with pytest.raises(SystemExit) as ended:
        with raising_on_sigterm() as handler:
            Dies(handler)  # collected at once: its SystemExit cannot propagate
    assert ended.value.code == 128 + signal.SIGTERM
    err = capsys.readouterr().err
    assert "Traceback" not in err and "Exception ignored" not in err, err
