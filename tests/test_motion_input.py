"""Motion input hlik can trust (issue 15): implausible recordings are refused in one line naming
the file, the motion and the sensor; what can be worked around is read with a one-line note; MMM
files round-trip exactly. Bad inputs are made inside the tests from a real KIT take."""

from __future__ import annotations

import math
import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from conftest import DATA, data_file, kit_takes
from hlik import load_motion
from hlik.human.demo import demo_motion
from hlik.human.mmm_format import read_mmm, write_mmm
from hlik.human.motion import ARM_RANGES, HumanMotion, ObjectMotion
from hlik.util.errors import MotionFormatError, SettingsError

STIR = "kit_bimanual/Stir_files_motions_2941_Stir1_bc_s_right_03.xml"  # 79 frames at 10 Hz, 7.8 s
SUBJECT = "subject 'true_1723'"
CUP = "true_cup_large"


# --- making inputs from the real take ---------------------------------------------------------------


def _take(stop: float | None = 3.0) -> ET.Element:
    """The Stir take's XML, cropped to ``0 <= t <= stop`` s (every sensor) to keep tests fast."""
    root = ET.parse(data_file(STIR)).getroot()
    if stop is not None:
        for data in root.iter("Data"):
            for m in list(data):
                if float(m.get("timestep", "0")) > stop + 1e-9:
                    data.remove(m)
    return root


def _motion(root: ET.Element, name: str = "true_1723") -> ET.Element:
    return next(m for m in root.iter("Motion") if m.get("name") == name)


def _sensors(motion: ET.Element, kind: str) -> list[ET.Element]:
    return [s for s in motion.iter("Sensor") if s.get("type") == kind]


def _scale(element: ET.Element, tag: str, factor: float) -> None:
    for e in element.iter(tag):
        e.text = " ".join(repr(float(v) * factor) for v in (e.text or "").split())


def _keep(sensor: ET.Element, keep) -> None:
    """Drop the measurements whose timestep fails ``keep(t)``."""
    data = sensor.find("Data")
    assert data is not None
    for m in list(data):
        if not keep(float(m.get("timestep", "0"))):
            data.remove(m)


def _write(tmp_path: Path, root: ET.Element, name: str = "take.xml") -> Path:
    path = tmp_path / name
    ET.ElementTree(root).write(path)
    return path


