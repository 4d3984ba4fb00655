"""The result of retargeting, shared by every solver, with a stable ``.npz`` file format.

A :class:`Trajectory` keeps what metrics and recordings need without solving again: the robot's
joint angles and TCP poses, the hand targets, the placement, the human motion (body markers are
dropped; objects are kept), the human reference the criteria compare to, and the solver's
per-frame diagnostics. Format 2 added the reference and the diagnostics, and later arrays without
a new number; format 3 is that layout, named: format 2 files with it are read, older ones and
format 1 are refused with a message saying so.
"""

from __future__ import annotations

import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hlik.human.motion import HumanMotion, ObjectMotion, frame_period
from hlik.problem.placement import Placement
from hlik.problem.reference import HumanReference
from hlik.problem.targets import HandTargets
from hlik.robot.model import Robot
from hlik.solvers.base import Diagnostics
from hlik.solvers.stack_file import SCENARIOS
from hlik.util.arrayfile import array_shapes
from hlik.util.atomic import atomic_path
from hlik.util.errors import TrajectoryFormatError
from hlik.util.files import check_readable

FORMAT = "hlik.trajectory/3"
# format 2 files whose layout is 3's are read; those written before format 2 gained arrays (the
# placement's method, the diagnostics' solve times, ...) are named as older, not as broken
OLDER = "hlik.trajectory/2"


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Robot motion retargeted from a human motion; arm index 0 = left, 1 = right.

    Attributes:
        robot: What ``hlik.load_robot`` loads the robot from: a bundled name or a TOML path.
        solver: Name of the solver that made it.
        times: (T,) seconds.
        joint_names: (n,) robot joint names; columns of ``q``.
        q: (T, n) joint angles, rad.
        tcp_pos, tcp_rot: (T, 2, 3), (T, 2, 3, 3) robot TCP poses in the robot base frame.
        targets: The hand targets the trajectory was made for (robot base frame).
        placement: Pose of the robot base in the human's world.
        motion: The human motion retargeted, on the same time base (no body markers; a motion
            fitted to keypoints keeps them, in memory, not in the ``.npz``).
        reference: The human reference of every frame (mapped pose, Ψ, manipulability).
        diagnostics: How the solver reached each frame.
        scenario: The functional scenario it was made for, ``pose`` or ``relative`` (the run's
            stack; what ``hlik evaluate`` scores by default), None where not known (a
            :func:`hlik.retarget` call, a file written before it was stored).
    """

    robot: str
    solver: str
    times: np.ndarray
    joint_names: tuple[str, ...]
    q: np.ndarray
    tcp_pos: np.ndarray
    tcp_rot: np.ndarray
    targets: HandTargets
    placement: Placement
    motion: HumanMotion
    reference: HumanReference
    diagnostics: Diagnostics
    scenario: str | None = None

    def __post_init__(self) -> None:
        if self.scenario not in (None, *SCENARIOS):  # written, it would be refused on reading
            raise ValueError(f"Trajectory.scenario must be None or one of {SCENARIOS}, got {self.scenario!r}")

    @property
    def n_frames(self) -> int:
        return len(self.times)

    @property
    def period(self) -> float:
        """The median frame step, s (:func:`~hlik.human.motion.frame_period`: 0.01 for one frame)."""
        return frame_period(self.times)

    def save(self, path: str | Path) -> Path:
        """Write to ``path`` (``.npz``) atomically: a failed write leaves no partial file.

        Arrays are stored as they are, float64 and uncompressed: a round trip is exact, and
        deflate would save only about 13 % of a take's bytes for some 50 times the write time
        (10-minute take at 100 Hz: 136 MB in 0.2 s, against 118 MB in 7 s).
        """
        path = Path(path)
        arrays = _to_arrays(self)
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, **arrays)  # type: ignore[arg-type]  # numpy's stub types allow_pickle
        return path


def load_trajectory(path: str | Path) -> Trajectory:
    """Read a trajectory written by :meth:`Trajectory.save`.

    Every array is checked before use: its shape against the time base and joint list, its type,
    finite values, strictly increasing times, rotation matrices.

    Raises:
        hlik.util.errors.TrajectoryFormatError: missing or unreadable file, not an hlik trajectory, or
            inconsistent (naming the array and the problem).
    """
    path = Path(path)
    if path.suffix.lower() == ".rrd":
        raise TrajectoryFormatError(
            f"{path}: a Rerun recording; the trajectory is the .npz written beside it "
            f"({path.with_suffix('.npz')})"
        )
    arrays = _read_arrays(path)
    found = str(arrays.get("format", ""))
    if found == OLDER:
        lacking = [k for k in _SPEC if k not in arrays]
        if lacking:
            raise TrajectoryFormatError(
                f"{path}: written in an older {OLDER} layout (before array {lacking[0]!r} was added); "
                "run hlik run again to rewrite it"
            )
        found = FORMAT
    version = found.removeprefix("hlik.trajectory/")
    if version.isdigit() and int(version) > int(FORMAT.rsplit("/", 1)[1]):
        raise TrajectoryFormatError(
            f"{path}: written in {found} by a newer hlik; this one reads {FORMAT}: update hlik to read it"
        )
    if found.startswith("hlik.trajectory/") and found != FORMAT:
        raise TrajectoryFormatError(
            f"{path}: written in {found}, this hlik reads {FORMAT} (which adds the human reference and the "
            "solver diagnostics); run hlik run again to rewrite it"
        )
    if found != FORMAT:
        raise TrajectoryFormatError(f"{path}: not an hlik trajectory (expected format {FORMAT!r})")
    _check_arrays(path, arrays)
    return _from_arrays(arrays)


def check_robot(path: str | Path, trajectory: Trajectory, robot: Robot) -> None:
    """Refuse a trajectory whose joints are not ``robot``'s (one robot's joints labelled as another).

    Raises:
        hlik.util.errors.TrajectoryFormatError: naming the file, the robot and the first joint that differs.
    """
    if trajectory.joint_names == robot.joint_names:
        _check_limits(path, trajectory, robot)
        return
    ours, theirs = robot.joint_names, trajectory.joint_names
    if len(ours) != len(theirs):
        detail = f"{len(theirs)} joints, {robot.name} has {len(ours)}"
    else:
        k = next(i for i, (a, b) in enumerate(zip(ours, theirs)) if a != b)
        detail = f"joint {k} is {theirs[k]!r}, {robot.name}'s is {ours[k]!r}"
    raise TrajectoryFormatError(f"{path}: joint_names are not those of robot {robot.name!r} ({detail})")


# rad (m): every solver keeps a joint within its limits; a saved angle farther out was not solved
LIMIT_SLACK = 1e-6
UNLIMITED_BOUND = 1e3  # rad an unlimited joint may wind to (160 turns): beyond, not an angle


def _check_limits(path: str | Path, trajectory: Trajectory, robot: Robot) -> None:
    """Refuse joint values outside ``robot``'s limits (or beyond ``UNLIMITED_BOUND`` for unlimited
    joints), naming the joint, the worst value and its frame."""
    lower = np.where(np.isfinite(robot.lower), robot.lower - LIMIT_SLACK, -UNLIMITED_BOUND)
    upper = np.where(np.isfinite(robot.upper), robot.upper + LIMIT_SLACK, UNLIMITED_BOUND)
    q = trajectory.q
    outside = (q < lower) | (q > upper)
    if not np.any(outside):
        return
    j = int(np.argmax(outside.any(axis=0)))
    k = int(np.argmax(np.where(outside[:, j], np.abs(q[:, j]), -np.inf)))
    raise TrajectoryFormatError(
        f"{path}: q: joint {robot.joint_names[j]!r} is {q[k, j]:.4g} at frame {k}, outside its limits "
        f"{lower[j]:.4g}..{upper[j]:.4g} ({int(outside[:, j].sum())} frames); not a solved trajectory"
    )


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` file, read with ``allow_pickle=False``."""
    check_readable(
        path, lambda problem: TrajectoryFormatError(f"{path}: {problem}"), "a trajectory .npz file"
    )
    if not zipfile.is_zipfile(path) and path.suffix.lower() != ".npy":  # a .toml, a .csv, ...
        raise TrajectoryFormatError(f"{path}: not a readable trajectory .npz file (not an .npz archive)")
    try:  # shapes from the headers first: a header may claim any size, a member inflate to GBs
        array_shapes(path)
    except ValueError as e:
        raise TrajectoryFormatError(f"{path}: not read: {e}") from None
    except (OSError, EOFError, KeyError, zipfile.BadZipFile, zlib.error):
        pass  # not an archive of arrays: np.load below says what it is not
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        # NumPy falls back to unpickling what is neither .npy nor .npz; say what it is not
        raise TrajectoryFormatError(
            f"{path}: not a readable trajectory .npz file (not an .npz archive)"
        ) from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise TrajectoryFormatError(f"{path}: a single .npy array, not a trajectory .npz archive")
    try:
        with archive as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as e:
        reason = "holds Python objects, not arrays" if "pickle" in str(e) else f"damaged ({e})"
        raise TrajectoryFormatError(f"{path}: not a readable trajectory .npz file: {reason}") from None


