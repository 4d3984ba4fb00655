"""Every CLI path that reads a motion, fed mutations of a real KIT take (issue 15): a bad input ends
in exit 2 and one line naming the file and the part at fault, with no traceback and no file left;
a fault the run can work around (a broken scene object) runs with a one-line warning."""

from __future__ import annotations

import math
import signal
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from conftest import data_file
from hlik.cli import app

STIR = "kit_bimanual/Stir_files_motions_2941_Stir1_bc_s_right_03.xml"  # 10 Hz, 7.8 s
SUBJECT, CUP = "true_1723", "true_cup_large"

Mutation = Callable[[ET.Element], None]


def _motion(root: ET.Element, name: str) -> ET.Element:
    return next(m for m in root.iter("Motion") if m.get("name") == name)


def _sensor(root: ET.Element, motion: str, kind: str) -> ET.Element:
    return next(s for s in _motion(root, motion).iter("Sensor") if s.get("type") == kind)


def _set(motion: str, kind: str, tag: str, value: float, frame: int = 5) -> Mutation:
    """One number of field ``tag`` at ``frame`` of a sensor set to ``value``."""

    def mutate(root: ET.Element) -> None:
        field = list(_sensor(root, motion, kind).iter(tag))[frame]
        values = (field.text or "").split()
        values[len(values) // 2] = repr(value)
        field.text = " ".join(values)

    return mutate


def _scale(motion: str, kind: str, tag: str, factor: float) -> Mutation:
    def mutate(root: ET.Element) -> None:
        for field in _sensor(root, motion, kind).iter(tag):
            field.text = " ".join(repr(float(v) * factor) for v in (field.text or "").split())

    return mutate


def _drop(motion: str, kind: str) -> Mutation:
    def mutate(root: ET.Element) -> None:
        sensors = _motion(root, motion).find("Sensors")
        assert sensors is not None
        sensors.remove(_sensor(root, motion, kind))

    return mutate


def _timesteps(motion: str, kind: str, change: Callable[[list[ET.Element]], None]) -> Mutation:
    def mutate(root: ET.Element) -> None:
        data = _sensor(root, motion, kind).find("Data")
        assert data is not None
        change(list(data))

    return mutate


def _duplicate(ms: list[ET.Element]) -> None:
    ms[11].set("timestep", ms[10].get("timestep", ""))


def _shuffle(ms: list[ET.Element]) -> None:
    a, b = ms[8].get("timestep", ""), ms[20].get("timestep", "")
    ms[8].set("timestep", b)
    ms[20].set("timestep", a)


# mutation -> the parts the one-line error must name (None: runs, with a warning naming them)
REFUSED: dict[str, tuple[Mutation, tuple[str, ...]]] = {
    "root in metres": (
        _scale(SUBJECT, "ModelPose", "RootPosition", 1e-3),
        ("subject", "ModelPose", "metres"),
    ),
    "root in centimetres": (_scale(SUBJECT, "ModelPose", "RootPosition", 0.1), ("subject", "ModelPose")),
    "angles in degrees": (
        _scale(SUBJECT, "Kinematic", "JointPosition", 180 / math.pi),
        ("subject", "degrees"),
    ),
    "no subject pose": (_drop(SUBJECT, "ModelPose"), ("ModelPose",)),
    "no subject joints": (_drop(SUBJECT, "Kinematic"), ("joint",)),
    "duplicated time": (_timesteps(SUBJECT, "ModelPose", _duplicate), ("subject", "ModelPose", "timestep")),
    "shuffled times": (_timesteps(SUBJECT, "Kinematic", _shuffle), ("subject", "Kinematic", "timestep")),
    **{
        f"{value} in {tag}": (_set(SUBJECT, kind, tag, value), ("subject", kind, tag))
        for kind, tag in (("Kinematic", "JointPosition"), ("ModelPose", "RootPosition"))
        for value in (math.nan, math.inf, -math.inf, 1e300)
    },
    **{
        f"{value} in RootRotation": (
            _set(SUBJECT, "ModelPose", "RootRotation", value),
            ("subject", "RootRotation"),
        )
        for value in (math.nan, math.inf)
    },
    "nan marker": (_set(SUBJECT, "MoCapMarker", "MarkerPosition", math.nan), ("subject", "MoCapMarker")),
}
WARNED: dict[str, tuple[Mutation, tuple[str, ...]]] = {
    "nan in an object's pose": (_set(CUP, "ModelPose", "RootPosition", math.nan), (CUP, "left out")),
    "an object without pose": (_drop(CUP, "ModelPose"), (CUP, "left out")),
    "duplicated object time": (_timesteps(CUP, "ModelPose", _duplicate), (CUP, "timestep", "left out")),
}


@pytest.fixture(scope="module")
def take() -> bytes:
    return data_file(STIR).read_bytes()


def _commands(path: Path, out: Path) -> list[list[str]]:
    """Every command that reads a motion: info, and run (jm: the reading, not the solving, is tested)."""
    run = ["run", str(path), "--solver", "jm", "--placement", "shoulders", "--out", str(out / "x.rrd")]
    return [["info", str(path)], run]


def _invoke(args: list[str]):
    return CliRunner().invoke(app, args)


def _check_refused(path: Path, out: Path, parts: tuple[str, ...]) -> None:
    for args in _commands(path, out):
        result = _invoke(args)
        err = result.stderr.strip()
        assert result.exit_code == 2, (args[0], result.exit_code, result.output)
        assert len(err.splitlines()) == 1 and err.startswith(f"error: {path}: "), err
        assert "Traceback" not in result.output, result.output
        for part in parts:
            assert part in err, (part, err)
        assert list(out.iterdir()) == [], list(out.iterdir())


def _write(tmp_path: Path, take: bytes, mutate: Mutation) -> tuple[Path, Path]:
    root = ET.fromstring(take)
    mutate(root)
    path, out = tmp_path / "take.xml", tmp_path / "out"
    ET.ElementTree(root).write(path)
    out.mkdir()
    return path, out


@pytest.mark.parametrize("name", list(REFUSED))
def test_a_bad_take_is_refused_in_one_line_naming_file_and_part(tmp_path, take, name):
    mutate, parts = REFUSED[name]
    _check_refused(*_write(tmp_path, take, mutate), parts)


@pytest.mark.parametrize("name", list(WARNED))
def test_a_broken_object_is_left_out_with_a_warning(tmp_path, take, name):
    mutate, parts = WARNED[name]
    path, out = _write(tmp_path, take, mutate)
    result = _invoke(_commands(path, out)[1])
    assert result.exit_code == 0, result.output
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning: ")]
    # ARMAR-6's own subject_scale, and jm keeping no limit: about the robot, not the object
    warnings = [w for w in warnings if "subject scaled" not in w and "keeps no speed" not in w]
    assert len(warnings) == 1 and all(p in warnings[0] for p in parts), result.stderr
    assert sorted(p.name for p in out.iterdir()) == ["x.npz", "x.rrd"]


@pytest.mark.parametrize("fraction", [0.0, 0.01, 0.3, 0.7, 0.999])
def test_a_truncated_take_is_refused(tmp_path, take, fraction):
    path, out = tmp_path / "take.xml", tmp_path / "out"
    path.write_bytes(take[: int(fraction * len(take))])
    out.mkdir()
    _check_refused(path, out, ())


@pytest.mark.parametrize("value", [1e300, 5.0, -50.0])
def test_evaluate_refuses_joint_values_no_solver_gives(tmp_path, value):
    """A limited joint beyond its limits (or any absurd angle) is not a solved trajectory."""
    import numpy as np

    out = tmp_path / "a.rrd"
    assert _invoke(["run", "--solver", "jm", "--out", str(out)]).exit_code == 0
    with np.load(out.with_suffix(".npz")) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["q"] = arrays["q"].copy()
    arrays["q"][3, 0] = value
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    result = _invoke(["evaluate", str(bad)])
    err = result.stderr.strip()
    assert result.exit_code == 2 and len(err.splitlines()) == 1, result.output
    assert err.startswith(f"error: {bad}: q: joint ") and "frame 3" in err and "limits" in err, err


def test_a_failed_run_creates_no_output_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert _invoke(["run", str(tmp_path / "missing.xml")]).exit_code == 2
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("stop", "code", "how"),
    [(KeyboardInterrupt, 130, "interrupted"), (SystemExit(128 + signal.SIGTERM), 143, "terminated")],
)
def test_ctrl_c_or_sigterm_ends_in_one_line_and_its_exit_code(tmp_path, monkeypatch, stop, code, how):
    """Ctrl-C, and SIGTERM, whose handler (hlik.util.atomic.Termination) raises SystemExit(143)
    wherever the command is: SIGTERM had ended with that code and no line (a reviewer's kill -TERM);
    now it says so, as Ctrl-C does."""
    import hlik.pipeline

    def stopped(*args, **kwargs):
        raise stop

    monkeypatch.setattr(hlik.pipeline, "load_motion", stopped)
    result = _invoke(["run", "--out", str(tmp_path / "x.rrd")])
    assert result.exit_code == code, result.output
    assert result.stderr.strip() == f"error: {how}; nothing written", result.stderr
    assert list(tmp_path.iterdir()) == []


def test_sigterm_after_the_outputs_are_written_says_they_are(tmp_path, monkeypatch):
    """A SIGTERM while the summary prints (the recording and trajectory already in place) had said
    "nothing written" with both files left (a reviewer, 2 of 12 kills): it now names them."""
    import hlik.cli.run

    def terminate(*args, **kwargs):
        raise SystemExit(128 + signal.SIGTERM)

    monkeypatch.setattr(hlik.cli.run, "_report", terminate)
    out = tmp_path / "x.rrd"
    result = _invoke(["run", "--solver", "jm", "--rate", "0", "--out", str(out)])
    assert result.exit_code == 143, result.output
    err = result.stderr.strip().splitlines()
    assert (
        err[-1]
        == f"error: terminated after writing {out} and {out.with_suffix('.npz')}; what followed was cut short"
    ), err
    assert "nothing written" not in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.npz", "x.rrd"]
