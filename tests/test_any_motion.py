"""Motion from other sources: keypoint arrays and BVH, fitted to the MMM model (issue 17)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import data_file
from hlik.human import forward_kinematics, load_motion
from hlik.human.fit import fit_error, fit_mmm
from hlik.human.keypoints import Keypoints, read_bvh, read_keypoints
from hlik.human.motion import ARM_JOINTS
from hlik.util.errors import MotionFormatError

ARM = [j for side in ("left", "right") for j in ARM_JOINTS[side]]
HUMAN_ASSEMBLY = """data = "{data}"
rate = 30
{extra}
[keypoints]
left_wrist = 0
right_wrist = 3
left_elbow = 6
right_elbow = 9
left_shoulder = 12
right_shoulder = 15
"""


def _knuckles(fk) -> tuple[np.ndarray, np.ndarray]:
    """Index and little-finger knuckles that give exactly the MMM TCP frame (keypoints.hand_frames)."""
    sign = np.array([1.0, -1.0])[None, :, None]
    knuckles = fk.wrist + 0.08 * fk.tcp_rot[..., 2]
    across = -sign * fk.tcp_rot[..., 1]
    return knuckles + 0.04 * across, knuckles - 0.04 * across


def test_fit_reproduces_kit_takes_from_their_keypoints(takes):
    """Round trip on the real takes: MMM FK keypoints -> fit (height estimated) -> the keypoints to
    <= 1 cm and the arm joint angles to <= 0.1 rad, median (the issue's bound)."""
    for take in takes:
        motion = load_motion(take)
        fk = forward_kinematics(motion)
        index, pinky = _knuckles(fk)
        keypoints = Keypoints(motion.name, motion.times, fk.shoulder, fk.elbow, fk.wrist, index, pinky)
        fitted = fit_mmm(keypoints)
        assert abs(fitted.height - motion.height) < 0.01, take.name
        again = forward_kinematics(fitted)
        points = np.concatenate(
            [again.elbow - fk.elbow, again.wrist - fk.wrist, again.tcp_pos - fk.tcp_pos], axis=1
        )
        assert np.median(np.linalg.norm(points, axis=-1)) <= 0.01, take.name
        assert np.median(np.abs(fitted.angles(ARM) - motion.angles(ARM))) <= 0.1, take.name
        assert np.median(fit_error(fitted)) <= 0.01


def test_fit_is_invariant_to_moving_and_turning_the_keypoints(takes):
    motion = load_motion(takes[0]).frames(slice(0, 30))
    fk = forward_kinematics(motion)
    turn = Rotation.from_euler("z", 1.1)
    shift = np.array([0.7, -2.0, 0.0])
    moved = [turn.apply(p.reshape(-1, 3)).reshape(p.shape) + shift for p in (fk.shoulder, fk.elbow, fk.wrist)]
    a = fit_mmm(Keypoints("a", motion.times, fk.shoulder, fk.elbow, fk.wrist))
    b = fit_mmm(Keypoints("b", motion.times, *moved))
    np.testing.assert_allclose(a.angles(ARM), b.angles(ARM), atol=1e-4)


def _assembly(tmp_path: Path, relative: str, extra: str = "") -> Path:
    desc = tmp_path / "take.toml"
    desc.write_text(HUMAN_ASSEMBLY.format(data=data_file(relative), extra=extra))
    return desc


def test_human_assembly_keypoints_are_fitted(tmp_path):
    """Real OpenPose keypoints (camera frame, y down): axis and floor found, the arms fitted."""
    motion = load_motion(_assembly(tmp_path, "human_assembly/Task1/Human1/trial1.txt"))
    notes = "\n".join(motion.notes)
    assert "up axis detected as -y" in notes and "stood on one" in notes
    assert "no knuckles (index, pinky): the hands' orientation is not measured" in notes  # said, not hidden
    error = fit_error(motion)
    assert error is not None and np.median(error) < 0.06
    assert np.all(np.isfinite(motion.joints))
    assert 1.2 < motion.height < 2.0


def test_keypoints_with_nan_are_interpolated_never_passed_on(tmp_path):
    table = np.loadtxt(data_file("human_assembly/Task1/Human1/trial1.txt"))
    table[100:104, 3:6] = np.nan  # the right wrist lost for four frames, as Task3/Human2/trial2's
    np.savetxt(tmp_path / "gaps.txt", table)
    desc = tmp_path / "take.toml"
    desc.write_text(HUMAN_ASSEMBLY.format(data=tmp_path / "gaps.txt", extra=""))
    motion = load_motion(desc, rate=100)
    assert any("NaN keypoints, interpolated" in n for n in motion.notes)
    assert np.all(np.isfinite(motion.joints)) and np.all(np.isfinite(motion.root_position))


def test_a_keypoint_never_detected_is_refused_naming_it(tmp_path):
    """Task3/Human2/trial2 of the LEGO data has its right shoulder at 0 0 0 in every frame (and
    the left one still): fitted, it made a subject with one shoulder at the camera."""
    with pytest.raises(MotionFormatError, match="keypoint right_shoulder is never detected"):
        load_motion(_assembly(tmp_path, "human_assembly/Task3/Human2/trial2.txt"))


def test_keypoints_in_wrong_units_are_caught(tmp_path):
    table = np.loadtxt(data_file("human_assembly/Task1/Human1/trial1.txt"))
    mm = tmp_path / "mm.csv"
    np.savetxt(mm, table * 1000, delimiter=",")
    desc = tmp_path / "take.toml"
    desc.write_text(HUMAN_ASSEMBLY.format(data=mm, extra='units = "m"'))
    with pytest.raises(MotionFormatError, match=r"take.toml: units = 'm' gives arms .* fit units = 'mm'"):
        read_keypoints(desc)
    desc.write_text(HUMAN_ASSEMBLY.format(data=mm, extra=""))  # detected
    reference = read_keypoints(_assembly(tmp_path / "..", "human_assembly/Task1/Human1/trial1.txt"))
    np.testing.assert_allclose(read_keypoints(desc).wrist, reference.wrist, atol=1e-9)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ('up = "z"', r"up = 'z', but the elbows hang below the shoulders along -y"),
        ("rate = 0.1", r"rate = 0.1 Hz is outside"),
        ('units = "furlong"', r"units = 'furlong'; choose from"),
        ("lowpass = 40", r"lowpass = 40: give a cutoff in Hz below half the rate"),
    ],
)
def test_bad_keypoint_descriptions_are_refused(tmp_path, extra, message):
    desc = _assembly(tmp_path, "human_assembly/Task1/Human1/trial1.txt", extra)
    if extra.startswith("rate"):
        desc.write_text(desc.read_text().replace("rate = 30\n", "", 1))
    with pytest.raises(MotionFormatError, match=message):
        read_keypoints(desc)


