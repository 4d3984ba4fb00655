"""Usage and input mistakes are answered before the heavy libraries load (issue 32: a typo cost
about 4 s of imports before its one-line error), and formats hlik does not read are named."""

from __future__ import annotations

import subprocess
import sys

import pytest

from conftest import data_file
from hlik.criteria import registry
from hlik.human.formats import READS, motion_format
from hlik.util.errors import MotionFormatError

HEAVY = ("numpy", "mujoco", "scipy", "rerun", "mink", "nlopt")
# Runs ``hlik ARGS`` in a fresh interpreter; prints the heavy modules it imported, then its exit code.
PROBE = f"""
import runpy, sys
code = 0
try:
    runpy.run_module("hlik", run_name="__main__")
except SystemExit as e:
    code = e.code
print(",".join(m for m in {HEAVY!r} if m in sys.modules) + "|" + str(code), file=sys.__stdout__)
"""


def _probe(args: list[str], cwd) -> tuple[str, str, str]:
    """``hlik ARGS`` run by :data:`PROBE` in ``cwd``: the heavy modules it imported (comma
    separated), its exit code and its stderr, stripped."""
    done = subprocess.run(
        [sys.executable, "-c", PROBE, *args], cwd=cwd, capture_output=True, text=True, timeout=60
    )
    heavy, _, code = done.stdout.strip().splitlines()[-1].partition("|")
    return heavy, code, done.stderr.strip()


MISTAKES = [
    (["run", "--robot", "armar7"], "unknown robot 'armar7'"),
    (["run", "no_such_take.xml"], "no_such_take.xml: no such file"),
    (["run", "--solver", "qp", "--criteria", "SYNN"], "unknown criteria SYNN"),
    (["run", "--rate", "-1"], "--rate must be positive"),
    (["run", "--solver", "qpp"], "unknown solver 'qpp'"),
    (["run", "--layout", "sideways"], "unknown layout 'sideways'"),
    (["run", "--gradients", "fd"], "--gradients fd is for --solver slsqp"),
    (["run", "--scenario", "poses"], "unknown scenario 'poses'"),
    (["run", "--metric", "no_such_metric.toml"], "no_such_metric.toml (--metric): no such file"),
    (["run", "--span", "5:2"], "--span 5:2: START and END must be finite"),
    (["evaluate", "no_such_run.npz"], "no_such_run.npz: no such file"),
    (["export", "no_such_run.npz", "--format", "csv"], "no_such_run.npz: no such file"),
    (["replay", "no_such_run.npz"], "no_such_run.npz: no such file"),
    (["study", "--robots", "armar7"], "unknown robot 'armar7'"),
    (["run", "--out", "x.txt"], "--out names the recording and must end in .rrd"),
    (["run", "--out", "nope/x.rrd"], "output folder nope does not exist"),
    (["run", "--placement", "nowhere"], "placement 'nowhere': expected one of reach, mapped"),
    (["run", "--placement", "1,2"], "placement '1,2': expected one of"),
    (["run", "--export", "parquet"], "unknown --export format 'parquet'"),
    (["run", "--time-scale", "0"], "--time-scale must be 0.1 to 10"),
    (["run", "--time-scale", "nan"], "--time-scale must be 0.1 to 10"),
    (["run", "--scale", "-2"], "subject scale (--scale, subject_scale) must be auto or 0.1-10"),
    (["run", "--scale", "big"], "subject scale (--scale, subject_scale) must be auto or 0.1-10"),
]


@pytest.mark.parametrize(("args", "message"), MISTAKES, ids=[" ".join(a) for a, _ in MISTAKES])
def test_a_mistake_is_answered_before_any_heavy_import(tmp_path, args, message):
    heavy, code, err = _probe(args, tmp_path)
    assert code == "2", err
    assert len(err.splitlines()) == 1 and err.startswith("error: ") and message in err, err
    assert heavy == "", f"imported {heavy} before the error"
    assert not any(tmp_path.iterdir()), "nothing is written"


