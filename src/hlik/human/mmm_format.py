"""Reading and writing MMM motion files (kinematics.md §1.3 legacy format, §1.4 MMM 2.0).

Files are parsed with defusedxml (no entity expansion, no external entities). Lengths in the
files are millimetres and are converted to metres here; nothing else in hlik sees millimetres.

Reading checks that a recording is plausible, not only well formed. What would make the subject's
motion wrong is refused with a :class:`~hlik.util.errors.MotionFormatError` that names the file, the
motion (``subject 'name'`` or ``object 'name'``), the sensor and the problem: lengths or angles in
another unit, a frame rate outside :data:`~hlik.human.motion.RATE_RANGE`, streams that share fewer
than two frames. What hlik can work around is read, and said in one line in
:attr:`HumanMotion.notes <hlik.human.motion.HumanMotion>`:

- streams that disagree in time: the span they share is used, nothing is held past a stream's end;
- gaps in the sampling longer than 2.5 frame periods;
- arm poses outside the MMM model's ranges;
- markers not seen: (0, 0, 0), the Vicon convention for a lost marker, and absent entries are NaN;
- any fault in a scene object: the object is left out (retargeting never uses objects, so a broken
  object must not cost the take).

Writing is exact: reading a written file gives back the same float64 times, joint angles, root
positions and markers; root rotations pass through roll-pitch-yaw and come back to ~1e-15.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path
from xml.etree.ElementTree import Element, ParseError
from xml.sax.saxutils import quoteattr

import defusedxml.ElementTree as DET
import numpy as np
from defusedxml import DefusedXmlException
from scipy.spatial.transform import Rotation

from hlik.human.motion import ARM_JOINTS, ARM_RANGES, RATE_RANGE, HumanMotion, ObjectMotion, _slerp
from hlik.util.atomic import atomic_path
from hlik.util.errors import MotionFormatError

MM = 1e-3
VERSIONS = ("1.0", "2.0")  # MMM versions read; legacy files carry none

_LARGEST = 1e12  # largest magnitude of any number in a file (file units); keeps arithmetic finite
_SAME = 1e-6  # s: timesteps closer than this are the same instant
_GAP = 2.5  # frame periods: a longer step misses at least two frames
_RANGE_SLACK = 0.1  # rad beyond an MMM arm range before a pose is reported as outside it
_DEGREES = 720.0  # |angle| of a body joint above 2π up to this reads as degrees; beyond, as nonsense
_ROOT = 0.53  # root (hip-joint) height / body height standing (Winter: 0.039 + 0.246 + 0.245)
_BODY = 0.9  # largest extent of a full body marker set / body height, as in the KIT takes
_MIN_BODY_MARKERS = 10  # fewer markers may sit on one limb: too few to judge the unit from


@dataclass(frozen=True, eq=False)
class _Stream:
    """One sensor's samples: times (n,) s and values (n, k); ``label`` names it in messages."""

    label: str
    times: np.ndarray
    values: np.ndarray


def read_mmm(path: Path) -> HumanMotion:
    """Parse an MMM file; the human is the motion whose kinematics carries the MMM arm joints.

    Raises:
        hlik.util.errors.MotionFormatError: the file is missing, malformed, or its subject's motion is
            implausible (the message names the motion, the sensor and what was expected).
    """
    root = _parse(path)
    if root.tag != "MMM":
        raise MotionFormatError(path, f"root element is <{root.tag}>, expected <MMM>")
    version = root.get("version")
    if version is not None and version.strip() not in VERSIONS:
        raise MotionFormatError(
            path, f"MMM version {version!r} is not supported; hlik reads MMM 2.0 and the legacy format"
        )
    motions = root.findall("Motion")
    if not motions:
        raise MotionFormatError(path, "no <Motion> element")
    reader = _Reader(path)
    legacy = any(m.find("MotionFrames") is not None for m in motions)
    return reader.legacy(motions) if legacy else reader.v2(motions)