def test_smplh_joint_positions_with_hands(tmp_path):
    """OMOMO SMPL-H joint positions, joints named in the file: hands give the wrist's orientation."""
    data = data_file("omomo_holosoma/sub3_largebox_003.npz")
    names = {
        "left_shoulder": "L_Shoulder", "right_shoulder": "R_Shoulder", "left_elbow": "L_Elbow",
        "right_elbow": "R_Elbow", "left_wrist": "L_Wrist", "right_wrist": "R_Wrist",
        "left_index": "L_Index1", "left_pinky": "L_Pinky1",
        "right_index": "R_Index1", "right_pinky": "R_Pinky1",
    }  # fmt: skip
    desc = tmp_path / "box.toml"
    table = "\n".join(f'{k} = "{v}"' for k, v in names.items())
    # no rate: the file stores its fps
    desc.write_text(f'data = "{data}"\narray = "joint_pos"\nnames = "joint_names"\n[keypoints]\n{table}\n')
    keypoints = read_keypoints(desc)
    assert np.isclose(keypoints.times[1], 1 / 30)
    assert keypoints.index is not None and keypoints.hand_frames() is not None
    motion = fit_mmm(keypoints)
    assert np.median(fit_error(motion)) < 0.06
    assert "the subject walks" in motion.walking()  # carrying the box across the room
    assert not any("no knuckles" in n for n in motion.notes)  # SMPL-H gives the knuckles
    hand = forward_kinematics(motion).tcp_rot
    wanted = keypoints.hand_frames()[1]
    angle = np.degrees(Rotation.from_matrix(np.swapaxes(hand, -1, -2) @ wanted).magnitude())
    assert np.median(angle) < 25  # the MMM wrist's range and a rigid SMPL-H hand allow no better