def _refused(path: Path, *patterns: str) -> str:
    """The one-line message of reading ``path``, checked to name the file and match ``patterns``."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(MotionFormatError) as err:
            load_motion(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: ") and "\n" not in msg, msg
    for pattern in patterns:
        assert re.search(pattern, msg), (pattern, msg)
    return msg


def _read(path: Path) -> HumanMotion:
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        return load_motion(path)


def _one_note(motion: HumanMotion, *patterns: str) -> str:
    assert len(motion.notes) == 1, motion.notes
    note = motion.notes[0]
    assert note.startswith(f"{motion.source}: ") and "\n" not in note, note
    for pattern in patterns:
        assert re.search(pattern, note), (pattern, note)
    return note


@pytest.fixture(scope="module")
def stir() -> HumanMotion:
    """The take as read unchanged, cropped like the inputs made from it."""
    return load_motion(data_file(STIR)).crop(0.0, 3.0)


# --- real data reads clean ---------------------------------------------------------------------------


def test_real_takes_have_no_notes():
    """Every note on a real take would be a false alarm: the KIT takes are regular, in range and
    in millimetres."""
    for path in [*kit_takes(), data_file("kit_ml/00001_mmm.xml")]:
        m = _read(path)
        assert m.notes == (), m.notes
        assert all(np.all(np.isfinite(o.position)) for o in m.objects.values())


# --- 1. units ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("factor,unit", [(1e-3, "metres"), (1e-1, "centimetres")])
def test_lengths_in_another_unit_are_refused(tmp_path, factor, unit):
    root = _take()
    for tag in ("RootPosition", "MarkerPosition"):
        _scale(root, tag, factor)
    _refused(
        _write(tmp_path, root), SUBJECT, "ModelPose sensor", f"RootPosition looks like {unit}", "millimetres"
    )


def test_legacy_lengths_in_metres_are_refused(tmp_path):
    root = ET.parse(data_file("kit_ml/00001_mmm.xml")).getroot()
    _scale(root, "RootPosition", 1e-3)
    _refused(_write(tmp_path, root), "subject 'subject_id_4': MotionFrames: the root", "looks like metres")


def test_markers_alone_in_metres_are_refused(tmp_path):
    root = _take()
    _scale(_sensors(_motion(root), "MoCapMarker")[0], "MarkerPosition", 1e-3)
    _refused(_write(tmp_path, root), SUBJECT, "MoCapMarker sensor", "MarkerPosition looks like metres")


def test_angles_in_degrees_are_refused(tmp_path):
    root = _take()
    _scale(_sensors(_motion(root), "Kinematic")[0], "JointPosition", 180.0 / math.pi)
    _refused(_write(tmp_path, root), SUBJECT, "Kinematic sensor 1", r"look like degrees: \w+_joint reaches")


# --- 2. streams that disagree in time ---------------------------------------------------------------


def test_kinematic_stream_ending_early_is_cropped_not_held(tmp_path, stir):
    root = _take()
    _keep(_sensors(_motion(root), "Kinematic")[0], lambda t: t <= 2.0 + 1e-9)
    m = _read(_write(tmp_path, root))
    _one_note(
        m,
        SUBJECT,
        r"Kinematic sensor 1 \(44 joints",
        "ends at 2.00 s",
        "ModelPose sensor at 3.00 s",
        "using 0.00-2.00 s",
    )
    assert m.times[-1] == pytest.approx(2.0) and m.n_frames == 21
    np.testing.assert_array_equal(m.joints, stir.joints[:21])  # recorded values, nothing held
    np.testing.assert_array_equal(m.root_position, stir.root_position[:21])


def test_pose_stream_ending_early_is_reported(tmp_path, stir):
    root = _take()
    _keep(_sensors(_motion(root), "ModelPose")[0], lambda t: t <= 1.5 + 1e-9)
    m = _read(_write(tmp_path, root))
    _one_note(m, "ModelPose sensor ends at 1.50 s", r"Kinematic sensor \d .* at 3.00 s", "using 0.00-1.50 s")
    np.testing.assert_array_equal(m.joints, stir.joints[:16])


def test_kinematic_stream_starting_late_is_reported(tmp_path, stir):
    root = _take()
    _keep(_sensors(_motion(root), "Kinematic")[2], lambda t: t >= 1.0 - 1e-9)
    m = _read(_write(tmp_path, root))
    _one_note(m, r"Kinematic sensor 3 \(19 joints RightFinger", "starts at 1.00 s", "using 1.00-3.00 s")
    np.testing.assert_array_equal(m.joints, stir.joints[10:])


def test_streams_sharing_one_frame_are_refused(tmp_path):
    root = _take()
    _keep(_sensors(_motion(root), "Kinematic")[0], lambda t: t >= 3.0 - 1e-9)
    _refused(_write(tmp_path, root), SUBJECT, "starts at 3.00 s", r"share 1 frame\(s\), at least 2 needed")


def test_object_stream_ending_early_is_unknown_after(tmp_path):
    root = _take()
    _keep(_sensors(_motion(root, CUP), "ModelPose")[0], lambda t: t <= 1.0 + 1e-9)
    m = _read(_write(tmp_path, root))
    _one_note(
        m, f"object '{CUP}': ModelPose sensor runs 0.00-1.00 s, the motion 0.00-3.00 s", "unknown outside"
    )
    cup = m.objects[CUP]
    assert np.all(np.isfinite(cup.position[:11])) and np.all(np.isnan(cup.position[11:]))
    up = m.resample(100.0)
    pos = up.objects[CUP].position
    known = up.times <= up.times[0] + 1.0 + 1e-9
    assert np.all(np.isfinite(pos[known])) and np.all(np.isnan(pos[~known]))
    assert np.all(np.isfinite(up.objects[CUP].rotation[known]))


# --- 3. irregular sampling --------------------------------------------------------------------------


def test_gaps_in_the_sampling_are_reported(tmp_path):
    root = _take(stop=None)
    gone = lambda t: not any(a - 1e-9 <= t <= a + 0.4 + 1e-9 for a in (1.0, 3.0, 5.0))  # noqa: E731
    for data in root.iter("Data"):
        for meas in list(data):
            if not gone(float(meas.get("timestep", "0"))):
                data.remove(meas)
    m = _read(_write(tmp_path, root))
    _one_note(m, SUBJECT, "ModelPose sensor: irregular sampling: 3 gap", "longest 0.6 s after", "10 Hz")
    assert m.rate == pytest.approx(10.0)


# --- 4. poses outside every human range -------------------------------------------------------------


def test_poses_outside_the_mmm_ranges_are_reported(tmp_path, stir):
    root = _take()
    kin = _sensors(_motion(root), "Kinematic")[0]
    names = [j.get("name") for j in kin.iter("Joint")]
    col = names.index("LSx_joint")
    for k, e in enumerate(kin.iter("JointPosition")):
        if 5 <= k < 9:
            values = (e.text or "").split()
            values[col] = "-3.0" if k == 6 else "-2.5"
            e.text = " ".join(values)
    m = _read(_write(tmp_path, root))
    _one_note(
        m,
        "Kinematic sensor 1",
        "LSx_joint outside the MMM range -1.22..3.32 rad in 4 of 31 frames",
        r"worst -3\.00 rad at 0.60 s",
    )


def test_arm_ranges_are_the_mmm_models():
    from hlik.human.kinematics import human_model

    model = human_model(1.0)
    for name, limits in ARM_RANGES.items():
        np.testing.assert_allclose(model.joint(name).range, limits, err_msg=name)


# --- 5. scene objects -------------------------------------------------------------------------------


def test_object_without_pose_is_left_out_and_nothing_is_nan(tmp_path):
    root = _take()
    cup = _motion(root, CUP)
    sensors = cup.find("Sensors")
    assert sensors is not None
    sensors.remove(_sensors(cup, "ModelPose")[0])
    m = _read(_write(tmp_path, root))
    _one_note(m, f"object '{CUP}': no ModelPose sensor \\(only MoCapMarker\\); object left out")
    assert CUP not in m.objects and len(m.objects) == 2
    up = m.resample(100.0)  # crashed in the spline on NaN positions
    for o in up.objects.values():
        assert np.all(np.isfinite(o.position)) and np.all(np.isfinite(o.rotation))
    assert np.all(np.isfinite(up.joints)) and np.all(np.isfinite(up.root_position))


def test_object_without_sensors_is_left_out(tmp_path):
    root = _take()
    root.append(ET.Element("Motion"))
    m = _read(_write(tmp_path, root))
    _one_note(m, "object 'motion 5': no sensors; object left out")
    assert "motion 5" not in m.objects


def test_a_fault_in_an_object_leaves_it_out_with_the_object_named(tmp_path):
    root = _take()
    pose = _sensors(_motion(root, CUP), "ModelPose")[0]
    stamps = [m for m in pose.iter("Measurement")]
    stamps[12].set("timestep", stamps[11].get("timestep", ""))
    m = _read(_write(tmp_path, root))
    _one_note(m, f"object '{CUP}': ModelPose sensor: timesteps not increasing at frame 12", "object left out")
    assert CUP not in m.objects


def test_lost_markers_are_unknown_and_do_not_grow_the_box(tmp_path):
    """A cup marker at (0, 0, 0) for half a second, Vicon's 'lost': read as NaN, splined around,
    and the box the recording fits to the markers keeps its size."""
    root = _take()
    cup_markers = _sensors(_motion(root, CUP), "MoCapMarker")[0]
    for k, meas in enumerate(cup_markers.iter("Measurement")):
        if 10 <= k < 15:
            next(meas.iter("MarkerPosition")).text = "0 0 0"
    clean = _read(_write(tmp_path, _take(), "clean.xml")).resample(100.0)
    m = _read(_write(tmp_path, root))
    _one_note(
        m, f"object '{CUP}': MoCapMarker sensor: 1 of 4 markers not seen", "in 5 of 31", "read as unknown"
    )
    name = next(iter(m.objects[CUP].markers))
    lost = m.objects[CUP].markers[name]
    assert np.all(np.isnan(lost[10:15])) and np.all(np.isfinite(lost[:10])) and np.all(np.isfinite(lost[15:]))
    up = m.resample(100.0)
    splined = up.objects[CUP].markers[name]
    seen = np.isfinite(splined[:, 0])
    assert 0.55 * up.n_frames < seen.sum() < 0.9 * up.n_frames
    # through every recorded sample; between them within 1 mm of the spline through the clean take
    np.testing.assert_allclose(splined[seen], clean.objects[CUP].markers[name][seen], atol=1e-3)
    knots = splined[::10][np.isfinite(splined[::10, 0])]
    np.testing.assert_allclose(knots, lost[np.isfinite(lost[:, 0])], rtol=0, atol=1e-12)

    # the box recording.py fits: 2-98 % of the finite marker positions in the object frame
    boxes = []
    for motion in (clean, up):
        cup = motion.objects[CUP]
        local = np.concatenate(
            [np.einsum("tji,tj->ti", cup.rotation, p - cup.position) for p in cup.markers.values()]
        )
        local = local[np.all(np.isfinite(local), axis=1)]
        boxes.append(np.diff(np.percentile(local, [2, 98], axis=0), axis=0))
    np.testing.assert_allclose(boxes[1], boxes[0], rtol=0.05)


# --- 6. messages name the motion and the sensor ------------------------------------------------------


def test_subject_faults_name_the_subject_and_the_sensor(tmp_path):
    root = _take()
    pose = _sensors(_motion(root), "ModelPose")[0]
    stamps = list(pose.iter("Measurement"))
    stamps[12].set("timestep", stamps[11].get("timestep", ""))
    _refused(
        _write(tmp_path, root),
        f"{SUBJECT}: ModelPose sensor: timesteps not increasing at frame 12 \\(1.1 -> 1.1\\)",
    )


def test_a_joint_listed_twice_is_named(tmp_path):
    root = _take()
    fingers = _sensors(_motion(root), "Kinematic")[1]
    next(fingers.iter("Joint")).set("name", "LSx_joint")
    _refused(_write(tmp_path, root), SUBJECT, "joint 'LSx_joint' is listed twice")


def test_a_bad_number_names_sensor_time_and_field(tmp_path):
    root = _take()
    kin = _sensors(_motion(root), "Kinematic")[1]
    e = list(kin.iter("JointPosition"))[7]
    e.text = (e.text or "").replace(" ", " x ", 1)
    _refused(
        _write(tmp_path, root),
        f"{SUBJECT}: Kinematic sensor 2 .*: t=0.7 s: JointPosition has 20 values, expected 19",
    )


# --- 7. exact round trips ---------------------------------------------------------------------------

ROUND_TRIP = settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
finite = st.floats(-2.0, 2.0, allow_subnormal=False)


@ROUND_TRIP
@given(
    start=st.floats(0.0, 1e5),
    rate=st.floats(1.0, 1000.0),
    n=st.integers(2, 5),
    seed=st.integers(0, 2**32 - 1),
    scale=st.sampled_from([1.0, 1e-3, 1e3]),
    lost=st.booleans(),
)
def test_mmm_files_round_trip_exactly(tmp_path_factory, start, rate, n, seed, scale, lost):
    """read(write(m)) == m to the last bit for times, joints, root and object positions and markers
    (rotations through roll-pitch-yaw to 1e-12), at any time base."""
    rng = np.random.default_rng(seed)
    names = demo_motion().joint_names
    times = start + np.arange(n) / rate
    root_position = np.column_stack([rng.uniform(-2, 2, (n, 2)) * scale, rng.uniform(0.8, 1.0, n)])
    markers = {f"M{i}": rng.uniform(-2, 2, (n, 3)) * scale for i in range(3)}
    if lost:
        markers["M0"][rng.integers(n)] = np.nan
    cup = ObjectMotion("cup", rng.normal(size=(n, 3)), Rotation.random(n, rng=seed).as_matrix(), markers)
    motion = HumanMotion(
        name="m",
        times=times,
        joint_names=names,
        joints=rng.uniform(-1.0, 1.0, (n, len(names))),
        root_position=root_position,
        root_rotation=Rotation.random(n, rng=seed + 1).as_matrix(),
        height=1.75,
        mass=70.0,
        markers=markers,
        objects={"cup": cup},
    )
    path = tmp_path_factory.mktemp("rt") / "m.xml"
    write_mmm(motion, path)
    back = read_mmm(path)
    assert (
        back.joint_names == motion.joint_names and back.height == motion.height and back.mass == motion.mass
    )
    np.testing.assert_array_equal(back.times, motion.times)
    np.testing.assert_array_equal(back.joints, motion.joints)
    np.testing.assert_array_equal(back.root_position, motion.root_position)
    for k in markers:
        np.testing.assert_array_equal(back.markers[k], motion.markers[k])
        np.testing.assert_array_equal(back.objects["cup"].markers[k], cup.markers[k])
    np.testing.assert_array_equal(back.objects["cup"].position, cup.position)
    np.testing.assert_allclose(back.root_rotation, motion.root_rotation, atol=1e-12)
    np.testing.assert_allclose(back.objects["cup"].rotation, cup.rotation, atol=1e-12)
    assert back.rate == pytest.approx(rate)


def test_real_take_round_trips_exactly(tmp_path):
    m = load_motion(data_file(STIR))
    write_mmm(m, tmp_path / "copy.xml")
    back = read_mmm(tmp_path / "copy.xml")
    np.testing.assert_array_equal(back.times, m.times)
    np.testing.assert_array_equal(back.joints, m.joints)  # finger angles wrapped once, then kept
    np.testing.assert_array_equal(back.root_position, m.root_position)
    np.testing.assert_array_equal(back.markers["LSHO"], m.markers["LSHO"])
    assert back.notes == ()


# --- 8. edge inputs: one typed error ----------------------------------------------------------------


def test_unknown_mmm_version_is_refused(tmp_path):
    root = _take()
    root.set("version", "3.0")
    _refused(_write(tmp_path, root), "MMM version '3.0' is not supported")


def test_legacy_file_without_frames_is_refused(tmp_path):
    root = ET.parse(data_file("kit_ml/00001_mmm.xml")).getroot()
    frames = root.find("Motion/MotionFrames")
    assert frames is not None
    for f in list(frames):
        frames.remove(f)
    _refused(_write(tmp_path, root), "subject 'subject_id_4': MotionFrames has no <MotionFrame>")


@pytest.mark.parametrize(
    "step,pattern", [(1e-9, r"1e-09 s apart \(1e\+09 Hz\), above 10000 Hz"), (2.0, "below 1 Hz")]
)
def test_absurd_frame_rates_are_refused(tmp_path, step, pattern):
    root = _take()
    for data in root.iter("Data"):
        for k, meas in enumerate(data):
            meas.set("timestep", repr(k * step))
    _refused(_write(tmp_path, root), SUBJECT, "ModelPose sensor: timesteps are", pattern)


def test_a_huge_last_timestep_reads_but_is_not_resampled(tmp_path):
    root = _take()
    for data in root.iter("Data"):
        list(data)[-1].set("timestep", "1e6")
    path = _write(tmp_path, root)
    m = _read(path)
    _one_note(m, "irregular sampling: 1 gap", "longest 1e\\+06 s")
    with pytest.raises(
        SettingsError, match=r"take.xml: resampling 0-1e\+06 s .* at 100 Hz would make 100000001 frames"
    ):
        load_motion(path, rate=100.0)


@pytest.mark.parametrize("height,hint", [("0", ""), ("-1.7", ""), ("168", r" \(looks like centimetres\)")])
def test_implausible_heights_are_refused(tmp_path, height, hint):
    root = _take()
    h = next(root.iter("Height"))
    h.text = height
    _refused(
        _write(tmp_path, root), SUBJECT, f"subject height {height} m is implausible{hint}; expected 0.5-2.5 m"
    )


@pytest.mark.parametrize(
    "value,pattern", [("1e300", "is not a plausible value"), ("1e5", "not a joint angle")]
)
def test_absurd_angles_are_refused_without_warnings(tmp_path, value, pattern):
    root = _take()
    e = next(_sensors(_motion(root), "Kinematic")[0].iter("JointPosition"))
    e.text = value + " " + (e.text or "").split(" ", 1)[1]
    _refused(_write(tmp_path, root), SUBJECT, "Kinematic sensor 1", pattern)


@pytest.mark.parametrize("rate", [math.nan, math.inf, 1e-9, 1e6, 0.0, -10.0])
def test_absurd_resampling_rates_are_refused(stir, rate):
    with pytest.raises(SettingsError, match="resampling rate must be between 1 and 10000 Hz"):
        stir.resample(rate)


def test_notes_survive_crop_and_resample(tmp_path):
    root = _take()
    root.append(ET.Element("Motion"))
    m = _read(_write(tmp_path, root))
    assert len(m.notes) == 1
    assert m.crop(0.0, 1.0).notes == m.notes == m.resample(50.0).notes == m.mirrored().notes


# --- fuzzing: any mutation of a real take reads, or is refused in one line --------------------------

BAD_VALUES = ["nan", "inf", "-inf", "1e300", "-1e9", "1e-300", "0", "", "abc", "1 2", "7e2"]


def _numeric_slots(root: ET.Element) -> list[tuple[ET.Element, str | None]]:
    """(element, attribute) of every number in the file: texts, and timestep attributes (None = text)."""
    slots: list[tuple[ET.Element, str | None]] = []
    for e in root.iter():
        if e.get("timestep") is not None:
            slots.append((e, "timestep"))
        if e.text and e.text.strip() and e.tag not in ("File",):
            slots.append((e, None))
    return slots


@pytest.fixture(scope="module")
def small_take() -> bytes:
    return ET.tostring(_take(stop=1.0))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(slot=st.integers(0, 10**6), token=st.integers(0, 40), value=st.sampled_from(BAD_VALUES))
def test_any_mutated_number_reads_or_is_refused_in_one_line(tmp_path_factory, small_take, slot, token, value):
    root = ET.fromstring(small_take)
    slots = _numeric_slots(root)
    element, attribute = slots[slot % len(slots)]
    text = element.get(attribute) if attribute else element.text
    tokens = (text or "").split()
    tokens[token % len(tokens)] = value
    if attribute:
        element.set(attribute, " ".join(tokens))
    else:
        element.text = " ".join(tokens)
    path = _write(tmp_path_factory.mktemp("fuzz"), root)
    try:
        m = _read(path)
    except MotionFormatError as e:
        msg = str(e)
        assert msg.startswith(f"{path}: ") and "\n" not in msg
        assert "subject '" in msg or "MMM" in msg or "XML" in msg, msg
        return
    assert np.all(np.isfinite(m.joints)) and np.all(np.isfinite(m.root_position))
    assert np.all(np.diff(m.times) > 0) and all(n.startswith(f"{path}: ") for n in m.notes)
    up = m.resample(50.0)
    assert np.all(np.isfinite(up.joints)) and np.all(np.isfinite(up.root_rotation))


@pytest.mark.parametrize("fraction", [0.0, 0.1, 0.5, 0.9, 0.999])
def test_truncated_files_are_refused(tmp_path, small_take, fraction):
    path = tmp_path / "take.xml"
    path.write_bytes(small_take[: int(len(small_take) * fraction)])
    _refused(path, "malformed XML")


@pytest.mark.parametrize(
    "kind,pattern",
    [
        ("ModelPose", f"{SUBJECT}: no ModelPose sensor"),
        ("Kinematic", "no motion with MMM arm joints"),
    ],
)
def test_dropped_subject_streams_are_refused(tmp_path, kind, pattern):
    root = _take()
    subject = _motion(root)
    sensors = subject.find("Sensors")
    assert sensors is not None
    for s in _sensors(subject, kind):
        sensors.remove(s)
    _refused(_write(tmp_path, root), pattern)


def test_shuffled_timestamps_name_the_sensor(tmp_path):
    root = _take()
    kin = _sensors(_motion(root), "Kinematic")[2]
    stamps = list(kin.iter("Measurement"))
    a, b = stamps[3].get("timestep", ""), stamps[8].get("timestep", "")
    stamps[3].set("timestep", b)
    stamps[8].set("timestep", a)
    _refused(_write(tmp_path, root), f"{SUBJECT}: Kinematic sensor 3 .*: timesteps not increasing at frame 4")


# --- the field cases behave as their README says -----------------------------------------------------


@pytest.mark.parametrize(
    "name,outcome",
    [
        ("lengths_in_metres.xml", "RootPosition looks like metres"),
        ("joint_stream_ends_early.xml", "Kinematic sensor 1 .* ends at 4.00 s, ModelPose sensor at 7.80 s"),
        ("object_without_pose.xml", "object 'true_cup_large': no ModelPose sensor"),
    ],
)
def test_field_cases(name, outcome):
    path = DATA.parent / "field_cases" / name
    if not path.exists():
        pytest.skip(f"field case {path} not found")
    if name == "lengths_in_metres.xml":
        _refused(path, outcome)
        return
    m = load_motion(path, rate=100.0)
    _one_note(m, outcome)
    assert np.all(np.isfinite(m.joints)) and all(np.all(np.isfinite(o.position)) for o in m.objects.values())
