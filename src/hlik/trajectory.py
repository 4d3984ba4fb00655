"""The result of retargeting, shared by every solver, with a stable ``.npz`` file format.

A :class:`Trajectory` keeps what metrics and recordings need without solving again: the robot's
joint angles and TCP poses, the hand targets, the placement, the human motion (body markers are
dropped; objects are kept), the human reference the criteria compare to, and the solver's
per-frame diagnostics. Format 2 added the reference and the diagnostics; format 1 files are
refused with a message saying so.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hlik.atomic import atomic_path
from hlik.errors import TrajectoryFormatError
from hlik.human.motion import HumanMotion, ObjectMotion
from hlik.problem.placement import Placement
from hlik.problem.reference import HumanReference
from hlik.problem.targets import HandTargets
from hlik.solvers.base import Diagnostics

FORMAT = "hlik.trajectory/2"


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Robot motion retargeted from a human motion; arm index 0 = left, 1 = right.

    Attributes:
        robot: Robot name (``hlik.load_robot`` loads it).
        solver: Name of the solver that made it.
        times: (T,) seconds.
        joint_names: (n,) robot joint names; columns of ``q``.
        q: (T, n) joint angles, rad.
        tcp_pos, tcp_rot: (T, 2, 3), (T, 2, 3, 3) robot TCP poses in the robot base frame.
        targets: The hand targets the trajectory was made for (robot base frame).
        placement: Pose of the robot base in the human's world.
        motion: The human motion retargeted, on the same time base (no body markers).
        reference: The human reference of every frame (mapped pose, Ψ, manipulability).
        diagnostics: How the solver reached each frame.
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

    @property
    def n_frames(self) -> int:
        return len(self.times)

    def save(self, path: str | Path) -> Path:
        """Write to ``path`` (``.npz``) atomically: a failed write leaves no partial file."""
        path = Path(path)
        arrays = _to_arrays(self)
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)  # type: ignore[arg-type]  # numpy's stub types allow_pickle
        return path


def load_trajectory(path: str | Path) -> Trajectory:
    """Read a trajectory written by :meth:`Trajectory.save`.

    Raises:
        hlik.errors.TrajectoryFormatError: missing file, not an hlik trajectory, or inconsistent.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise TrajectoryFormatError(f"{path}: no such file") from None
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        hint = " (a recording? evaluate the .npz written beside it)" if path.suffix == ".rrd" else ""
        reason = "not an .npz archive" if "pickle" in str(e) else str(e)
        raise TrajectoryFormatError(f"{path}: not a readable trajectory .npz file: {reason}{hint}") from None
    found = str(arrays.get("format", ""))
    if found.startswith("hlik.trajectory/") and found != FORMAT:
        raise TrajectoryFormatError(
            f"{path}: written in {found}, this hlik reads {FORMAT} (which adds the human reference and the "
            "solver diagnostics); run hlik run again to rewrite it"
        )
    if found != FORMAT:
        raise TrajectoryFormatError(f"{path}: not an hlik trajectory (expected format {FORMAT!r})")
    try:
        traj = _from_arrays(arrays)
    except KeyError as e:
        raise TrajectoryFormatError(f"{path}: missing array {e}") from None
    _check(path, traj)
    return traj


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
    )


def _check(path: Path, t: Trajectory) -> None:
    n_t, n_q = len(t.times), len(t.joint_names)
    shapes = {
        "q": (t.q, (n_t, n_q)),
        "tcp_pos": (t.tcp_pos, (n_t, 2, 3)),
        "tcp_rot": (t.tcp_rot, (n_t, 2, 3, 3)),
        "target_pos": (t.targets.pos, (n_t, 2, 3)),
        "target_rot": (t.targets.rot, (n_t, 2, 3, 3)),
        "ref.joints": (t.motion.joints, (n_t, len(t.motion.joint_names))),
        "human.q_map": (t.reference.q_map, (n_t, n_q)),
        "human.psi": (t.reference.psi, (n_t, 2)),
        "human.manip": (t.reference.manip, (n_t, 2, 3, 3)),
        **{f"diag.{k}": (getattr(t.diagnostics, k), (n_t,)) for k in ("iterations", "converged", "failed")},
        "diag.solve_time": (t.diagnostics.solve_time, (n_t,)),
    }
    for key, (array, shape) in shapes.items():
        if array.shape != shape:
            raise TrajectoryFormatError(f"{path}: {key} has shape {array.shape}, expected {shape}")
    if not np.all(np.isfinite(t.q)):
        raise TrajectoryFormatError(f"{path}: joint angles contain NaN or inf")