BVH_ARM = """    JOINT {S}Shoulder
    {{
      OFFSET {x4} 40.0 0.0
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT {S}Arm
      {{
        OFFSET {x14} 0.0 0.0
        CHANNELS 3 Zrotation Xrotation Yrotation
        JOINT {S}ForeArm
        {{
          OFFSET 0.0 -30.0 0.0
          CHANNELS 3 Zrotation Xrotation Yrotation
          JOINT {S}Hand
          {{
            OFFSET 0.0 -25.0 0.0
            CHANNELS 3 Zrotation Xrotation Yrotation
            End Site
            {{
              OFFSET 0.0 -8.0 0.0
            }}
          }}
        }}
      }}
    }}
"""


def _bvh(path: Path, frames: np.ndarray) -> None:
    """A Y-up BVH in cm (the usual export), facing +z, left arm towards +x."""
    arms = BVH_ARM.format(S="Left", x4=4.0, x14=14.0) + BVH_ARM.format(S="Right", x4=-4.0, x14=-14.0)
    head = (
        "HIERARCHY\nROOT Hips\n{\n  OFFSET 0.0 0.0 0.0\n"
        "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
        "  JOINT Spine\n  {\n    OFFSET 0.0 10.0 0.0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
    )
    motion = f"MOTION\nFrames: {len(frames)}\nFrame Time: 0.0333333\n"
    rows = "\n".join(" ".join(f"{v:.5f}" for v in f) for f in frames)
    path.write_text(head + arms + "  }\n}\n" + motion + rows + "\n")


def test_bvh_angles_come_back_as_mmm_angles(tmp_path):
    """Known BVH rotations (shoulder flexion, elbow flexion) are the MMM angles the fit finds."""
    pytest.importorskip("bvhio", reason='reading BVH needs bvhio: pip install -e ".[bvh]"')
    n = 20
    lift = np.linspace(0.0, 60.0, n)
    frames = np.zeros((n, 6 + 3 + 24))
    frames[:, 1] = 95.0  # the hips, cm above the floor
    frames[:, 13] = -lift  # LeftArm, X: forward
    frames[:, 16] = -lift  # LeftForeArm, X: elbow flexion
    frames[:, 25] = -lift / 2  # RightArm, X
    path = tmp_path / "lift.bvh"
    _bvh(path, frames)
    keypoints = read_bvh(path)
    assert any("up axis y (the skeleton's spine)" in n for n in keypoints.notes)
    assert np.allclose(
        np.linalg.norm(keypoints.elbow - keypoints.shoulder, axis=-1), 0.30, atol=1e-5
    )  # cm -> m
    motion = load_motion(path)
    rad = np.radians(lift)
    np.testing.assert_allclose(motion.joint("LSx_joint"), rad, atol=0.05)
    np.testing.assert_allclose(motion.joint("LEx_joint"), rad, atol=0.05)
    np.testing.assert_allclose(motion.joint("RSx_joint"), rad / 2, atol=0.05)


def test_bvh_without_usual_names_says_how_to_name_them(tmp_path):
    pytest.importorskip("bvhio", reason='reading BVH needs bvhio: pip install -e ".[bvh]"')
    path = tmp_path / "odd.bvh"
    _bvh(path, np.zeros((3, 33)))
    path.write_text(path.read_text().replace("LeftForeArm", "l_lowerleg_oops"))
    with pytest.raises(MotionFormatError, match=r"no BVH joint for the left elbow .*\[keypoints\]"):
        read_bvh(path)


