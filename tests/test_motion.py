"""Reading MMM files and human kinematics, checked against the recorded markers."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import data_file, kit_takes
from hlik import load_motion
from hlik.human.demo import demo_motion
from hlik.human.kinematics import forward_kinematics
from hlik.human.mmm_format import write_mmm
from hlik.human.motion import ARM_JOINTS
from hlik.util.paths import demo_motion_path

MIRROR = np.diag([-1.0, 1.0, 1.0])


def _midpoint(markers, a, b):
    return (markers[a] + markers[b]) / 2


def test_kit_takes_read(takes):
    for path in takes:
        m = load_motion(path)
        assert m.rate == pytest.approx(10.0)
        assert m.height == pytest.approx(1.68)
        assert all(j in m.joint_names for side in ARM_JOINTS.values() for j in side)
        assert len(m.markers) == 53 and "kitchen_sideboard" in "".join(m.objects)
        # metres: shoulder markers at standing shoulder height, the root near hip height
        assert 1.2 < np.median(m.markers["LSHO"][:, 2]) < 1.5
        assert 0.8 < np.median(m.root_position[:, 2]) < 1.0
        assert np.allclose(m.root_rotation @ m.root_rotation.transpose(0, 2, 1), np.eye(3), atol=1e-9)
        fingers = [i for i, n in enumerate(m.joint_names) if "Finger" in n]
        assert fingers and np.all(np.abs(m.joints[:, fingers]) <= np.pi)  # wrapped


@pytest.mark.parametrize("path", kit_takes(), ids=lambda p: p.name.split("_")[0])
def test_kinematics_match_markers(path):
    """kinematics.md §8: elbow ≤ 3 cm, wrist ≤ 4.5 cm median to the marker midpoints.

    Evaluated at the pipeline's 100 Hz (splined markers and joints); at the recorded 10 Hz the
    Transfer take's wrist median is 4.505 cm, the skin-marker forearm being 2 cm shorter.
    """
    m = load_motion(path, rate=100.0)
    k = forward_kinematics(m)
    mk = m.markers
    elbow = np.stack([_midpoint(mk, "LAEL", "LAOL"), _midpoint(mk, "RAEL", "RAOL")], 1)
    wrist = np.stack([_midpoint(mk, "LWPS", "LWTS"), _midpoint(mk, "RWPS", "RWTS")], 1)
    shoulder = np.stack([mk["LSHO"], mk["RSHO"]], 1)
    assert np.median(np.linalg.norm(k.elbow - elbow, axis=-1)) <= 0.030
    assert np.median(np.linalg.norm(k.wrist - wrist, axis=-1)) <= 0.045
    assert np.median(np.linalg.norm(k.shoulder - shoulder, axis=-1)) <= 0.04
    # left arm is on the subject's left: the body's x axis points from left to right shoulder
    right_axis = m.root_rotation[:, :, 0]
    assert np.all(np.sum((k.shoulder[:, 1] - k.shoulder[:, 0]) * right_axis, -1) > 0.3)


def test_tcp_frame_and_segment_lengths(takes):
    m = load_motion(takes[0])
    k = forward_kinematics(m)
    r = k.tcp_rot
    assert np.allclose(r @ r.transpose(0, 1, 3, 2), np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(r), 1.0)
    assert np.allclose(np.linalg.norm(k.elbow - k.shoulder, axis=-1), 0.188 * m.height)
    assert np.allclose(np.linalg.norm(k.wrist - k.elbow, axis=-1), 0.145 * m.height)
    # TCP is in the palm: half a hand length along the approach axis past the wrist
    along = np.sum((k.tcp_pos - k.wrist) * r[..., :, 2], -1)
    assert np.allclose(along, 0.054 * m.height, atol=1e-9)


def test_legacy_walk_reads():
    m = load_motion(data_file("kit_ml/00001_mmm.xml"))
    assert m.n_frames == 378 and m.rate == pytest.approx(100.0) and m.height == pytest.approx(1.82)
    walked = np.linalg.norm(m.root_position[-1, :2] - m.root_position[0, :2])
    assert 1.0 < walked < 1.8
    k = forward_kinematics(m)
    assert np.all(np.isfinite(k.tcp_pos))
    # arms swing at the sides: wrists stay below the shoulders
    assert np.all(k.wrist[..., 2] < k.shoulder[..., 2])


def test_walking_is_noted_on_the_span_retargeted(takes):
    """Any format's subject that walks gets the note, from its root; the span where it stands, and
    the KIT takes at their tables, do not."""
    walk = load_motion(data_file("kit_ml/00001_mmm.xml"))
    assert "00001_mmm.xml: motion: the subject walks (1." in walk.walking()
    assert walk.crop(0.0, 0.3).walking() == ""  # the first steps: under half a metre
    assert all(load_motion(t).walking() == "" for t in takes)


def test_resample_round_trip(takes):
    m = load_motion(takes[1])
    up = m.resample(100.0)
    assert np.allclose(np.diff(up.times), 0.01)
    assert up.duration == pytest.approx(m.duration, abs=0.01)
    # an interpolating spline passes through its knots: every 10th frame is a recorded frame
    assert np.allclose(up.joints[::10], m.joints[: len(up.joints[::10])], atol=1e-9)
    assert np.allclose(up.root_rotation[::10], m.root_rotation[: len(up.times[::10])], atol=1e-9)
    assert np.allclose(up.markers["LSHO"][::10], m.markers["LSHO"][: len(up.times[::10])], atol=1e-9)
    name = next(iter(m.objects))
    assert up.objects[name].position.shape == (up.n_frames, 3)


@pytest.mark.parametrize(("factor", "every"), [(2.0, (2, 1)), (0.5, (1, 2)), (3.0, (3, 1))])
def test_retimed_plays_the_same_poses_at_the_same_rate(takes, factor, every):
    """Time scaling: the same poses at times t0 + factor (t - t0), at the take's own rate, so every
    joint speed is divided by the factor; 1 changes nothing. ``every``: the frames of the new and
    the old motion that fall at the same pose (the spline passes through the old frames)."""
    m = load_motion(takes[1], rate=100.0).crop(0.0, 2.0)
    slow = m.retimed(factor)
    assert slow.rate == pytest.approx(m.rate)
    assert slow.duration == pytest.approx(factor * m.duration, abs=0.01)
    new, old = slow.joints[:: every[0]], m.joints[:: every[1]]
    n = min(len(new), len(old))
    assert n > 50 and np.allclose(new[:n], old[:n], atol=1e-9)
    assert np.allclose(slow.root_rotation[:: every[0]][:n], m.root_rotation[:: every[1]][:n], atol=1e-9)
    speed = lambda motion: np.abs(np.diff(motion.joints, axis=0)).max() * motion.rate  # noqa: E731
    assert speed(slow) == pytest.approx(speed(m) / factor, rel=0.1)
    assert m.retimed(1.0) is m


def test_resampled_jerk_has_no_steps(takes):
    # 10 Hz takes at 100 Hz: a cubic's jerk jumps at every recorded frame by about its own size
    # (MJE scores that as a barcode); the quintic's changes between frames by under half its maximum
    for path in takes:
        m = load_motion(path)
        q = m.resample(100.0).joints[:, np.ptp(m.joints, axis=0) > 0.05]
        jerk = np.diff(q, 3, axis=0)
        step = np.abs(np.diff(jerk, axis=0)).max(axis=0)
        assert np.all(step < 0.5 * np.abs(jerk).max(axis=0)), path.name


def test_mirror_is_reflection(takes):
    m = load_motion(takes[2])
    mm = m.mirrored()
    assert np.allclose(mm.mirrored().joints, m.joints)
    k, km = forward_kinematics(m), forward_kinematics(mm)
    for a, b in ((k.wrist, km.wrist), (k.elbow, km.elbow), (k.tcp_pos, km.tcp_pos)):
        assert np.allclose(b[:, 0], a[:, 1] @ MIRROR, atol=1e-9)
        assert np.allclose(b[:, 1], a[:, 0] @ MIRROR, atol=1e-9)
    assert np.allclose(mm.markers["LSHO"], m.markers["RSHO"] @ MIRROR)
    assert np.allclose(mm.markers["L3"], m.markers["L3"] @ MIRROR)  # lumbar marker, not "left"
    assert np.allclose(mm.joint("LSy_joint"), -m.joint("RSy_joint"))
    assert np.allclose(mm.joint("LSx_joint"), m.joint("RSx_joint"))


def test_write_read_round_trip(tmp_path, takes):
    m = load_motion(takes[3])
    out = tmp_path / "copy.xml"
    write_mmm(m, out)
    back = load_motion(out)
    assert back.joint_names == m.joint_names
    assert np.allclose(back.times, m.times)
    assert np.allclose(back.joints, m.joints, atol=1e-7)
    assert np.allclose(back.root_position, m.root_position, atol=1e-7)
    assert np.allclose(back.root_rotation, m.root_rotation, atol=1e-7)
    assert set(back.markers) == set(m.markers) and set(back.objects) == set(m.objects)
    name = next(iter(m.objects))
    assert np.allclose(back.objects[name].position, m.objects[name].position, atol=1e-7)
    assert list(tmp_path.iterdir()) == [out]  # no temporary file left behind


def test_bundled_demo_is_the_generated_one():
    m = load_motion(demo_motion_path())
    ref = demo_motion()
    assert m.joint_names == ref.joint_names
    assert np.allclose(m.joints, ref.joints, atol=1e-7) and np.allclose(m.times, ref.times)
    k = forward_kinematics(m.resample(100.0))
    # both hands work in front of the body at some point, and the motion is smooth
    assert np.max(k.tcp_pos[:, :, 1]) > 0.25
    jerk = np.diff(m.resample(100.0).joints, 3, axis=0)
    assert np.max(np.abs(jerk)) < 1e-3