# Array name -> (shape with T frames, n robot joints, J human joints, O objects; kind): "f" finite
# reals, "f?" reals (NaN where undefined: Ψ of an arm whose elbow is never bent, markers that
# dropped out), "i" whole numbers, "b" booleans, "s" text.
_SPEC: dict[str, tuple[tuple[str | int, ...], str]] = {
    "format": ((), "s"),
    "robot": ((), "s"),
    "solver": ((), "s"),
    "times": (("T",), "f"),
    "joint_names": (("n",), "s"),
    "q": (("T", "n"), "f"),
    "tcp_pos": (("T", 2, 3), "f"),
    "tcp_rot": (("T", 2, 3, 3), "f"),
    "target_pos": (("T", 2, 3), "f"),
    "target_rot": (("T", 2, 3, 3), "f"),
    "base_pose": ((4, 4), "f"),
    "base_method": ((), "s"),
    "ref.name": ((), "s"),
    "ref.times": (("T",), "f"),
    "ref.joint_names": (("J",), "s"),
    "ref.joints": (("T", "J"), "f"),
    "ref.root_position": (("T", 3), "f"),
    "ref.root_rotation": (("T", 3, 3), "f"),
    "ref.height": ((), "f"),
    "ref.mass": ((), "f?"),
    "ref.source": ((), "s"),
    "obj.names": (("O",), "s"),
    "human.q_map": (("T", "n"), "f"),
    "human.psi": (("T", 2), "f?"),
    "human.manip": (("T", 2, 3, 3), "f"),
    "diag.iterations": (("T",), "i"),
    "diag.converged": (("T",), "b"),
    "diag.failed": (("T",), "b"),
    "diag.solve_time": (("T",), "f"),
}
_OBJECT_SPEC: dict[str, tuple[tuple[str | int, ...], str]] = {
    "position": (("T", 3), "f?"),
    "rotation": (("T", 3, 3), "f?"),
    "marker_names": (("M",), "s"),
    "markers": (("M", "T", 3), "f?"),
}
_KINDS = {"f": "reals", "f?": "reals", "i": "whole numbers", "b": "booleans", "s": "text"}