def write_mmm(motion: HumanMotion, path: str | Path) -> None:
    """Write ``motion`` as an MMM 2.0 file, atomically (temporary file, then rename).

    Every number is written so that reading gives the same float64 back. Unseen markers are written
    as (0, 0, 0); an object's pose only where it is known (an object never known is left out).
    """
    path = Path(path)
    lines = [f'<MMM version="2.0" name={quoteattr(motion.name)}>']
    for obj in motion.objects.values():
        known = np.all(np.isfinite(obj.position), axis=1) & np.all(np.isfinite(obj.rotation), axis=(1, 2))
        if not known.any():
            continue
        lines.append(f'\t<Motion name={quoteattr(obj.name)} type="object" synchronized="true">')
        lines.append("\t\t<Sensors>")
        lines += _pose_sensor(motion.times[known], obj.position[known], obj.rotation[known])
        lines += _marker_sensor(motion.times, obj.markers)
        lines.append("\t\t</Sensors>\n\t</Motion>")
    lines.append(f'\t<Motion name={quoteattr(motion.name)} type="object" synchronized="true">')
    lines.append('\t\t<Model path="mmm.xml">\n\t\t\t<ModelProcessorConfig type="Winter">')
    lines.append(f"\t\t\t\t<Height>{_num(motion.height)}</Height>")
    if motion.mass is not None:
        lines.append(f"\t\t\t\t<Mass>{_num(motion.mass)}</Mass>")
    lines.append("\t\t\t</ModelProcessorConfig>\n\t\t</Model>\n\t\t<Sensors>")
    lines += _pose_sensor(motion.times, motion.root_position, motion.root_rotation)
    lines.append('\t\t\t<Sensor type="Kinematic" version="1.0">\n\t\t\t\t<Configuration>')
    lines += [f"\t\t\t\t\t<Joint name={quoteattr(n)}/>" for n in motion.joint_names]
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
    except UnicodeDecodeError:
        raise MotionFormatError(path, "not text in the encoding its XML declaration names") from None
    except OSError as e:
        raise MotionFormatError(path, f"cannot read: {e.strerror}") from None


