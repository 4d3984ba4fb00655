"""Keypoint streams as pose estimators write them (issue 30): dropouts written as ``0 0 0`` or
``-1 -1 -1``, left and right swapped for a span, a wrist swapped alone, a misdetected limb, a take
labelled mirrored. Built from a real LEGO-assembly take (OpenPose, skeleton-fitted), so the repair
can be compared with the untouched take."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import data_file
from hlik.human import load_motion
from hlik.human.keypoints import read_keypoints
from hlik.util.errors import MotionFormatError

TAKE = "human_assembly/Task1/Human1/trial1.txt"
COLUMNS = {
    "left_wrist": 0,
    "right_wrist": 3,
    "left_elbow": 6,
    "right_elbow": 9,
    "left_shoulder": 12,
    "right_shoulder": 15,
}
DESC = 'data = "{data}"\nrate = 30\n[keypoints]\n' + "".join(f"{k} = {v}\n" for k, v in COLUMNS.items())


def _write(tmp_path: Path, table: np.ndarray, name: str = "take") -> Path:
    np.savetxt(tmp_path / f"{name}.txt", table)
    desc = tmp_path / f"{name}.toml"
    desc.write_text(DESC.format(data=tmp_path / f"{name}.txt"))
    return desc


@pytest.fixture(scope="module")
def table() -> np.ndarray:
    return np.loadtxt(data_file(TAKE))


@pytest.fixture(scope="module")
def clean(table, tmp_path_factory):
    return read_keypoints(_write(tmp_path_factory.mktemp("clean"), table))


def _swap(
    table: np.ndarray, frames: slice, points: tuple[str, ...] = ("wrist", "elbow", "shoulder")
) -> np.ndarray:
    out = table.copy()
    for p in points:
        left, right = COLUMNS[f"left_{p}"], COLUMNS[f"right_{p}"]
        out[frames, left : left + 3], out[frames, right : right + 3] = (
            table[frames, right : right + 3],
            table[frames, left : left + 3],
        )
    return out


def test_the_untouched_take_needs_no_repair(clean):
    assert not any(
        "swapped" in n or "misdetected" in n or "undetected" in n or "mirrored" in n for n in clean.notes
    )


@pytest.mark.parametrize("sentinel", [0.0, -1.0])
def test_dropouts_are_gaps_filled_from_the_frames_around(tmp_path, table, clean, sentinel):
    """OpenPose writes an undetected keypoint as 0 0 0 (or -1 -1 -1): they were fitted as positions
    at the camera origin, jumps of 1.3 rad in 10 ms."""
    broken = table.copy()
    broken[200:206, 9:12] = sentinel  # the right elbow lost for 0.2 s
    broken[400, 0:3] = sentinel  # the left wrist for a frame
    keypoints = read_keypoints(_write(tmp_path, broken))
    assert any(
        "undetected keypoints (0 0 0 or -1 -1 -1) taken as gaps: left_wrist in 1 frame (13.33 s); "
        "right_elbow in 6 frames (6.67-6.83 s)" in n
        for n in keypoints.notes
    )
    # filled by interpolation: within a few cm of what was recorded, nowhere near the origin
    assert np.max(np.linalg.norm(keypoints.elbow[195:211, 1] - clean.elbow[195:211, 1], axis=-1)) < 0.05
    np.testing.assert_allclose(keypoints.elbow[:190], clean.elbow[:190])


def test_a_keypoint_never_detected_is_refused_naming_it(tmp_path, table):
    broken = table.copy()
    broken[:, 9:12] = 0.0
    with pytest.raises(MotionFormatError, match="keypoint right_elbow is never detected") as e:
        read_keypoints(_write(tmp_path, broken))
    assert "\n" not in str(e.value)


def test_sides_swapped_for_half_a_second_are_swapped_back_exactly(tmp_path, table, clean):
    keypoints = read_keypoints(_write(tmp_path, _swap(table, slice(300, 315))))
    said = [n for n in keypoints.notes if "swapped" in n.split(": ", 1)[1]]  # not the folder's name
    assert len(said) == 1 and "left and right keypoints swapped at 10.00-10.47 s; swapped back" in said[0]
    for part in ("shoulder", "elbow", "wrist"):
        np.testing.assert_allclose(getattr(keypoints, part), getattr(clean, part))


def test_one_swapped_span_changes_nothing_in_the_rest_of_the_fit(tmp_path, table):
    """The fitted subject turned round for the span and the warm-started fit carried the wrong
    branch on; repaired, the fitted joint angles are those of the untouched take."""
    clean = load_motion(_write(tmp_path, table, "clean"))
    swapped = load_motion(_write(tmp_path, _swap(table, slice(300, 315)), "swapped"))
    np.testing.assert_allclose(swapped.joints, clean.joints, atol=1e-9)


def test_wrists_swapped_alone_are_swapped_back(tmp_path, table, clean):
    keypoints = read_keypoints(_write(tmp_path, _swap(table, slice(500, 510), ("wrist",))))
    assert any("left and right wrists swapped at" in n for n in keypoints.notes)
    np.testing.assert_allclose(keypoints.wrist, clean.wrist)


def test_a_misdetected_wrist_is_filled_and_said(tmp_path, table, clean):
    broken = table.copy()
    broken[600:603, 3:6] += [0.3, 0.0, 0.0]  # the right wrist thrown 30 cm for three frames
    keypoints = read_keypoints(_write(tmp_path, broken))
    assert any("right arm misdetected" in n and "20.00-20.07 s" in n for n in keypoints.notes)
    assert np.max(np.linalg.norm(keypoints.wrist[598:606, 1] - clean.wrist[598:606, 1], axis=-1)) < 0.05


def test_a_take_labelled_mirrored_is_warned_about(tmp_path, table):
    """Every left column given as the right one: the labels are consistent, so nothing can be
    swapped back, but the hands then work behind the subject's back."""
    keypoints = read_keypoints(_write(tmp_path, _swap(table, slice(None))))
    assert any("left and right may be mirrored" in n for n in keypoints.notes)