def _check_arrays(path: Path, a: dict[str, np.ndarray]) -> None:
    """Refuse arrays of the wrong kind or shape, non-finite values, times that do not increase and
    matrices that are not rotations, naming the array (and the frame) at fault."""
    spec = dict(_SPEC)
    missing = [k for k in spec if k not in a]
    if missing:
        raise TrajectoryFormatError(f"{path}: missing array {missing[0]!r}")
    if a["times"].size == 0:
        raise TrajectoryFormatError(f"{path}: no frames")
    if "scenario" in a:
        _check_kind(path, "scenario", a["scenario"], "s")
        if a["scenario"].shape != () or str(a["scenario"]) not in ("", *SCENARIOS):
            raise TrajectoryFormatError(
                f"{path}: scenario is {str(a['scenario'])!r}, expected pose or relative"
            )
    _check_kind(path, "obj.names", a["obj.names"], "s")
    for i in range(len(a["obj.names"]) if a["obj.names"].ndim == 1 else 0):
        spec |= {f"obj.{i}.{k}": v for k, v in _OBJECT_SPEC.items()}
    missing = [k for k in spec if k not in a]
    if missing:
        raise TrajectoryFormatError(f"{path}: missing array {missing[0]!r}")
    sizes: dict[str, int] = {}  # the sizes T, n, J, O as the first array with them gives them
    for key, (shape, kind) in spec.items():
        array = a[key]
        _check_kind(path, key, array, kind)
        if key.endswith(".marker_names"):
            sizes.pop("M", None)  # each object has its own markers
        for i, d in enumerate(shape):
            if isinstance(d, str) and d not in sizes and i < array.ndim:
                sizes[d] = array.shape[i]
        expected = tuple(sizes.get(d, d) if isinstance(d, str) else d for d in shape)
        if array.shape != expected:
            shown = "(" + ", ".join(map(str, expected)) + ("," if len(expected) == 1 else "") + ")"
            raise TrajectoryFormatError(f"{path}: {key} has shape {array.shape}, expected {shown}")
        if kind == "f":
            bad = ~np.isfinite(array)
            if bad.any():
                frame = f" at frame {np.argwhere(bad)[0][0]}" if shape and shape[0] == "T" else ""
                raise TrajectoryFormatError(f"{path}: {key} has NaN or infinite values{frame}")
        elif kind == "f?" and np.isinf(array).any():
            raise TrajectoryFormatError(f"{path}: {key} has infinite values")
    for key in ("times", "ref.times"):
        steps = np.diff(a[key])
        if np.any(steps <= 0):
            k = int(np.argmax(steps <= 0)) + 1
            raise TrajectoryFormatError(f"{path}: {key} not increasing at frame {k} ({a[key][k]:g} s)")
    if not np.array_equal(a["times"], a["ref.times"]):
        raise TrajectoryFormatError(f"{path}: ref.times differ from times (one time base for both)")
    if not a["ref.height"] > 0:
        raise TrajectoryFormatError(f"{path}: ref.height must be positive, got {a['ref.height']:g} m")
    if np.any(a["diag.iterations"] < 0) or np.any(a["diag.solve_time"] < 0):
        raise TrajectoryFormatError(f"{path}: diag.iterations and diag.solve_time must be >= 0")
    if a["joint_names"].size != len(set(a["joint_names"].tolist())):
        raise TrajectoryFormatError(f"{path}: joint_names lists a joint twice")
    rotations = {
        "tcp_rot": a["tcp_rot"],
        "target_rot": a["target_rot"],
        "ref.root_rotation": a["ref.root_rotation"],
        "base_pose": a["base_pose"][None, :3, :3],
    }
    for key, rot in rotations.items():
        _check_rotations(path, key, rot)