def test_an_unknown_export_format_is_answered_before_any_heavy_import(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    (work / "run.npz").write_bytes(b"not read: the format is checked first")
    heavy, code, err = _probe(["export", "run.npz", "--format", "xlsx"], work)
    assert code == "2" and err == "error: unknown export format 'xlsx'; choose one of: csv, mcap, lerobot"
    assert heavy == "", f"imported {heavy} before the error"
    assert sorted(p.name for p in work.iterdir()) == ["run.npz"]


@pytest.mark.parametrize("robot", ["armar6", "dual_panda", "armar3"])
def test_an_existing_default_output_is_answered_before_any_heavy_import(tmp_path, robot):
    """The default name needs the robot's description (its name, placement and scale), not its
    model: an earlier run's recording is found before MuJoCo loads, and kept."""
    earlier = tmp_path / "recordings" / f"demo_pour_wipe_{robot}_jm.rrd"
    earlier.parent.mkdir()
    earlier.write_bytes(b"earlier")
    heavy, code, err = _probe(["run", "--robot", robot, "--solver", "jm"], tmp_path)
    assert code == "2" and heavy == "", (heavy, err)
    said = "exists; pass --force to replace it, or --out to write elsewhere"
    assert err == f"error: {earlier.relative_to(tmp_path)}: {said}"
    assert earlier.read_bytes() == b"earlier" and [p.name for p in earlier.parent.iterdir()] == [earlier.name]


STACK_VALUES = [
    ("[qp]\nvelocity_cost = -1\n", "[qp] velocity_cost must be a finite number in [0, 1e+06], got -1"),
    ("[qp.gamma]\nHJA_r = 1e300\n", "HJA_r must be a finite number in [0, 1e+06], got 1e+300"),
    ('[slsqp]\ngradients = "fdd"\n', "[slsqp] gradients must be 'analytic' or 'fd'"),
    ("[jv]\nk = 1.0\n", "[jv] k must be a finite number <= 0, got 1.0"),
    ('[qp]\nsolver = "no_such_qp"\n', "[qp] solver 'no_such_qp' is not an installed QP solver"),
]


@pytest.mark.parametrize(("table", "message"), STACK_VALUES, ids=[m for _, m in STACK_VALUES])
def test_a_bad_stack_file_value_is_answered_before_any_heavy_import(tmp_path, table, message):
    """The settings classes live apart from the solvers (``solvers/settings.py``), so checking a
    stack file's values loads none of them; only another QP backend's name asks qpsolvers."""
    stack, work = tmp_path / "stack.toml", tmp_path / "work"
    stack.write_text(table)
    work.mkdir()
    heavy, code, err = _probe(["run", "--stack", str(stack)], work)
    assert code == "2", err
    assert len(err.splitlines()) == 1 and f"{stack}:" in err and message in err, err
    if "solver" not in table:
        assert heavy == "", f"imported {heavy} before the error"
    assert not any(work.iterdir()), "nothing is written"


@pytest.mark.parametrize(
    ("relative", "kind"),
    [
        ("cmu/01_01.amc", "ASF/AMC"),
        ("cmu/01.asf", "ASF/AMC"),
        ("hdm05/HDM_dg_06-03_03_120.amc", "ASF/AMC"),
        ("hdm05/HDM_dg_06-03_03_120.c3d", "C3D"),
    ],
)
def test_formats_hlik_does_not_read_are_named(relative, kind):
    path = data_file(relative)
    with pytest.raises(MotionFormatError) as err:
        motion_format(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ") and kind in message and READS in message, message
    assert "XML" not in message


def test_formats_are_recognised_by_content_without_their_extension(tmp_path):
    bvh, mmm, amc, text = (tmp_path / n for n in ("take.motion", "take.mmm", "take.dat", "notes.md"))
    bvh.write_text("HIERARCHY\nROOT Hips\n")
    mmm.write_text('\ufeff  <?xml version="1.0"?>\n<MMM version="2.0">')
    amc.write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 0 0 0 0 0 0\n")
    text.write_text("# not a motion\n")
    assert motion_format(bvh) == "bvh" and motion_format(mmm) == "mmm"
    with pytest.raises(MotionFormatError, match="ASF/AMC"):
        motion_format(amc)
    with pytest.raises(MotionFormatError, match="not a motion format hlik recognises"):
        motion_format(text)
    renamed = tmp_path / "take.bvh"  # a CMU .amc renamed .bvh: what it is, the file named once
    renamed.write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 0 0 0 0 0 0\n")
    with pytest.raises(MotionFormatError) as err:
        motion_format(renamed)
    assert str(err.value).startswith(f"{renamed}: not a BVH file: an ASF/AMC (Acclaim) file"), err.value
    assert str(err.value).count("take.bvh") == 1
    renamed.write_text("a text file\n")
    with pytest.raises(MotionFormatError, match=r"not a BVH file \(a BVH begins with HIERARCHY\)"):
        motion_format(renamed)
    named = tmp_path / "notes.xml"  # named as MMM, but not XML at all
    named.write_text("a text file\n")
    with pytest.raises(MotionFormatError, match="not XML") as err:
        motion_format(named)
    assert READS in str(err.value)


def test_the_registry_names_each_built_in_criterion_by_its_class():
    """The registry lists the built-ins without importing them; each name must resolve to the
    class of that name, functional where listed so."""
    for name in registry.human_likeness() + registry.functional():
        cls = registry.criterion_class(name)
        assert cls.name == name and cls.functional == (name in registry.functional())


def test_the_placement_rules_the_command_line_knows_are_the_placement_modules():
    from hlik.problem.placement import PLACEMENTS
    from hlik.run_spec import PLACEMENT_RULES

    assert PLACEMENT_RULES == (*PLACEMENTS, "optimize")


def test_the_export_formats_the_command_line_knows_are_the_writers():
    from hlik.export import WRITERS
    from hlik.run_spec import EXPORT_FORMATS

    assert EXPORT_FORMATS == tuple(WRITERS)


def test_the_demo_corpus_named_in_python_says_how_python_names_it():
    """``--corpus demo`` names the bundled demo on the command line; ``RunSpec(corpus="demo")``
    was refused as a missing folder (a reviewer's trial): it now says that Python's is None."""
    from hlik.run_spec import RunSpec
    from hlik.util.errors import SettingsError

    with pytest.raises(
        SettingsError, match=r"RunSpec.corpus 'demo': in Python the bundled demo is corpus=None"
    ):
        RunSpec(corpus="demo").check()


@pytest.mark.parametrize("command", ["info", "run"])
def test_a_robot_description_given_as_the_motion_says_what_it_is(command, tmp_path):
    """A robot TOML where a motion goes (a reviewer's `hlik info robot.toml`) was read as a keypoint
    description and refused for its 'acceleration_limits' key: it is now named for what it is."""
    from typer.testing import CliRunner

    from hlik.cli import app
    from hlik.util.paths import robots_dir

    robot = robots_dir() / "armar3.toml"
    result = CliRunner().invoke(
        app, [command, str(robot), "--out", str(tmp_path / "x.rrd")][: 2 if command == "info" else 4]
    )
    assert result.exit_code == 2, result.output
    assert result.stderr.strip() == (
        f"error: {robot}: a robot description, not a motion: use it as `--robot FILE` "
        "(`hlik calibrate FILE` checks it)"
    ), result.stderr
    assert list(tmp_path.iterdir()) == []
