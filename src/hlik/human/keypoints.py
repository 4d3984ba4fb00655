"""Arm keypoints from other motion sources: joint positions of a pose estimator or a body-model fit,
and BVH skeletons. :mod:`hlik.human.fit` turns them into MMM joint angles.

A keypoint file is described by a small TOML (the file users pass to ``hlik run``)::

    data = "trial1.txt"       # .csv/.txt (T, columns), .npy/.npz (T, J, 3), or .bvh; relative to the TOML
    array = "joint_pos"       # .npz only: which array
    names = "joint_names"     # .npz only, optional: an array of joint names, so [keypoints] may name them
    rate = 30.0               # Hz; an .npz may store it (fps, rate, framerate, mocap_framerate)
    units = "m"               # m, cm, mm or in; checked against the arm lengths either way
    up = "z"                  # the vertical axis: x, y, z, -x, -y, -z; detected if left out
    floor = 0.0               # height of the floor along ``up``, file units; "auto" (the default) keeps a
                              # plausible floor at 0 and otherwise stands the subject on one
    lowpass = 6.0             # Hz, optional: a zero-phase Butterworth filter for noisy estimates
    [keypoints]               # name -> first column of x, y, z (tables), joint index or name (arrays)
    left_shoulder = 12
    ...

A BVH file is read as joint positions (its joints' world positions by forward kinematics, bvhio)
and needs no description when its joints have the usual names (``LeftArm``, ``LeftForeArm``,
``LeftHand``, ... as in CMU, LAFAN1, Mixamo or Xsens exports; :data:`BVH_NAMES`); otherwise a
description names them (``data = "take.bvh"``, ``[keypoints] left_shoulder = "l_upperarm"``).

Required: ``{left,right}_{shoulder,elbow,wrist}``. Optional: ``{left,right}_{index,pinky}``, the
knuckles of the index and little finger, which give the hand's orientation (the TCP frame of
``robots/README.md``: z from the wrist to the knuckles, x the palm normal).
"""

from __future__ import annotations

import math
import re
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hlik.human import cleanup
from hlik.human.motion import MAX_FRAMES, RATE_RANGE
from hlik.util.arrayfile import array_shapes
from hlik.util.errors import HlikError, MotionFormatError
from hlik.util.tomlfile import read_toml, unknown_key