def _check_kind(path: Path, key: str, array: np.ndarray, kind: str) -> None:
    dtype = array.dtype
    ok = {
        "f": dtype.kind in "fiu",
        "f?": dtype.kind in "fiu",
        "i": dtype.kind in "iu",
        "b": dtype.kind == "b",
        "s": dtype.kind == "U",
    }[kind]
    if not ok:
        raise TrajectoryFormatError(f"{path}: {key} holds {dtype}, expected {_KINDS[kind]}")


def _check_rotations(path: Path, key: str, rot: np.ndarray, tol: float = 1e-4) -> None:
    """``rot`` (..., 3, 3) orthonormal with determinant 1, within ``tol``."""
    if not rot.size:
        return
    error = np.abs(np.swapaxes(rot, -1, -2) @ rot - np.eye(3)).max(axis=(-1, -2))
    bad = (error > tol) | (np.linalg.det(rot) < 0)
    if bad.any():
        frame = np.argwhere(bad)[0][0]
        where = "" if key == "base_pose" else f" at frame {frame}"
        raise TrajectoryFormatError(f"{path}: {key} is not a rotation{where}")


def _to_arrays(t: Trajectory) -> dict[str, np.ndarray]:
    ref, d = t.motion, t.diagnostics
    out = {
        "format": np.array(FORMAT),
        "robot": np.array(t.robot),
        "solver": np.array(t.solver),
        "times": t.times,
        "joint_names": np.array(t.joint_names, dtype=str),
        "q": t.q,
        "tcp_pos": t.tcp_pos,
        "tcp_rot": t.tcp_rot,
        "target_pos": t.targets.pos,
        "target_rot": t.targets.rot,
        "base_pose": t.placement.matrix,
        "base_method": np.array(t.placement.method),
        "ref.name": np.array(ref.name),
        "ref.times": ref.times,
        "ref.joint_names": np.array(ref.joint_names, dtype=str),
        "ref.joints": ref.joints,
        "ref.root_position": ref.root_position,
        "ref.root_rotation": ref.root_rotation,
        "ref.height": np.array(ref.height),
        "ref.mass": np.array(np.nan if ref.mass is None else ref.mass),
        "ref.source": np.array("" if ref.source is None else str(ref.source)),
        "obj.names": np.array(list(ref.objects), dtype=str),
        "human.q_map": t.reference.q_map,
        "human.psi": t.reference.psi,
        "human.manip": t.reference.manip,
        "diag.iterations": d.iterations,
        "diag.converged": d.converged,
        "diag.failed": d.failed,
        "scenario": np.array(t.scenario or ""),
        "diag.solve_time": d.solve_time,
    }
    for i, obj in enumerate(ref.objects.values()):
        out[f"obj.{i}.position"] = obj.position
        out[f"obj.{i}.rotation"] = obj.rotation
        out[f"obj.{i}.marker_names"] = np.array(list(obj.markers), dtype=str)
        out[f"obj.{i}.markers"] = np.array(list(obj.markers.values())).reshape(-1, len(ref.times), 3)
    return out