class _Reader:
    """Reads one file; collects the notes (one line each, naming the file) on the way."""

    def __init__(self, path: Path):
        self.path = path
        self.notes: list[str] = []

    def note(self, text: str) -> None:
        self.notes.append(f"{self.path}: {text}")

    def fail(self, problem: str) -> MotionFormatError:
        return MotionFormatError(self.path, problem)

    # --- the two formats --------------------------------------------------------------------------

    def scene_objects(self, motions: list[tuple[str, Element]], times: np.ndarray) -> dict:
        """The readable objects among the MMM 2.0 ``motions`` (name, element) at ``times``; a
        second motion of one name, or one that cannot be read, is left out with a note."""
        objects: dict = {}
        for key, m in motions:
            if key in objects:
                self.note(f"object {key!r}: a second motion of that name, left out")
                continue
            try:
                obj = self.scene_object(key, m, times)
            except MotionFormatError as e:
                self.note(f"{e.problem}; object left out")
                continue
            if obj is not None:
                objects[key] = obj
        return objects

    def v2(self, motions: list[Element]) -> HumanMotion:
        human, others = None, []
        for k, m in enumerate(motions):
            if not _has_arm_joints(m):
                others.append((m.get("name") or f"motion {k + 1}", m))
            elif human is None:
                human = m
            else:
                self.note(f"subject {m.get('name')!r}: a second motion with MMM arm joints, left out")
        if human is None:
            raise self.fail("no motion with MMM arm joints (e.g. LSx_joint) found")
        name = human.get("name") or self.path.stem
        who = f"subject {name!r}"
        sensors = human.findall("Sensors/Sensor")
        pose_sensor = next((s for s in sensors if s.get("type") == "ModelPose"), None)
        if pose_sensor is None:
            raise self.fail(f"{who}: no ModelPose sensor")
        pose = self.pose_stream(pose_sensor, who)
        kinematic = [s for s in sensors if s.get("type") == "Kinematic"]
        names: list[str] = []
        sources: list[str] = []
        streams = []
        for k, s in enumerate(kinematic):
            joints = [j.get("name") or "" for j in s.findall("Configuration/Joint")]
            label = _kinematic_label(s, k, len(kinematic), joints)
            if "" in joints:
                raise self.fail(f"{who}: {label}: a <Joint> has no name")
            streams.append(self.stream(s, who, label, [("JointPosition", len(joints), False)]))
            names += joints
            sources += [label] * len(joints)
        times = self.common_times(who, [pose, *streams])
        frames = np.isin(pose.times, times)
        joints_q = np.concatenate([_align(s.times, s.values, times) for s in streams], axis=1)
        markers: dict[str, np.ndarray] = {}
        for s in (s for s in sensors if s.get("type") == "MoCapMarker"):
            markers.update(self.markers(s, who, times))
        objects = self.scene_objects(others, times)
        height, mass = self.subject(human.find("Model/ModelProcessorConfig"), who)
        return self.finish(
            who,
            name,
            times,
            names,
            sources,
            joints_q,
            pose.values[frames, :3],
            _rpy_to_matrix(pose.values[frames, 3:]),
            height,
            mass,
            markers,
            objects,
        )

    def legacy(self, motions: list[Element]) -> HumanMotion:
        human = next((m for m in motions if m.find("JointOrder") is not None), None)
        if human is None:
            raise self.fail("legacy motion without <JointOrder>")
        name = human.get("name") or self.path.stem
        who = f"subject {name!r}"
        names = [j.get("name") or "" for j in human.findall("JointOrder/Joint")]
        if "" in names:
            raise self.fail(f"{who}: JointOrder: a <Joint> has no name")
        frames = human.findall("MotionFrames/MotionFrame")
        if not frames:
            raise self.fail(f"{who}: MotionFrames has no <MotionFrame>")

        def at(tag: str) -> Callable[[int], str]:
            return lambda k: f"{who}: MotionFrame {k}: {tag}"

        def column(tag: str, n: int, mm: bool = False) -> np.ndarray:
            return self.table([f.findtext(tag) for f in frames], n, at(tag), mm)

        times = column("Timestep", 1)[:, 0]
        pos = column("RootPosition", 3, mm=True)
        rpy = column("RootRotation", 3)
        q = column("JointPosition", len(names))
        times_a = self.increasing(times, who, "MotionFrames")
        height, mass = self.subject(human.find("ModelProcessorConfig"), who)
        return self.finish(
            who,
            name,
            times_a,
            names,
            ["MotionFrames"] * len(names),
            q,
            pos,
            _rpy_to_matrix(rpy),
            height,
            mass,
            {},
            {},
        )

    # --- sensors ------------------------------------------------------------------------------------

    def pose_stream(self, sensor: Element, who: str) -> _Stream:
        """ModelPose: values (n, 6) = root position (m), roll-pitch-yaw (rad)."""
        fields = [("RootPosition", 3, True), ("RootRotation", 3, False)]
        return self.stream(sensor, who, "ModelPose sensor", fields)

    def stream(self, sensor: Element, who: str, label: str, fields: list[tuple[str, int, bool]]) -> _Stream:
        """The measurements of a sensor: per field (tag, count, in millimetres), side by side."""
        measurements = sensor.findall("Data/Measurement")
        if not measurements:
            raise self.fail(f"{who}: {label} has no measurements")
        times = self.timesteps(measurements, who, label)

        def where(tag: str) -> Callable[[int], str]:
            return lambda k: f"{who}: {label}: t={times[k]:.10g} s: {tag}"

        columns = [
            self.table([m.findtext(tag) for m in measurements], n, where(tag), mm) for tag, n, mm in fields
        ]
        return _Stream(label, self.increasing(times, who, label), np.concatenate(columns, axis=1))

    def timesteps(self, measurements: list[Element], who: str, label: str) -> np.ndarray:
        texts = [m.get("timestep") for m in measurements]
        return self.table(texts, 1, lambda k: f"{who}: {label}: measurement {k}: timestep")[:, 0]

    def markers(self, sensor: Element, who: str, times: np.ndarray) -> dict[str, np.ndarray]:
        """Marker name -> (T, 3) positions on ``times``, m; NaN where the marker was not seen."""
        label = "MoCapMarker sensor"
        measurements = sensor.findall("Data/Measurement")
        t = self.timesteps(measurements, who, label)
        slots: dict[str, int] = {}
        where, texts = [], []  # (frame, marker slot) and text of every entry
        for k, meas in enumerate(measurements):
            in_frame = set()
            for e in meas.findall("MarkerPosition"):
                name = e.get("name")
                if not name:
                    raise self.fail(f"{who}: {label}: t={t[k]:.10g} s: a <MarkerPosition> has no name")
                if name in in_frame:
                    raise self.fail(f"{who}: {label}: t={t[k]:.10g} s: marker {name!r} is listed twice")
                in_frame.add(name)
                where.append((k, slots.setdefault(name, len(slots))))
                texts.append(e.text)
        if not slots:
            return {}
        names = list(slots)
        rows = self.table(
            texts,
            3,
            lambda i: f"{who}: {label}: t={t[where[i][0]]:.10g} s: marker {names[where[i][1]]!r}",
            mm=True,
        )
        values = np.full((len(measurements), len(names), 3), np.nan)
        frame, slot = np.array(where).T
        lost = np.all(rows == 0.0, axis=1)  # (0, 0, 0): the marker was lost
        values[frame[~lost], slot[~lost]] = rows[~lost]
        ta = self.increasing(t, who, label)
        unseen = np.isnan(values[:, :, 0])
        if unseen.any():
            counts = unseen.sum(axis=0)
            worst = int(np.argmax(counts))
            self.note(
                f"{who}: {label}: {np.count_nonzero(counts)} of {len(names)} markers not seen in some "
                f"samples ((0, 0, 0) or absent; {unseen.sum()} samples in all, most {names[worst]!r} in "
                f"{counts[worst]} of {len(ta)}): read as unknown"
            )
        self.span_note(who, label, ta, times, "markers unknown outside")
        data = _align_known(ta, values.reshape(len(ta), -1), times)
        return {n: data[:, 3 * i : 3 * i + 3] for i, n in enumerate(names)}

    def scene_object(self, key: str, motion: Element, times: np.ndarray) -> ObjectMotion | None:
        """An object on the subject's times, NaN outside its own span; None (with a note) if it has
        no pose to show."""
        who = f"object {key!r}"
        sensors = motion.findall("Sensors/Sensor")
        if not sensors:
            self.note(f"{who}: no sensors; object left out")
            return None
        pose_sensor = next((s for s in sensors if s.get("type") == "ModelPose"), None)
        if pose_sensor is None:
            kinds = ", ".join(sorted({str(s.get("type")) for s in sensors}))
            self.note(f"{who}: no ModelPose sensor (only {kinds}); object left out")
            return None
        pose = self.pose_stream(pose_sensor, who)
        position = _align_known(pose.times, pose.values[:, :3], times)
        rotation = _align_rotations(pose.times, _rpy_to_matrix(pose.values[:, 3:]), times)
        if not np.isfinite(position[:, 0]).any():
            self.note(
                f"{who}: ModelPose sensor runs {_span(pose.times)}, outside the subject's "
                f"{_span(times)}; object left out"
            )
            return None
        if len(pose.times) > 1:
            self.span_note(who, "ModelPose sensor", pose.times, times, "pose unknown outside")
        markers: dict[str, np.ndarray] = {}
        for s in (s for s in sensors if s.get("type") == "MoCapMarker"):
            markers.update(self.markers(s, who, times))
        return ObjectMotion(name=key, position=position, rotation=rotation, markers=markers)

    def common_times(self, who: str, streams: list[_Stream]) -> np.ndarray:
        """The frames of the first stream (ModelPose) within the span every stream covers."""
        start = max(s.times[0] for s in streams)
        stop = min(s.times[-1] for s in streams)
        parts = []
        first, late = min(streams, key=lambda s: s.times[0]), max(streams, key=lambda s: s.times[0])
        if late.times[0] > first.times[0] + _SAME:
            parts.append(
                f"{late.label} starts at {_sec(late.times[0])} s, {first.label} at {_sec(first.times[0])} s"
            )
        last, early = max(streams, key=lambda s: s.times[-1]), min(streams, key=lambda s: s.times[-1])
        if early.times[-1] < last.times[-1] - _SAME:
            parts.append(
                f"{early.label} ends at {_sec(early.times[-1])} s, {last.label} at {_sec(last.times[-1])} s"
            )
        t = streams[0].times
        t = t[(t >= start - _SAME) & (t <= stop + _SAME)]
        if len(t) < 2:
            raise self.fail(
                f"{who}: {'; '.join(parts)}: the streams share {len(t)} frame(s), at least 2 needed"
            )
        if parts:
            self.note(f"{who}: {'; '.join(parts)}; using {_sec(t[0])}-{_sec(t[-1])} s")
        return t

    def span_note(self, who: str, label: str, t: np.ndarray, times: np.ndarray, consequence: str) -> None:
        if t[0] > times[0] + _SAME or t[-1] < times[-1] - _SAME:
            self.note(f"{who}: {label} runs {_span(t)}, the motion {_span(times)}; {consequence}")

    # --- values -----------------------------------------------------------------------------------

    def numbers(self, text: str | None, n: int, what: str) -> np.ndarray:
        """``n`` finite numbers from ``text``."""
        return self.table([text], n, lambda k: what)[0]

    def table(
        self, texts: list[str | None], n: int, what: Callable[[int], str], mm: bool = False
    ) -> np.ndarray:
        """(len(texts), n) finite numbers, ``n`` from each text, parsed together (a KIT take has
        10^4 of them); ``what(k)`` names text ``k`` in messages. Millimetres become metres exactly
        (see :func:`_milli`)."""
        tokens: list[str] = []
        for k, text in enumerate(texts):
            if text is None:
                raise self.fail(f"{what(k)} is missing")
            row = text.split()
            if len(row) != n:
                raise self.fail(f"{what(k)} has {len(row)} values, expected {n}")
            tokens += row
        try:
            values = np.array(tokens, dtype=float).reshape(len(texts), n)
        except ValueError:
            k = next(k for k, text in enumerate(texts) if not _all_numbers(str(text)))
            raise self.fail(f"{what(k)} is not a list of numbers") from None
        finite = np.isfinite(values)
        if not finite.all():
            raise self.fail(f"{what(int(np.argmin(finite.all(axis=1))))} contains non-finite values")
        size = np.abs(values)
        if size.max(initial=0.0) > _LARGEST:
            at, i = np.unravel_index(np.argmax(size), size.shape)
            raise self.fail(
                f"{what(int(at))}: {values[at, i]:g} is not a plausible value (beyond ±{_LARGEST:g})"
            )
        if mm:
            return np.array([_milli(token) for token in tokens], dtype=float).reshape(len(texts), n)
        return values

    def increasing(self, t: np.ndarray, who: str, label: str) -> np.ndarray:
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            k = bad[0] + 1
            raise self.fail(
                f"{who}: {label}: timesteps not increasing at frame {k} ({t[k - 1]:.10g} -> {t[k]:.10g})"
            )
        return t

    def subject(self, cfg: Element | None, who: str) -> tuple[float, float | None]:
        if cfg is None or cfg.findtext("Height") is None:
            raise self.fail(f"{who}: no <Height> in ModelProcessorConfig")
        height = float(self.numbers(cfg.findtext("Height"), 1, f"{who}: ModelProcessorConfig: Height")[0])
        if not 0.5 < height < 2.5:
            unit = next(
                (
                    f" (looks like {u})"
                    for u, f in (("centimetres", 1e2), ("millimetres", 1e3))
                    if 0.5 < height / f < 2.5
                ),
                "",
            )
            raise self.fail(f"{who}: subject height {height:g} m is implausible{unit}; expected 0.5-2.5 m")
        text = cfg.findtext("Mass")
        if text is None:
            return height, None
        mass = float(self.numbers(text, 1, f"{who}: ModelProcessorConfig: Mass")[0])
        if not 10.0 < mass < 500.0:
            self.note(f"{who}: ModelProcessorConfig: mass {mass:g} kg is implausible; ignored")
            return height, None
        return height, mass

    # --- the subject as a whole ---------------------------------------------------------------------

    def finish(
        self,
        who: str,
        name: str,
        times: np.ndarray,
        names: list[str],
        sources: list[str],
        joints: np.ndarray,
        root_pos: np.ndarray,
        root_rot: np.ndarray,
        height: float,
        mass: float | None,
        markers: dict[str, np.ndarray],
        objects: dict[str, ObjectMotion],
    ) -> HumanMotion:
        missing = [j for side in ARM_JOINTS.values() for j in side if j not in names]
        if missing:
            raise self.fail(f"{who}: missing arm joint(s): {', '.join(missing)}")
        twice = next((n for i, n in enumerate(names) if n in names[:i]), None)
        if twice is not None:
            raise self.fail(f"{who}: joint {twice!r} is listed twice")
        if len(times) < 2:
            raise self.fail(f"{who}: needs at least 2 frames, found {len(times)}")
        clock = "MotionFrames" if "MotionFrames" in sources else "ModelPose sensor"  # whose frames these are
        period = float(np.median(np.diff(times)))
        self.check_rate(who, clock, period)
        joints = self.check_angles(who, times, names, sources, joints)
        self.check_lengths(who, clock, height, root_pos, markers)
        self.note_gaps(who, clock, times, period)
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
            source=self.path,
            notes=tuple(self.notes),
        )

    def check_rate(self, who: str, label: str, period: float) -> None:
        low, high = RATE_RANGE
        rate = 1.0 / period
        if not low <= rate <= high:
            side = f"above {high:g} Hz: are they seconds?" if rate > high else f"below {low:g} Hz"
            raise self.fail(f"{who}: {label}: timesteps are {period:.3g} s apart ({rate:.3g} Hz), {side}")

    def check_angles(
        self, who: str, times: np.ndarray, names: list[str], sources: list[str], joints: np.ndarray
    ) -> np.ndarray:
        """Refuse degrees and nonsense; note arm poses outside the MMM ranges; wrap finger angles
        (some KIT takes record them unwrapped, up to -9.3 rad)."""
        size = np.abs(joints)
        k, j = np.unravel_index(np.argmax(size), size.shape)
        if size[k, j] > _DEGREES:
            raise self.fail(
                f"{who}: {sources[j]}: {names[j]} is {joints[k, j]:g} at {_sec(times[k])} s: "
                "not a joint angle"
            )
        fingers = np.array(["Finger" in n for n in names])
        body = np.where(fingers, 0.0, size)
        k, j = np.unravel_index(np.argmax(body), body.shape)
        if body[k, j] > 2 * np.pi:
            raise self.fail(
                f"{who}: {sources[j]}: joint angles look like degrees: {names[j]} reaches {joints[k, j]:.4g} "
                f"at {_sec(times[k])} s (MMM angles are radians, within ±3.4)"
            )
        for name, (low, high) in ARM_RANGES.items():
            col = names.index(name)
            q = joints[:, col]
            beyond = np.maximum(low - q, q - high)
            outside = beyond > _RANGE_SLACK
            if outside.any():
                worst = int(np.argmax(beyond))
                self.note(
                    f"{who}: {sources[col]}: {name} outside the MMM range {low:.2f}..{high:.2f} rad in "
                    f"{np.count_nonzero(outside)} of {len(q)} frames (worst {q[worst]:.2f} rad at "
                    f"{_sec(times[worst])} s)"
                )
        joints = joints.copy()
        wrap = fingers & (size > np.pi)  # only what needs it: wrapped angles read back unchanged
        joints[wrap] = np.arctan2(np.sin(joints[wrap]), np.cos(joints[wrap]))
        return joints

    def check_lengths(
        self, who: str, clock: str, height: float, root_pos: np.ndarray, markers: dict[str, np.ndarray]
    ) -> None:
        """Refuse root and marker positions that are not millimetres, judged by the subject's height."""
        z = root_pos[:, 2]
        top, typical = float(np.max(z)), float(np.median(z))
        expected = _ROOT * height
        if top < 0.1 * height or typical > 3.0 * height:
            raise self.fail(
                f"{who}: {clock}: the root (pelvis) is {_mm(typical)} above the floor (at most "
                f"{_mm(top)}) for a {height:.2f} m subject, expected about {_mm(expected)}: "
                f"RootPosition looks like {_unit(typical / expected)}; MMM uses millimetres"
            )
        if len(markers) < _MIN_BODY_MARKERS:
            return
        p = np.stack(list(markers.values()), axis=1)  # (T, M, 3)
        seen = np.all(np.isfinite(p), axis=2)
        frames = np.count_nonzero(seen, axis=1) >= _MIN_BODY_MARKERS
        if not frames.any():
            return
        p, seen = p[frames], seen[frames][..., None]
        extent = np.max(
            np.max(np.where(seen, p, -np.inf), axis=1) - np.min(np.where(seen, p, np.inf), axis=1), axis=1
        )
        typical, expected = float(np.median(extent)), _BODY * height
        if not 0.3 * height < typical < 3.0 * height:
            raise self.fail(
                f"{who}: MoCapMarker sensor: the body markers span {_mm(typical)} for a {height:.2f} m "
                f"subject, expected about {_mm(expected)}: MarkerPosition looks like "
                f"{_unit(typical / expected)}; MMM uses millimetres"
            )

    def note_gaps(self, who: str, label: str, times: np.ndarray, period: float) -> None:
        steps = np.diff(times)
        gaps = steps > _GAP * period
        if gaps.any():
            k = int(np.argmax(steps))
            self.note(
                f"{who}: {label}: irregular sampling: {np.count_nonzero(gaps)} gap(s) longer than {_GAP:g} "
                f"frame periods ({_GAP * period:.3g} s), the longest {steps[k]:.3g} s after "
                f"{_sec(times[k])} s; the rate {1.0 / period:.4g} Hz is the median"
            )