def test_a_fitted_motion_records_its_keypoints_and_fit_error(tmp_path):
    """The recording of a run from keypoints draws them and plots the fit error per frame."""
    pytest.importorskip("bvhio")
    from rerun.chunk import RrdReader
    from typer.testing import CliRunner

    from hlik.cli import app

    n = 12
    frames = np.zeros((n, 33))
    frames[:, 1] = 95.0
    frames[:, 13] = frames[:, 16] = -np.linspace(20, 60, n)
    path = tmp_path / "lift.bvh"
    _bvh(path, frames)
    out = tmp_path / "lift.rrd"
    result = CliRunner().invoke(
        app, ["run", str(path), "--robot", "armar6", "--solver", "jm", "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    chunks = list(RrdReader(out).stream().to_chunks())
    entities = {c.entity_path for c in chunks}
    assert {"/world/human/keypoints", "/plots/fit/error"} <= entities
    error = [c for c in chunks if c.entity_path == "/plots/fit/error" and not c.is_static]
    frames = len(np.load(out.with_suffix(".npz"))["times"])
    assert sum(c.to_record_batch().num_rows for c in error) == frames  # a value every frame


def test_a_bvh_with_fewer_rows_than_frames_is_refused_at_once(tmp_path):
    """bvhio never returns from such a file (exporters write them: YanjieZe/GMR #172)."""
    pytest.importorskip("bvhio")
    path = tmp_path / "short.bvh"
    _bvh(path, np.zeros((10, 33)))
    path.write_text(path.read_text().replace("Frames: 10", "Frames: 12"))
    with pytest.raises(
        MotionFormatError, match=r"Frames: 12 but 10 motion rows \(the file ends early\)"
    ) as e:
        read_bvh(path)
    assert str(e.value).count("short.bvh") == 1  # the file named once
    path.write_text(path.read_text().replace("Frames: 12", "Frames: 2000000"))
    with pytest.raises(MotionFormatError, match="2000000 frames, more than hlik's 1000000"):
        read_bvh(path)


def test_the_bvh_writer_round_trips_the_joint_centres(tmp_path):
    """hlik's BVH (positions of the MMM joint centres) read back by hlik's BVH reader gives the same
    shoulders, elbows and wrists; the shipped demo BVH is the one the writer makes of the demo."""
    pytest.importorskip("bvhio", reason='reading BVH needs bvhio: pip install -e ".[bvh]"')
    from hlik.human.bvh import write_bvh
    from hlik.human.kinematics import forward_kinematics
    from hlik.human.load import load_motion
    from hlik.util.paths import demo_bvh_path, demo_motion_path

    demo = load_motion(demo_motion_path())
    path = write_bvh(demo, tmp_path / "demo.bvh")
    assert path.read_bytes() == demo_bvh_path().read_bytes(), "run python -m hlik.human.demo"
    back = load_motion(path)
    original = forward_kinematics(demo.resample(30.0))
    again = forward_kinematics(back)
    assert back.n_frames == demo.resample(30.0).n_frames
    for part in ("shoulder", "elbow", "wrist"):
        np.testing.assert_allclose(getattr(again, part), getattr(original, part), atol=1e-5)
    assert any("units detected as cm" in n for n in back.notes)


def test_the_readme_python_block_runs(tmp_path, monkeypatch):
    """README "Python", as written (the shared data found where the tests find it), in a fresh
    folder: every call in both its blocks works and the files they name are written."""
    pytest.importorskip("bvhio", reason='the block reads a BVH: pip install -e ".[bvh]"')
    take = data_file("kit_bimanual/Cut_files_motions_3021_Cut1_c_0_05cm_03.xml")
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    blocks = []  # the plain block, then the one that needs the extras
    for _ in range(2):
        after = blocks[-1][1] if blocks else text.index("## Python")
        start = text.index("```python", after) + len("```python")
        blocks.append((text[start : text.index("```", start)], text.index("```", start) + 3))
    assert 'load_robot("robots/examples/g1.toml")' in blocks[1][0]
    block = "".join(b for b, _ in blocks).replace("../shared/motion_data", str(take.parents[1]))
    block = block.replace('"robots/', f'"{Path(__file__).resolve().parents[1]}/robots/')  # from the checkout
    (tmp_path / "recordings").mkdir()
    monkeypatch.chdir(tmp_path)
    exec(block, {})  # noqa: S102 - the README's own block
    assert (tmp_path / "recordings" / "cut_armar6_jm.npz").is_file()
    assert (tmp_path / "recordings" / "cut_armar6_jm.rrd").is_file()


def test_smplh_elbows_labelled_as_the_other_sides_are_refused_naming_the_labels(tmp_path):
    """OMOMO with the elbows' names swapped: the arms reach across the chest and their length fits
    no unit; the one line names the labels as well as the units (it had blamed the units alone)."""
    data = data_file("omomo_holosoma/sub3_largebox_003.npz")
    names = {"left_shoulder": "L_Shoulder", "right_shoulder": "R_Shoulder", "left_elbow": "R_Elbow",
             "right_elbow": "L_Elbow", "left_wrist": "L_Wrist", "right_wrist": "R_Wrist"}  # fmt: skip
    desc = tmp_path / "swapped.toml"
    table = "\n".join(f'{k} = "{v}"' for k, v in names.items())
    desc.write_text(f'data = "{data}"\narray = "joint_pos"\nnames = "joint_names"\n[keypoints]\n{table}\n')
    with pytest.raises(MotionFormatError, match=r"measure .* or check the \[keypoints\] labels"):
        read_keypoints(desc)