def _from_arrays(a: dict[str, np.ndarray]) -> Trajectory:
    objects = {}
    for i, name in enumerate(a["obj.names"].tolist()):
        markers = dict(zip(a[f"obj.{i}.marker_names"].tolist(), a[f"obj.{i}.markers"]))
        objects[name] = ObjectMotion(name, a[f"obj.{i}.position"], a[f"obj.{i}.rotation"], markers)
    mass = float(a["ref.mass"])
    source = str(a["ref.source"])
    motion = HumanMotion(
        name=str(a["ref.name"]),
        times=a["ref.times"],
        joint_names=tuple(a["ref.joint_names"].tolist()),
        joints=a["ref.joints"],
        root_position=a["ref.root_position"],
        root_rotation=a["ref.root_rotation"],
        height=float(a["ref.height"]),
        mass=None if np.isnan(mass) else mass,
        objects=objects,
        source=Path(source) if source else None,
    )
    return Trajectory(
        robot=str(a["robot"]),
        solver=str(a["solver"]),
        times=a["times"],
        joint_names=tuple(a["joint_names"].tolist()),
        q=a["q"],
        tcp_pos=a["tcp_pos"],
        tcp_rot=a["tcp_rot"],
        targets=HandTargets(a["target_pos"], a["target_rot"]),
        placement=Placement.from_matrix(a["base_pose"], str(a.get("base_method", "given"))),
        motion=motion,
        reference=HumanReference(a["human.q_map"], a["human.psi"], a["human.manip"]),
        diagnostics=Diagnostics(
            a["diag.iterations"], a["diag.converged"], a["diag.failed"], a["diag.solve_time"]
        ),
        scenario=str(a["scenario"]) or None if "scenario" in a else None,  # optional: added within format 3
    )