def _has_arm_joints(motion: Element) -> bool:
    names = {
        j.get("name")
        for s in motion.findall("Sensors/Sensor")
        if s.get("type") == "Kinematic"
        for j in s.findall("Configuration/Joint")
    }
    return ARM_JOINTS["left"][0] in names or ARM_JOINTS["right"][0] in names


def _all_numbers(text: str) -> bool:
    try:
        np.array(text.split(), dtype=float)
    except ValueError:
        return False
    return True


def _kinematic_label(sensor: Element, k: int, count: int, joints: list[str]) -> str:
    if sensor.get("name"):
        return f"Kinematic sensor {sensor.get('name')!r}"
    if count == 1:
        return "Kinematic sensor"
    span = f"{joints[0]}..{joints[-1]}" if joints else "no joints"
    return f"Kinematic sensor {k + 1} ({len(joints)} joints {span})"


def _samples(t: np.ndarray, times: np.ndarray) -> np.ndarray | None:
    """Indices of the samples of ``t`` at ``times``, if every time is a sample time; else None.
    Taking those samples keeps the recorded floats (interpolating at a knot may move the last bit)."""
    i = np.minimum(np.searchsorted(t, times - _SAME), len(t) - 1)
    return i if np.all(np.abs(t[i] - times) <= _SAME) else None


