"""Bad input: one typed error naming the file and the problem; the CLI exits 2 with one line."""

from __future__ import annotations

import re

import pytest
from typer.testing import CliRunner

from hlik import MotionFormatError, RobotError, load_motion
from hlik.cli import app
from hlik.human.demo import demo_motion
from hlik.human.mmm_format import write_mmm
from hlik.robot.model import load_robot


@pytest.fixture(scope="module")
def good_xml(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("demo") / "demo.xml"
    m = demo_motion()
    from dataclasses import replace

    write_mmm(
        replace(
            m,
            times=m.times[:5],
            joints=m.joints[:5],
            root_position=m.root_position[:5],
            root_rotation=m.root_rotation[:5],
        ),
        path,
    )
    return path.read_text()


def _write(tmp_path, text: str):
    path = tmp_path / "bad.xml"
    path.write_text(text)
    return path


def _expect(path, pattern: str):
    with pytest.raises(MotionFormatError) as err:
        load_motion(path)
    msg = str(err.value)
    assert str(path) in msg and re.search(pattern, msg), msg
    assert "\n" not in msg
    return msg


def test_malformed_xml(tmp_path, good_xml):
    _expect(_write(tmp_path, good_xml[:-40]), "malformed XML")


def test_entity_expansion_refused(tmp_path):
    bomb = (
        '<?xml version="1.0"?><!DOCTYPE MMM [<!ENTITY a "aaaaaaaaaa">'
        '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;"><!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;">]>'
        "<MMM>&c;</MMM>"
    )
    _expect(_write(tmp_path, bomb), "forbidden XML construct")


def test_missing_arm_joint(tmp_path, good_xml):
    text = good_xml.replace('<Joint name="LWy_joint"/>', "")
    # drop the matching column so the rest stays consistent
    lines = []
    for line in text.splitlines():
        if "<JointPosition>" in line:
            inner = line.split(">")[1].split("<")[0].split()
            del inner[18]
            line = f"<JointPosition>{' '.join(inner)}</JointPosition>"
        lines.append(line)
    _expect(_write(tmp_path, "\n".join(lines)), r"missing arm joint\(s\): LWy_joint")


def test_joint_vector_wrong_length(tmp_path, good_xml):
    text = good_xml.replace("</JointPosition>", " 0.5</JointPosition>", 1)
    _expect(_write(tmp_path, text), "JointPosition has 27 values, expected 26")


def test_non_finite_values(tmp_path, good_xml):
    i = good_xml.index("<JointPosition>") + len("<JointPosition>")
    _expect(_write(tmp_path, good_xml[:i] + "nan " + good_xml[i:].split(" ", 1)[1]), "non-finite")


def test_non_increasing_timesteps(tmp_path, good_xml):
    text = good_xml.replace('timestep="0.08"', 'timestep="0.02"')
    _expect(_write(tmp_path, text), r"timesteps not increasing at frame 2")


def test_missing_file_and_wrong_root(tmp_path):
    _expect(tmp_path / "nope.xml", "no such file")
    _expect(_write(tmp_path, "<Motion/>"), r"root element is <Motion>")


def test_unknown_robot():
    with pytest.raises(RobotError, match=r"unknown robot 'armar7'; choose one of: armar3"):
        load_robot("armar7")


@pytest.mark.parametrize(
    "args,pattern",
    [
        (["info", "missing.xml"], "missing.xml: no such file"),
        (["calibrate", "armar7"], "unknown robot 'armar7'"),
    ],
)
def test_cli_errors_are_one_line(args, pattern):
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    out = result.output.strip()
    assert re.search(pattern, out) and len(out.splitlines()) == 1 and "Traceback" not in out


def test_the_package_gives_its_submodules_on_first_access():
    """``import hlik; hlik.util.paths.demo_motion_path()`` (the README's mink example) works in a fresh
    interpreter without importing ``hlik.util.paths`` first; an unknown name is still an AttributeError,
    and importing ``hlik`` alone loads none of the heavy libraries."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import hlik\n"
        "heavy = sorted(m for m in ('mujoco', 'rerun', 'scipy') if m in sys.modules)\n"
        "print(hlik.util.paths.demo_motion_path().name, heavy)\n"
        "try:\n"
        "    hlik.no_such_thing\n"
        "except AttributeError as err:\n"
        "    print('AttributeError', err)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "demo_pour_wipe.xml []" in done.stdout, done.stdout
    assert "AttributeError module 'hlik' has no attribute 'no_such_thing'" in done.stdout, done.stdout


@pytest.mark.parametrize("module", ["hlik", "hlik.cli"])
def test_python_dash_m_runs_the_command_line(module):
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-m", module, "--help"], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0 and "Usage" in done.stdout and "run" in done.stdout, done.stdout + done.stderr
