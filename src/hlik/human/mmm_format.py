"""Reading and writing MMM motion files (kinematics.md §1.3 legacy format, §1.4 MMM 2.0).

Files are parsed with defusedxml (no entity expansion, no external entities). Lengths in the
files are millimetres and are converted to metres here; nothing else in hlik sees millimetres.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from xml.etree.ElementTree import Element, ParseError

import defusedxml.ElementTree as DET
import numpy as np
from defusedxml import DefusedXmlException
from scipy.spatial.transform import Rotation

from hlik.atomic import atomic_path
from hlik.errors import MotionFormatError
from hlik.human.motion import ARM_JOINTS, HumanMotion, ObjectMotion, _slerp

MM = 1e-3


def read_mmm(path: Path) -> HumanMotion:
    """Parse an MMM file; the human is the motion whose kinematics carries the MMM arm joints."""
    root = _parse(path)
    if root.tag != "MMM":
        raise MotionFormatError(path, f"root element is <{root.tag}>, expected <MMM>")
    motions = root.findall("Motion")
    if not motions:
        raise MotionFormatError(path, "no <Motion> element")
    legacy = any(m.find("MotionFrames") is not None for m in motions)
    return _read_legacy(path, motions) if legacy else _read_v2(path, motions)


def write_mmm(motion: HumanMotion, path: str | Path) -> None:
    """Write ``motion`` as an MMM 2.0 file, atomically (temporary file, then rename)."""
    path = Path(path)
    lines = [f'<MMM version="2.0" name="{motion.name}">']
    for obj in motion.objects.values():
        lines.append(f'\t<Motion name="{obj.name}" type="object" synchronized="true">')
        lines.append("\t\t<Sensors>")
        lines += _pose_sensor(motion.times, obj.position, obj.rotation)
        lines += _marker_sensor(motion.times, obj.markers)
        lines.append("\t\t</Sensors>\n\t</Motion>")
    lines.append(f'\t<Motion name="{motion.name}" type="object" synchronized="true">')
    lines.append('\t\t<Model path="mmm.xml">\n\t\t\t<ModelProcessorConfig type="Winter">')
    lines.append(f"\t\t\t\t<Height>{_num(motion.height)}</Height>")
    if motion.mass is not None:
        lines.append(f"\t\t\t\t<Mass>{_num(motion.mass)}</Mass>")
    lines.append("\t\t\t</ModelProcessorConfig>\n\t\t</Model>\n\t\t<Sensors>")
    lines += _pose_sensor(motion.times, motion.root_position, motion.root_rotation)
    lines.append('\t\t\t<Sensor type="Kinematic" version="1.0">\n\t\t\t\t<Configuration>')
    lines += [f'\t\t\t\t\t<Joint name="{n}"/>' for n in motion.joint_names]
    lines.append("\t\t\t\t</Configuration>\n\t\t\t\t<Data>")
    for t, q in zip(motion.times, motion.joints):
        lines.append(f'\t\t\t\t\t<Measurement timestep="{_num(t)}">')
        lines.append(f"\t\t\t\t\t\t<JointPosition>{_fmt(q)}</JointPosition>")
        lines.append("\t\t\t\t\t</Measurement>")
    lines.append("\t\t\t\t</Data>\n\t\t\t</Sensor>")
    lines += _marker_sensor(motion.times, motion.markers)
    lines.append("\t\t</Sensors>\n\t</Motion>\n</MMM>\n")
    _atomic_write(path, "\n".join(lines))


# --- parsing -------------------------------------------------------------------------------------


def _parse(path: Path) -> Element:
    try:
        return DET.parse(path).getroot()
    except FileNotFoundError:
        raise MotionFormatError(path, "no such file") from None
    except IsADirectoryError:
        raise MotionFormatError(path, "is a directory, not a motion file") from None
    except DefusedXmlException as e:
        raise MotionFormatError(path, f"forbidden XML construct ({type(e).__name__})") from None
    except ParseError as e:
        raise MotionFormatError(path, f"malformed XML: {e}") from None
    except OSError as e:
        raise MotionFormatError(path, f"cannot read: {e.strerror}") from None


def _read_v2(path: Path, motions: list[Element]) -> HumanMotion:
    human, objects = None, {}
    for m in motions:
        sensors = m.findall("Sensors/Sensor")
        kin = [s for s in sensors if s.get("type") == "Kinematic"]
        names = [j.get("name") for s in kin for j in s.findall("Configuration/Joint")]
        if ARM_JOINTS["left"][0] in names or ARM_JOINTS["right"][0] in names:
            if human is None:
                human = m
            continue
        objects[m.get("name", "object")] = m
    if human is None:
        raise MotionFormatError(path, "no motion with MMM arm joints (e.g. LSx_joint) found")

    sensors = human.findall("Sensors/Sensor")
    pose = [s for s in sensors if s.get("type") == "ModelPose"]
    if not pose:
        raise MotionFormatError(path, f"motion {human.get('name')!r} has no ModelPose sensor")
    times, root_pos, root_rot = _read_pose_sensor(path, pose[0])
    names, columns = [], []
    for s in (s for s in sensors if s.get("type") == "Kinematic"):
        jn = [j.get("name") or "" for j in s.findall("Configuration/Joint")]
        t, q = _read_measurements(path, s, "JointPosition", len(jn))
        names += jn
        columns.append(_align(t, q, times))
    joints = np.concatenate(columns, axis=1)
    markers = {}
    for s in (s for s in sensors if s.get("type") == "MoCapMarker"):
        markers.update(_read_markers(path, s, times))
    objs = {name: _read_object(path, name, m, times) for name, m in objects.items()}
    height, mass = _read_subject(path, human.find("Model/ModelProcessorConfig"))
    return _finish(
        path,
        human.get("name") or path.stem,
        times,
        names,
        joints,
        root_pos,
        root_rot,
        height,
        mass,
        markers,
        objs,
    )


def _read_legacy(path: Path, motions: list[Element]) -> HumanMotion:
    human = next((m for m in motions if m.find("JointOrder") is not None), None)
    if human is None:
        raise MotionFormatError(path, "legacy motion without <JointOrder>")
    names = [j.get("name") or "" for j in human.findall("JointOrder/Joint")]
    frames = human.findall("MotionFrames/MotionFrame")
    times, pos, rpy, q = [], [], [], []
    for k, f in enumerate(frames):
        times.append(_floats(path, f.findtext("Timestep"), 1, f"frame {k}: Timestep")[0])
        pos.append(_floats(path, f.findtext("RootPosition"), 3, f"frame {k}: RootPosition"))
        rpy.append(_floats(path, f.findtext("RootRotation"), 3, f"frame {k}: RootRotation"))
        q.append(_floats(path, f.findtext("JointPosition"), len(names), f"frame {k}: JointPosition"))
    times_a = _check_times(path, np.asarray(times), "MotionFrames")
    height, mass = _read_subject(path, human.find("ModelProcessorConfig"))
    return _finish(
        path,
        human.get("name") or path.stem,
        times_a,
        names,
        np.asarray(q),
        np.asarray(pos) * MM,
        _rpy_to_matrix(np.asarray(rpy)),
        height,
        mass,
        {},
        {},
    )


def _finish(path, name, times, names, joints, root_pos, root_rot, height, mass, markers, objects):
    missing = [j for side in ARM_JOINTS.values() for j in side if j not in names]
    if missing:
        raise MotionFormatError(path, f"missing arm joint(s): {', '.join(missing)}")
    if len(set(names)) != len(names):
        raise MotionFormatError(path, "a joint is listed twice")
    if len(times) < 2:
        raise MotionFormatError(path, f"needs at least 2 frames, found {len(times)}")
    fingers = np.array(["Finger" in n for n in names])
    joints = joints.copy()
    joints[:, fingers] = np.arctan2(np.sin(joints[:, fingers]), np.cos(joints[:, fingers]))
    return HumanMotion(
        name=name,
        times=times,
        joint_names=tuple(names),
        joints=joints,
        root_position=root_pos,
        root_rotation=root_rot,
        height=height,
        mass=mass,
        markers=markers,
        objects=objects,
        source=path,
    )


def _read_subject(path: Path, cfg: Element | None) -> tuple[float, float | None]:
    if cfg is None or cfg.findtext("Height") is None:
        raise MotionFormatError(path, "no subject <Height> in ModelProcessorConfig")
    height = _floats(path, cfg.findtext("Height"), 1, "Height")[0]
    if not 0.5 < height < 2.5:
        raise MotionFormatError(path, f"subject height {height} m is implausible")
    mass = cfg.findtext("Mass")
    return height, None if mass is None else _floats(path, mass, 1, "Mass")[0]


def _read_pose_sensor(path: Path, sensor: Element):
    t, pos = _read_measurements(path, sensor, "RootPosition", 3)
    _, rpy = _read_measurements(path, sensor, "RootRotation", 3)
    return t, pos * MM, _rpy_to_matrix(rpy)


def _read_object(path: Path, name: str, motion: Element, times: np.ndarray) -> ObjectMotion:
    sensors = motion.findall("Sensors/Sensor")
    pose = next((s for s in sensors if s.get("type") == "ModelPose"), None)
    if pose is None:
        eye = np.broadcast_to(np.eye(3), (len(times), 3, 3)).copy()
        position, rotation = np.full((len(times), 3), np.nan), eye
    else:
        t, pos, rot = _read_pose_sensor(path, pose)
        position = _align(t, pos, times)
        rotation = _align(t, rot, times, _slerp)
    markers = {}
    for s in (s for s in sensors if s.get("type") == "MoCapMarker"):
        markers.update(_read_markers(path, s, times))
    return ObjectMotion(name=name, position=position, rotation=rotation, markers=markers)


def _read_measurements(path: Path, sensor: Element, tag: str, n: int):
    times, rows = [], []
    for k, meas in enumerate(sensor.findall("Data/Measurement")):
        times.append(_floats(path, meas.get("timestep"), 1, f"measurement {k}: timestep")[0])
        rows.append(_floats(path, meas.findtext(tag), n, f"t={times[-1]:g}: {tag}"))
    if not rows:
        raise MotionFormatError(path, f"{sensor.get('type')} sensor has no measurements")
    return _check_times(path, np.asarray(times), f"{sensor.get('type')} sensor"), np.asarray(rows)


def _read_markers(path: Path, sensor: Element, times: np.ndarray) -> dict[str, np.ndarray]:
    t: list[float] = []
    names: list[str] | None = None
    rows: list[list[np.ndarray]] = []
    for k, meas in enumerate(sensor.findall("Data/Measurement")):
        t.append(_floats(path, meas.get("timestep"), 1, f"marker measurement {k}: timestep")[0])
        entries = meas.findall("MarkerPosition")
        frame = {str(e.get("name")): _floats(path, e.text, 3, f"marker {e.get('name')}") for e in entries}
        names = list(frame) if names is None else names
        if list(frame) != names:
            raise MotionFormatError(path, f"t={t[-1]:g}: marker set differs from the first frame")
        rows.append([frame[n] for n in names])
    if not rows or names is None:
        return {}
    ta = _check_times(path, np.asarray(t), "MoCapMarker sensor")
    data = _align(ta, np.asarray(rows).reshape(len(rows), -1) * MM, times)
    return {n: data[:, 3 * i : 3 * i + 3] for i, n in enumerate(names)}


def _floats(path: Path, text: str | None, n: int, what: str) -> np.ndarray:
    if text is None:
        raise MotionFormatError(path, f"{what} is missing")
    try:
        values = np.array(text.split(), dtype=float)
    except ValueError:
        raise MotionFormatError(path, f"{what} is not a list of numbers") from None
    if len(values) != n:
        raise MotionFormatError(path, f"{what} has {len(values)} values, expected {n}")
    if not np.all(np.isfinite(values)):
        raise MotionFormatError(path, f"{what} contains non-finite values")
    return values


def _check_times(path: Path, t: np.ndarray, what: str) -> np.ndarray:
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        k = bad[0] + 1
        raise MotionFormatError(
            path, f"{what}: timesteps not increasing at frame {k} ({t[k - 1]:g} -> {t[k]:g})"
        )
    return t


def _lerp(t: np.ndarray, y: np.ndarray, times: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(times, t, c) for c in y.T], axis=1)


def _align(t: np.ndarray, y: np.ndarray, times: np.ndarray, interpolate=_lerp) -> np.ndarray:
    """Values of ``y(t)`` on ``times``: identical time bases pass through, others interpolate."""
    if len(t) == len(times) and np.allclose(t, times, atol=1e-6):
        return y
    if len(t) == 1:
        return np.repeat(y, len(times), axis=0)
    return interpolate(t, y, times)


def _rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    # MMM RootRotation (roll, pitch, yaw): R = Rz(yaw) Ry(pitch) Rx(roll) = extrinsic x-y-z.
    return Rotation.from_euler("xyz", rpy).as_matrix()


# --- writing -------------------------------------------------------------------------------------


def _num(value: float) -> str:
    """The shortest text that reads back as the same float (exact round trips at any time base)."""
    return repr(float(value))


def _fmt(values: Iterable[float]) -> str:
    return " ".join(_num(v) for v in values)


def _pose_sensor(times, position, rotation) -> list[str]:
    rpy = Rotation.from_matrix(rotation).as_euler("xyz")
    out = ['\t\t\t<Sensor type="ModelPose" version="1.0">', "\t\t\t\t<Configuration/>", "\t\t\t\t<Data>"]
    for t, p, r in zip(times, position / MM, rpy):
        out.append(f'\t\t\t\t\t<Measurement timestep="{_num(t)}">')
        out.append(f"\t\t\t\t\t\t<RootPosition>{_fmt(p)}</RootPosition>")
        out.append(f"\t\t\t\t\t\t<RootRotation>{_fmt(r)}</RootRotation>")
        out.append("\t\t\t\t\t</Measurement>")
    return out + ["\t\t\t\t</Data>", "\t\t\t</Sensor>"]


def _marker_sensor(times, markers) -> list[str]:
    if not markers:
        return []
    out = ['\t\t\t<Sensor type="MoCapMarker" version="1.0">', "\t\t\t\t<Configuration/>", "\t\t\t\t<Data>"]
    for k, t in enumerate(times):
        out.append(f'\t\t\t\t\t<Measurement timestep="{_num(t)}">')
        out += [
            f'\t\t\t\t\t\t<MarkerPosition name="{n}">{_fmt(p[k] / MM)}</MarkerPosition>'
            for n, p in markers.items()
        ]
        out.append("\t\t\t\t\t</Measurement>")
    return out + ["\t\t\t\t</Data>", "\t\t\t</Sensor>"]


def _atomic_write(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