SIDES = ("left", "right")
ARM_POINTS = ("shoulder", "elbow", "wrist")
HAND_POINTS = ("index", "pinky")
# the keys of a keypoint description (README "Your robot, your motion")
KEYS = ("data", "keypoints", "array", "names", "rate", "lowpass", "floor", "units", "up")
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
# Upper arm plus forearm of adults, m: a sum outside it means the units are not what they were said
# to be (about 0.45-0.65 m for heights of 1.45-2.0 m, with room for children and fitting noise).
ARM_LENGTH = (0.25, 1.0)
AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True, eq=False)
class Keypoints:
    """Arm keypoints over time, in metres, in a z-up world; arm index 0 = left, 1 = right.

    Attributes:
        name: Motion name (the file's stem).
        times: (T,) strictly increasing timestamps, s.
        shoulder, elbow, wrist: (T, 2, 3) joint centres.
        index, pinky: (T, 2, 3) the hand's index and little-finger knuckles, or None.
        source: The file read.
        notes: One-line remarks about the reading (detected axes and units, filled gaps).
    """

    name: str
    times: np.ndarray
    shoulder: np.ndarray
    elbow: np.ndarray
    wrist: np.ndarray
    index: np.ndarray | None = None
    pinky: np.ndarray | None = None
    source: Path | None = None
    notes: tuple[str, ...] = ()

    @property
    def n_frames(self) -> int:
        return len(self.times)

    def hand_frames(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(T, 2, 3) hand points (between the knuckles) and (T, 2, 3, 3) hand orientations
        (z = wrist to knuckles, x = palm normal), or None without knuckles."""
        if self.index is None or self.pinky is None:
            return None
        knuckles = (self.index + self.pinky) / 2
        z = _unit(knuckles - self.wrist)
        across = self.index - self.pinky  # thumb side; the palm faces the body for left, x = -across x z
        sign = np.array([1.0, -1.0])[None, :, None]
        x = _unit(sign * np.cross(z, across))
        y = np.cross(z, x)
        return knuckles, np.stack([x, y, z], axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def read_keypoints(path: Path) -> Keypoints:
    """Read a keypoint description (``.toml``) and the array file it names.

    Raises:
        MotionFormatError: a missing or malformed description or data file, a keypoint or column
            outside the data, units or an up axis that the arm lengths contradict, gaps that
            cannot be filled (more than a fifth of the frames, or at the ends).
    """
    try:
        desc = read_toml(path, "keypoint description")
    except HlikError as e:
        raise MotionFormatError(path, str(e).split(": ", 1)[-1]) from None
    if "arms" in desc and "velocity_limits" in desc:  # a robot description given as the motion
        raise MotionFormatError(
            path,
            "a robot description, not a motion: use it as `--robot FILE` (`hlik calibrate FILE` checks it)",
        )
    if problem := unknown_key(desc, KEYS, "the top-level table"):
        raise MotionFormatError(path, problem)
    data_name = desc.get("data")
    if not isinstance(data_name, str):
        raise MotionFormatError(path, 'missing key data = "<file>" naming the keypoint array')
    data = path.parent / data_name
    table = desc.get("keypoints")
    if not isinstance(table, dict):
        raise MotionFormatError(path, "missing table [keypoints] (keypoint name -> column or joint index)")
    names = [f"{s}_{p}" for s in SIDES for p in ARM_POINTS]
    missing = [n for n in names if n not in table]
    if missing:
        raise MotionFormatError(path, f"[keypoints] lacks {', '.join(missing)}")
    known = set(names) | {f"{s}_{p}" for s in SIDES for p in HAND_POINTS}
    unknown = sorted(set(table) - known)
    if unknown:
        raise MotionFormatError(
            path, f"[keypoints] {unknown[0]}: unknown keypoint; choose from {', '.join(sorted(known))}"
        )
    skeleton_up: str | None = None
    rate: float | None
    if data.suffix.lower() == ".bvh":
        array, joint_names, rate, skeleton_up = _read_bvh(path, data)
    else:
        array, joint_names, rate = _load_array(path, data, desc)
    if rate is not None:  # what the data file says, unless the description says otherwise
        desc = {"rate": rate, **desc}
    points = {n: _column(path, array, n, table[n], joint_names) for n in table}
    times = _times(path, desc, array)
    return _assemble(path, data.stem, times, points, desc, data, skeleton_up)


# Usual BVH joint names of each keypoint (after any "prefix:" namespace), first match wins.
BVH_NAMES = {
    "shoulder": ("{S}Arm", "{S}UpperArm", "{s}_upperarm", "{s}_shoulder", "{s}humerus"),
    "elbow": ("{S}ForeArm", "{S}LowerArm", "{s}_forearm", "{s}_elbow", "{s}radius"),
    "wrist": ("{S}Hand", "{s}_hand", "{s}_wrist", "{s}wrist"),
    "index": ("{S}HandIndex1", "{S}HandIndex", "{S}Index1"),
    "pinky": ("{S}HandPinky1", "{S}HandPinky", "{S}Pinky1"),
}


def read_bvh(path: Path) -> Keypoints:
    """Read a BVH file whose joints have the usual names (:data:`BVH_NAMES`).

    Raises:
        MotionFormatError: unreadable BVH, or a required keypoint none of whose names it has.
    """
    array, joint_names, rate, up = _read_bvh(path, path)
    bare = [n.rsplit(":", 1)[-1] for n in joint_names]
    table = {}
    for side, S, s in (("left", "Left", "l"), ("right", "Right", "r")):
        for point, patterns in BVH_NAMES.items():
            found = [bare.index(p.format(S=S, s=s)) for p in patterns if p.format(S=S, s=s) in bare]
            if found:
                table[f"{side}_{point}"] = found[0]
            elif point in ARM_POINTS:
                raise MotionFormatError(
                    path,
                    f"no BVH joint for the {side} {point} "
                    f"(tried {', '.join(p.format(S=S, s=s) for p in patterns)}); "
                    "name it in a keypoint description (data = this file, [keypoints])",
                )
    points = {n: array[:, k] for n, k in table.items()}
    times = _times(path, {"rate": rate}, array)
    return _assemble(path, path.stem, times, points, {}, path, up)


def _read_bvh(path: Path, data: Path) -> tuple[np.ndarray, list[str], float, str]:
    """(T, J, 3) world positions of a BVH's joints, their names, the frame rate and the up axis: the
    skeleton's, from the root to its highest joint in the rest pose (arms held forward through a
    whole take would fool a guess from the motion)."""
    try:
        import bvhio
    except ImportError:
        raise MotionFormatError(path, 'reading BVH needs bvhio: pip install -e ".[bvh]"') from None

    _check_bvh_frames(path, data)
    try:
        container = bvhio.readAsBvh(str(data))
        root = bvhio.convertBvhToHierarchy(container.Root)
    except Exception as e:  # bvhio raises bare exceptions on malformed files
        raise MotionFormatError(path, f"cannot read BVH {data.name}: {' '.join(str(e).split())}") from None
    joints = root.layout()
    names = [j[0].Name for j in joints]
    frames = container.FrameCount
    if frames < 2 or not container.FrameTime > 0:
        raise MotionFormatError(
            path, f"{data.name}: {frames} frames at {container.FrameTime} s each; need two or more"
        )
    root.loadRestPose()
    rest = np.array([tuple(j[0].PositionWorld) for j in joints])
    lower = [n.rsplit(":", 1)[-1].lower() for n in names]
    upper_body = [i for key in ("head", "neck", "spine") for i, n in enumerate(lower) if key in n]
    top = rest[upper_body[0]] - rest[0] if upper_body else rest[np.argmax(rest[:, 1])] - rest[0]
    k = int(np.argmax(np.abs(top)))
    up = ("-" if top[k] < 0 else "") + "xyz"[k]
    positions = np.empty((frames, len(joints), 3))
    for k in range(frames):
        root.loadPose(k)
        for i, (joint, _, _) in enumerate(joints):
            positions[k, i] = tuple(joint.PositionWorld)
    return positions, names, 1.0 / container.FrameTime, up


def _check_bvh_frames(path: Path, data: Path) -> None:
    """The BVH's ``Frames:`` against its motion rows and hlik's frame limit, before bvhio reads it
    (bvhio never returns from a file with fewer rows than ``Frames:`` says, which exporters write:
    YanjieZe/GMR #172)."""
    try:
        text = data.read_text(errors="replace")
    except OSError as e:
        raise MotionFormatError(path, f"cannot read {data.name}: {e.strerror or e}") from None
    head, motion, rest = text.partition("\nMOTION")
    said = re.search(r"^\s*Frames:\s*(\d+)\s*$", rest, re.M)
    where = "" if data == path else f"{data.name}: "  # a .bvh read directly names itself once
    if not motion or said is None:
        raise MotionFormatError(path, f"{where}not a BVH file (no MOTION section with Frames:)")
    frames = int(said.group(1))
    _check_frames(path, data, frames)
    timed = re.search(r"^\s*Frame Time:.*$", rest, re.M)
    rows = sum(1 for line in rest[timed.end() :].splitlines() if line.strip()) if timed else 0
    if rows < frames:
        raise MotionFormatError(
            path, f"{where}Frames: {frames} but {rows} motion rows (the file ends early); fix Frames:"
        )


def _load_array(path: Path, data: Path, desc: Mapping) -> tuple[np.ndarray, list[str], float | None]:
    """The keypoint array, its joints' names if the description names them, and the frame rate an
    ``.npz`` stores (``fps``, ``rate``, ``framerate`` or ``mocap_framerate``; else None)."""
    if not data.is_file():
        raise MotionFormatError(path, f"data file {data} not found")
    suffix = data.suffix.lower()
    joint_names: list[str] = []
    rate = None
    if suffix in (".npz", ".npy"):
        try:
            shapes = array_shapes(data)
        except (ValueError, OSError, zipfile.BadZipFile, EOFError) as e:
            raise MotionFormatError(path, f"cannot read {data}: {_without_content(e)}") from None
        _check_frames(path, data, max((s[0] for s in shapes.values() if len(s) > 1), default=0))
    try:
        if suffix == ".npz":
            with np.load(data) as arrays:
                key = desc.get("array")
                if key not in arrays:
                    raise MotionFormatError(
                        path, f"array = {key!r} is not in {data.name}; it has {', '.join(arrays)}"
                    )
                array = np.asarray(arrays[key], dtype=float)
                if "names" in desc:
                    if desc["names"] not in arrays:
                        raise MotionFormatError(path, f"names = {desc['names']!r} is not in {data.name}")
                    joint_names = [str(n) for n in arrays[desc["names"]]]
                stored = [k for k in ("fps", "rate", "framerate", "mocap_framerate") if k in arrays]
                if stored:
                    rate = float(arrays[stored[0]])
        elif suffix == ".npy":
            array = np.load(data).astype(float)
        else:
            delimiter = "," if suffix == ".csv" else None
            array = np.loadtxt(data, delimiter=delimiter, ndmin=2)
            _check_frames(path, data, len(array))
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as e:
        raise MotionFormatError(path, f"cannot read {data}: {_without_content(e)}") from None
    if array.ndim not in (2, 3) or (array.ndim == 3 and array.shape[2] != 3):
        raise MotionFormatError(
            path, f"{data.name}: expected (T, columns) or (T, J, 3), got shape {array.shape}"
        )
    return array, joint_names, rate


def _without_content(error: Exception) -> str:
    """What went wrong reading a data file, without quoting the file (it may be anything a
    description points at): NumPy's text errors give the line they could not convert."""
    if isinstance(error, OSError) and error.strerror:
        return error.strerror
    text = " ".join(str(error).split())
    where = re.search(r"at row (\d+), column (\d+)", text)
    if "could not convert" in text:
        at = f" (row {int(where.group(1)) + 1}, column {where.group(2)})" if where else ""
        return f"not a table of numbers{at}"
    quoted = "'" in text or '"' in text
    return "not a keypoint array" if quoted and not text.startswith(("array ", "the array")) else text


def _check_frames(path: Path, data: Path, frames: int) -> None:
    """Refuse a take longer than :data:`~hlik.human.motion.MAX_FRAMES` before anything is fitted."""
    if frames > MAX_FRAMES:
        raise MotionFormatError(
            path, f"{data.name}: {frames} frames, more than hlik's {MAX_FRAMES}; crop the take first"
        )


def _column(path: Path, array: np.ndarray, name: str, where: object, joint_names: list[str]) -> np.ndarray:
    """(T, 3) positions of keypoint ``name``: columns where..where+2 of a table, or joint ``where``
    (an index, or a name of ``joint_names``)."""
    if isinstance(where, str) and joint_names:
        if where not in joint_names:
            raise MotionFormatError(
                path, f"[keypoints] {name} = {where!r}: no such joint; the file has {', '.join(joint_names)}"
            )
        where = joint_names.index(where)
    if isinstance(where, bool) or not isinstance(where, int) or where < 0:
        raise MotionFormatError(
            path, f"[keypoints] {name} must be a column or joint index >= 0, got {where!r}"
        )
    if array.ndim == 3:
        if where >= array.shape[1]:
            raise MotionFormatError(
                path, f"[keypoints] {name} = {where}: the array has {array.shape[1]} joints"
            )
        return array[:, where]
    if where + 3 > array.shape[1]:
        raise MotionFormatError(path, f"[keypoints] {name} = {where}: the table has {array.shape[1]} columns")
    return array[:, where : where + 3]


def _times(path: Path, desc: Mapping, array: np.ndarray) -> np.ndarray:
    rate = desc.get("rate")
    if isinstance(rate, bool) or not isinstance(rate, int | float) or not math.isfinite(rate):
        raise MotionFormatError(
            path, f"rate = <frame rate in Hz> is needed (the data file gives none), got {rate!r}"
        )
    if not RATE_RANGE[0] <= rate <= RATE_RANGE[1]:
        raise MotionFormatError(path, f"rate = {rate} Hz is outside {RATE_RANGE[0]:g}-{RATE_RANGE[1]:g} Hz")
    return np.arange(len(array)) / float(rate)


def _assemble(
    path: Path,
    name: str,
    times: np.ndarray,
    points: dict[str, np.ndarray],
    desc: Mapping,
    data: Path,
    skeleton_up: str | None = None,
) -> Keypoints:
    """Units, up axis and gaps of the named points (T, 3) in the file's units and axes.

    ``skeleton_up``: a BVH skeleton's up axis (``up`` in ``desc`` overrides it)."""
    notes: list[str] = []
    points = _fill_gaps(path, data, times, points, notes)
    scale = _units(path, desc, points)
    if "units" not in desc:
        unit = next(u for u, f in UNITS.items() if f == scale)
        notes.append(f"{path}: units detected as {unit} (arms of {arm_length(points) * scale:.2f} m)")
    up = _up_axis(path, desc, points, notes, skeleton_up)
    rot = _z_up(up)
    arrays = {k: (v * scale) @ rot.T for k, v in points.items()}
    lift = _floor(path, desc, arrays, scale, notes)
    arrays = {k: v + [0.0, 0.0, lift] for k, v in arrays.items()}
    arrays = _repair(path, data, times, arrays, notes)
    cutoff = desc.get("lowpass")
    if cutoff is not None:
        arrays = _lowpass(
            path, arrays, cutoff, 1.0 / float(np.median(np.diff(times))) if len(times) > 1 else 0.0
        )

    def pair(point: str) -> np.ndarray | None:
        if f"left_{point}" not in arrays or f"right_{point}" not in arrays:
            return None
        return np.stack([arrays[f"left_{point}"], arrays[f"right_{point}"]], axis=1)

    return Keypoints(
        name=name,
        times=times,
        shoulder=pair("shoulder"),  # type: ignore[arg-type]
        elbow=pair("elbow"),  # type: ignore[arg-type]
        wrist=pair("wrist"),  # type: ignore[arg-type]
        index=pair("index"),
        pinky=pair("pinky"),
        source=path,
        notes=tuple(notes),
    )


def _fill_gaps(
    path: Path, data: Path, times: np.ndarray, points: dict[str, np.ndarray], notes: list[str]
) -> dict[str, np.ndarray]:
    """The points with undetected keypoints (:func:`hlik.human.cleanup.dropouts`) and NaN frames
    filled by interpolation, noted; refused where a keypoint is never seen or the gaps are too many
    or at an end."""
    points, gone = cleanup.dropouts(points)
    never = [n for n, g in gone.items() if g.all()]
    if never:
        raise MotionFormatError(
            path, f"{data.name}: keypoint {never[0]} is never detected (0 0 0 or -1 -1 -1 in every frame)"
        )
    if gone:
        said = "; ".join(
            f"{n} in {g.sum()} frame{'s' if g.sum() > 1 else ''} ({cleanup.spans(g, times)})"
            for n, g in gone.items()
        )
        notes.append(f"{path}: {data.name}: undetected keypoints (0 0 0 or -1 -1 -1) taken as gaps: {said}")
    stacked = np.stack(list(points.values()))  # (K, T, 3)
    bad = ~np.all(np.isfinite(stacked), axis=(0, 2))
    if bad.all():
        raise MotionFormatError(path, f"{data.name}: no frame has every keypoint")
    if bad.any():
        if bad.mean() > 0.2 or bad[0] or bad[-1]:
            raise MotionFormatError(
                path,
                f"{data.name}: {bad.sum()} of {len(bad)} frames lack keypoints (NaN), first at "
                f"{times[np.argmax(bad)]:.2f} s; too many or at an end to fill, cut or repair them",
            )
        good = np.flatnonzero(~bad)
        for key, value in points.items():
            points[key] = np.stack([np.interp(times, times[good], value[good, k]) for k in range(3)], axis=1)
        what = "missing (NaN) or undetected keypoints" if gone else "NaN keypoints"
        spans = cleanup.spans(bad, times)
        notes.append(f"{path}: {data.name}: {bad.sum()} frames with {what}, interpolated ({spans})")
    return points


def _repair(
    path: Path, data: Path, times: np.ndarray, arrays: dict[str, np.ndarray], notes: list[str]
) -> dict[str, np.ndarray]:
    """Swapped sides swapped back, misdetected arms (a limb off its length) filled from the frames
    around them, and a warning when the sides look mirrored for the whole take
    (:mod:`hlik.human.cleanup`); notes added to ``notes``."""
    if not all(f"{s}_{p}" in arrays for s in SIDES for p in ARM_POINTS):
        return arrays
    arrays, fixed = cleanup.repair_swaps(arrays, times)
    notes += [f"{path}: {data.name}: {n}" for n in fixed]
    for side, bad in cleanup.limb_outliers(arrays).items():
        if bad.mean() > 0.2:
            raise MotionFormatError(
                path,
                f"{data.name}: the {side} arm's limbs change length by more than "
                f"{cleanup.LIMB_TOLERANCE:.0%} in {bad.sum()} of {len(bad)} frames: not one person's arm "
                "(wrong [keypoints] columns, or 2D points?)",
            )
        good = np.flatnonzero(~bad)
        for key in [k for k in arrays if k.startswith(side)]:
            value = arrays[key]
            arrays[key] = np.stack([np.interp(times, times[good], value[good, k]) for k in range(3)], axis=1)
        notes.append(
            f"{path}: {data.name}: {side} arm misdetected (a limb off its length by more than "
            f"{cleanup.LIMB_TOLERANCE:.0%}) at {cleanup.spans(bad, times)}; filled from the frames around"
        )
    ahead = cleanup.hands_behind(arrays)
    if ahead < -0.05:
        notes.append(
            f"{path}: {data.name}: the hands work {-100 * ahead:.0f} cm behind the shoulders (median) as the "
            "keypoints are labelled: left and right may be mirrored; check the [keypoints] table"
        )
    return arrays


# Shoulder heights (m) of a person standing or sitting on the floor at z = 0; outside them the file's
# origin is not on the floor (a camera frame) and the subject is stood on one.
SHOULDER_HEIGHT = (0.6, 2.0)
STANDING_SHOULDER = 0.818  # of the height, the MMM model's (kinematics.md §1.1)


def _floor(
    path: Path, desc: Mapping, arrays: Mapping[str, np.ndarray], scale: float, notes: list[str]
) -> float:
    """How far (m) to lift the points so that the floor is at z = 0."""
    floor = desc.get("floor", "auto")
    if floor != "auto":
        if isinstance(floor, bool) or not isinstance(floor, int | float) or not math.isfinite(floor):
            raise MotionFormatError(
                path, f'floor = {floor!r}; give its height in the file\'s units, or "auto"'
            )
        return -float(floor) * scale
    shoulder = float(
        np.median(np.concatenate([arrays["left_shoulder"][:, 2], arrays["right_shoulder"][:, 2]]))
    )
    if SHOULDER_HEIGHT[0] <= shoulder <= SHOULDER_HEIGHT[1]:
        return 0.0
    height = arm_length(arrays) / 0.333  # the MMM model's arm over its height
    lift = STANDING_SHOULDER * height - shoulder
    notes.append(
        f"{path}: shoulders {shoulder:.2f} m above the file's origin, not a floor; "
        "the subject is stood on one "
        f"(lifted {lift:+.2f} m; give floor = ... to place it)"
    )
    return lift


def _lowpass(
    path: Path, arrays: Mapping[str, np.ndarray], cutoff: object, rate: float
) -> dict[str, np.ndarray]:
    from scipy.signal import butter, filtfilt

    if isinstance(cutoff, bool) or not isinstance(cutoff, int | float) or not 0 < cutoff < rate / 2:
        raise MotionFormatError(
            path, f"lowpass = {cutoff!r}: give a cutoff in Hz below half the rate ({rate / 2:g} Hz)"
        )
    b, a = butter(2, cutoff / (rate / 2))
    if min(len(v) for v in arrays.values()) <= 3 * max(len(a), len(b)):
        raise MotionFormatError(path, "lowpass: too few frames to filter")
    return {k: filtfilt(b, a, v, axis=0) for k, v in arrays.items()}


def arm_length(points: Mapping[str, np.ndarray]) -> float:
    """Median upper arm plus forearm over both arms and all frames, in the points' units."""
    lengths = [
        np.linalg.norm(points[f"{s}_elbow"] - points[f"{s}_shoulder"], axis=1)
        + np.linalg.norm(points[f"{s}_wrist"] - points[f"{s}_elbow"], axis=1)
        for s in SIDES
    ]
    return float(np.median(np.concatenate(lengths)))


def _units(path: Path, desc: Mapping, points: Mapping[str, np.ndarray]) -> float:
    """Metres per unit of the file: the given ``units``, checked, or the one that gives an adult arm."""
    length = arm_length(points)
    given = desc.get("units")
    if given is not None:
        if given not in UNITS:
            raise MotionFormatError(path, f"units = {given!r}; choose from {', '.join(UNITS)}")
        metres = length * UNITS[given]
        if not ARM_LENGTH[0] <= metres <= ARM_LENGTH[1]:
            fits = [u for u, f in UNITS.items() if ARM_LENGTH[0] <= length * f <= ARM_LENGTH[1]]
            hint = f"; the lengths fit units = {fits[0]!r}" if fits else ""
            raise MotionFormatError(
                path,
                f"units = {given!r} gives arms (upper arm + forearm) of {metres:.3g} m, not a person's{hint}",
            )
        return UNITS[given]
    fits = [u for u, f in UNITS.items() if ARM_LENGTH[0] <= length * f <= ARM_LENGTH[1]]
    if len(fits) != 1:
        raise MotionFormatError(
            path,
            f"arms (upper arm + forearm) measure {length:.3g} in the file's units; "
            f"give units = one of {', '.join(UNITS)}, or check the [keypoints] labels (an elbow or "
            "wrist given as the other side's makes the arms reach across the body)",
        )
    return UNITS[fits[0]]


def _up_axis(
    path: Path, desc: Mapping, points: Mapping[str, np.ndarray], notes: list[str], skeleton_up: str | None
) -> str:
    """The file's vertical axis: given as ``up``, a BVH skeleton's (``skeleton_up``), or the axis
    along which the shoulders are above the elbows on average (true of a person standing or sitting
    at a task). A given axis the arms contradict is refused, unless a skeleton backs it."""
    down = np.concatenate([points[f"{s}_shoulder"] - points[f"{s}_elbow"] for s in SIDES])
    mean = np.nanmean(down, axis=0) / max(float(np.nanmean(np.linalg.norm(down, axis=1))), 1e-12)
    k = int(np.argmax(np.abs(mean)))
    detected = ("-" if mean[k] < 0 else "") + "xyz"[k]
    given = desc.get("up", skeleton_up)
    if given is None:
        if abs(mean[k]) < 0.3:
            raise MotionFormatError(
                path, "cannot tell the vertical axis from the arms; give up = x, y, z, -x, -y or -z"
            )
        notes.append(f"{path}: up axis detected as {detected} (the shoulders above the elbows)")
        return detected
    if not isinstance(given, str) or given.lstrip("-") not in AXES or given.count("-") > 1:
        raise MotionFormatError(path, f"up = {given!r}; choose from x, y, z, -x, -y, -z")
    if skeleton_up is not None:
        notes.append(f"{path}: up axis {given} (the skeleton's spine)")
        return given
    if given != detected and abs(mean[k]) > 0.5:
        raise MotionFormatError(
            path,
            f"up = {given!r}, but the elbows hang below the shoulders along {detected}; "
            f"is up = {detected!r}?",
        )
    return given


def _z_up(up: str) -> np.ndarray:
    """(3, 3) proper rotation taking the file's axis ``up`` to +z."""
    k, sign = AXES[up.lstrip("-")], -1.0 if up.startswith("-") else 1.0
    if k == 2:
        return np.diag([1.0, sign, sign])  # z or -z (a half turn about x)
    rot = np.zeros((3, 3))
    rot[2, k] = sign  # new z = the up axis
    other = [i for i in range(3) if i != k]
    rot[0, other[0]] = 1.0
    rot[1] = np.cross(rot[2], rot[0])
    return rot