def test_keypoints_no_human_arm_fits_are_refused_naming_the_table(tmp_path, table):
    """The shoulders' labels swapped for the whole take (the arms' kept): no MMM arm reaches the
    elbows and wrists (58 cm off on an OMOMO take), so the take is refused in one line rather than
    retargeted from a fit that is not the subject."""
    path = _write(tmp_path, _swap(table, slice(None), ("shoulder",)), "shoulders")
    with pytest.raises(MotionFormatError, match=r"do not fit a human's arms: elbows and wrists \d+ cm off"):
        load_motion(path)
    load_motion(_write(tmp_path, table, "clean"))  # the take as labelled fits


def test_a_subject_bending_over_is_said_and_not_floated_in_the_recording(tmp_path, table):
    """Every keypoint lowered by up to 0.6 m over a third of the take (a subject bending to lift
    a box, y down in this camera frame): the fit keeps the trunk upright, so it says so; the side
    layout lifts the human by where it stands, not by the bent frames (it had floated 0.7 m)."""
    from hlik.recording.scene import human_lift

    bent = table.copy()
    n = len(table)
    span = np.arange(n // 3, 2 * n // 3)
    bent[span, 1::3] += 0.6 * np.sin(np.linspace(0.0, np.pi, len(span)))[:, None] ** 2
    motion = load_motion(_write(tmp_path, bent, "bent"))
    said = [note for note in motion.notes if "the subject bends over" in note]
    assert len(said) == 1 and "sinks up to 0." in said[0], motion.notes
    standing = load_motion(_write(tmp_path, table, "standing"))
    assert not any("bends over" in note for note in standing.notes)
    assert human_lift(motion, "side") == pytest.approx(human_lift(standing, "side"), abs=0.02)