def _align(t: np.ndarray, y: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Values of ``y(t)`` (n, k) on ``times`` within ``t``'s span: samples where the instants are
    sample instants, else linear interpolation."""
    i = _samples(t, times)
    if i is not None:
        return y[i]
    return np.stack([np.interp(times, t, c) for c in y.T], axis=1)


def _align_known(t: np.ndarray, y: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Values of ``y(t)`` (n, k), NaN rows unknown, on ``times``: linear between consecutive known
    samples, NaN outside the span of ``t`` and next to unknown samples. A single sample is a
    static pose and holds."""
    if len(t) == 1:
        return np.repeat(y, len(times), axis=0)
    i = _samples(t, times)
    if i is not None:
        return y[i]
    known = np.all(np.isfinite(y), axis=1)
    out = np.full((len(times), y.shape[1]), np.nan)
    if not known.any():
        return out
    i = np.clip(np.searchsorted(t, times + _SAME, side="right") - 1, 0, len(t) - 1)  # t[i] <= time
    j = np.minimum(i + 1, len(t) - 1)
    on_sample = np.abs(times - t[i]) <= _SAME
    valid = (times >= t[0] - _SAME) & known[i] & (on_sample | ((i < len(t) - 1) & known[j]))
    for c in range(y.shape[1]):
        out[valid, c] = np.interp(times[valid], t[known], y[known, c])
    return out


def _align_rotations(t: np.ndarray, rot: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Rotations (n, 3, 3) on ``times`` by slerp within the span of ``t``, NaN outside; a single
    sample holds."""
    if len(t) == 1:
        return np.repeat(rot, len(times), axis=0)
    out = np.full((len(times), 3, 3), np.nan)
    inside = (times >= t[0] - _SAME) & (times <= t[-1] + _SAME)
    i = _samples(t, times[inside])
    if i is not None:
        out[inside] = rot[i]
    elif inside.any():
        out[inside] = _slerp(t, rot, times[inside])
    return out


def _rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    # MMM RootRotation (roll, pitch, yaw): R = Rz(yaw) Ry(pitch) Rx(roll) = extrinsic x-y-z.
    return Rotation.from_euler("xyz", rpy).as_matrix()


def _milli(token: str) -> str:
    """The text of a millimetre value as metres: '973.1' -> '973.1e-3'. Moving the decimal point in
    the text gives the float nearest the exact value; multiplying by 1e-3 would round twice."""
    mantissa, _, exponent = token.lower().partition("e")
    return f"{mantissa}e{int(exponent or 0) - 3}"


def _sec(t: float) -> str:
    """A time in seconds, with as many decimals (2 to 6) as it needs."""
    digits = next((d for d in (2, 3, 4) if abs(round(t, d) - t) <= 1e-9 * max(1.0, abs(t))), 6)
    return f"{t:.{digits}f}"


def _span(t: np.ndarray) -> str:
    return f"{_sec(t[0])}-{_sec(t[-1])} s"


def _mm(metres: float) -> str:
    return f"{metres * 1e3:.3g} mm"


def _unit(ratio: float) -> str:
    """What a length unit mistake looks like, from found / expected."""
    if not ratio > 0.0:
        return "a wrong unit or origin"
    factor = 10.0 ** round(float(np.log10(ratio)))
    names = {1e-3: "metres (values 1000x too small)", 1e-2: "decimetres (100x too small)"}
    names |= {1e-1: "centimetres (10x too small)", 1e3: "micrometres (1000x too large)"}
    return names.get(factor, f"a wrong unit ({ratio:.2g}x the expected size)")


# --- writing -------------------------------------------------------------------------------------


def _num(value: float) -> str:
    """The shortest text that reads back as the same float (exact round trips at any time base)."""
    return repr(float(value))


def _fmt(values: Iterable[float]) -> str:
    return " ".join(_num(v) for v in values)


def _mm_text(metres: float) -> str:
    """Millimetre text that :func:`_milli` reads back as exactly ``metres``: the shortest decimal of
    the float with its point moved three places."""
    mm = Decimal(repr(float(metres))).scaleb(3)
    return format(mm, "f") if -7 < mm.adjusted() < 16 else str(mm)


def _mm_fmt(values: Iterable[float]) -> str:
    return " ".join(_mm_text(v) for v in values)


def _pose_sensor(times, position, rotation) -> list[str]:
    rpy = Rotation.from_matrix(rotation).as_euler("xyz")
    out = ['\t\t\t<Sensor type="ModelPose" version="1.0">', "\t\t\t\t<Configuration/>", "\t\t\t\t<Data>"]
    for t, p, r in zip(times, position, rpy):
        out.append(f'\t\t\t\t\t<Measurement timestep="{_num(t)}">')
        out.append(f"\t\t\t\t\t\t<RootPosition>{_mm_fmt(p)}</RootPosition>")
        out.append(f"\t\t\t\t\t\t<RootRotation>{_fmt(r)}</RootRotation>")
        out.append("\t\t\t\t\t</Measurement>")
    return out + ["\t\t\t\t</Data>", "\t\t\t</Sensor>"]


def _marker_sensor(times, markers) -> list[str]:
    if not markers:
        return []
    out = ['\t\t\t<Sensor type="MoCapMarker" version="1.0">', "\t\t\t\t<Configuration/>", "\t\t\t\t<Data>"]
    names = {n: quoteattr(n) for n in markers}
    for k, t in enumerate(times):
        out.append(f'\t\t\t\t\t<Measurement timestep="{_num(t)}">')
        out += [
            f"\t\t\t\t\t\t<MarkerPosition name={names[n]}>"
            f"{'0 0 0' if np.isnan(p[k]).any() else _mm_fmt(p[k])}</MarkerPosition>"
            for n, p in markers.items()
        ]
        out.append("\t\t\t\t\t</Measurement>")
    return out + ["\t\t\t\t</Data>", "\t\t\t</Sensor>"]


def _atomic_write(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
