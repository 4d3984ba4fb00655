"""Rerun recordings of a retargeted motion: robot and human, targets, joint and error curves.

Entity tree::

    /world/human/bodies/<body>      human model (MJCF geometry), world frame
    /world/human/hand_paths         recorded hand (TCP) paths
    /world/objects/<object>         scene objects as boxes fitted to their markers
    /world/placement                the robot base as drawn (x and forward arrows), labelled with its rule
    /world/robot                    placement (and side-by-side offset) of the robot base
    /world/robot/bodies/<body>      robot model (MJCF geometry), base frame
    /world/robot/target_paths       hand targets; /world/robot/targets/<side> the current target frame
    /world/robot/tcp_paths          robot TCP paths; /world/robot/tcp/<side> the current TCP frame
    /plots/joints/<joint>           joint angles, rad
    /plots/fPOS/<side>, /plots/fORI/<side>   tracking errors, m and rad
    /plots/metrics/<criterion>      per-frame scores f_x0(h(t)) of the criteria, in [0, 1]
    /plots/solver/{iterations,failed}   solver diagnostics per frame

Timelines: ``frame`` (index) and ``time`` (seconds). Everything time-varying goes through
``send_columns``, chunk by chunk of frames (:data:`CHUNK_FRAMES`), so that a long take needs no
more memory than a short one to draw; log time is disabled so the same input gives the same file.
"""

from __future__ import annotations

import errno
import functools
import shutil
from collections.abc import Callable, Iterator, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from scipy.spatial.transform import Rotation

from hlik.atomic import atomic_path
from hlik.criteria.functional import position_error, rotation_angle
from hlik.fk import body_poses
from hlik.human.kinematics import human_model, qpos_trajectory
from hlik.human.motion import HumanMotion, ObjectMotion
from hlik.problem.placement import Placement
from hlik.robot.model import COLLISION_GROUP, SIDES, Robot
from hlik.trajectory import Trajectory

LAYOUTS = ("side", "overlay")
SIDE_COLORS = {"left": (66, 133, 244), "right": (244, 140, 40)}
TARGET_COLORS = {"left": (120, 200, 255), "right": (255, 200, 120)}
SPACING = 1.2  # m between human and robot shoulders in the side-by-side layout

_FILL = rr.components.FillMode.Solid

# Frames per chunk of columns. Each chunk is computed, sent and flushed before the next, so memory
# is bounded by it, not by the take. 4096 rows is where the viewer's store stops compacting
# (RERUN_CHUNK_MAX_ROWS); smaller chunks cost time, file size and footer memory per chunk.
CHUNK_FRAMES = 4096


def write_recording(
    path: str | Path,
    trajectory: Trajectory,
    robot: Robot,
    layout: str = "side",
    metrics: Mapping[str, np.ndarray] | None = None,
    chunk_frames: int = CHUNK_FRAMES,
) -> Path:
    """Write ``trajectory`` as a Rerun ``.rrd`` file, atomically: exactly ``path`` appears, whole.

    Time-varying data (body poses, errors, curves) is computed and sent ``chunk_frames`` frames at
    a time, so the memory it takes does not grow with the take; what does is the static part: the
    hand paths and the object-frame marker positions a box is fitted to (about 0.2 kB a frame for
    a KIT take, against 2.2 kB a frame the trajectory holds).

    Args:
        path: Output file.
        trajectory: The retargeted motion.
        robot: The robot it was retargeted to (for its geometry).
        layout: ``"side"`` (robot beside the human) or ``"overlay"`` (robot placed on the human).
        metrics: Criterion name -> (T,) per-frame score f_x0(h(t)), logged under ``/plots/metrics``
            (see :meth:`hlik.metrics.Evaluation.curves`).
        chunk_frames: Frames per chunk of columns (positive); the file shows the same for any.
    """
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    if chunk_frames < 1:
        raise ValueError(f"chunk_frames must be positive, got {chunk_frames}")
    for name, values in (metrics or {}).items():
        if np.shape(values) != (trajectory.n_frames,):
            raise ValueError(f"metric {name!r}: {np.shape(values)} values for {trajectory.n_frames} frames")
    path = Path(path)
    _check_space(path, trajectory.n_frames)
    recording_id = f"{trajectory.motion.name}-{robot.name}-{trajectory.solver}"
    with atomic_path(path) as tmp:
        rec = rr.RecordingStream("hlik", recording_id=recording_id)
        try:
            rec.set_log_time_enabled(False)
            rec.save(tmp, default_blueprint=blueprint())
            _log(rec, trajectory, robot, layout, metrics or {}, chunk_frames)
        finally:
            rec.disconnect()  # writes the footer; the file is complete only now
    return path


# Bytes a recording takes per frame at most, with room to spare (KIT takes on the three robots:
# 3.2-3.4 kB; 10 minutes of the Cut take looped: 2.9 kB).
BYTES_PER_FRAME = 8_000


def _check_space(path: Path, n_frames: int) -> None:
    """Refuse to start a recording the disk cannot hold: Rerun 0.41's file sink blocks for ever on a
    full disk (flush and disconnect both wait), so running out midway would hang the writer."""
    need = 1_000_000 + BYTES_PER_FRAME * n_frames
    free = shutil.disk_usage(path.parent if str(path.parent) else ".").free
    if free < need:
        raise OSError(
            errno.ENOSPC,
            f"No space left on device ({free / 1e6:.1f} MB free, {need / 1e6:.1f} MB needed)",
            str(path),
        )


def blueprint() -> rrb.Blueprint:
    """The 3D scene beside the joint-angle and tracking-error plots."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="/world", name="scene"),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="/plots/joints", name="joint angles (rad)"),
                rrb.TimeSeriesView(origin="/plots/fPOS", name="fPOS: TCP position error (m)"),
                rrb.TimeSeriesView(origin="/plots/fORI", name="fORI: TCP orientation error (rad)"),
                rrb.TimeSeriesView(origin="/plots/metrics", name="human-likeness scores f(h(t)), 1 = best"),
                rrb.TimeSeriesView(origin="/plots/solver", name="solver: iterations per frame, failed"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


# One entity's columns for some frames: (entity path, time columns, component columns).
Columns = tuple[str, list[rr.TimeColumn], Any]
# The time-varying data of one or more entities: frames (a slice of the take) -> their columns.
Track = Callable[[slice], Iterator[Columns]]
# A scalar curve: (T,) values, or the values of the frames (a slice).
Curve = np.ndarray | Callable[[slice], np.ndarray]


def _log(
    rec,
    traj: Trajectory,
    robot: Robot,
    layout: str,
    metrics: Mapping[str, np.ndarray],
    chunk_frames: int = CHUNK_FRAMES,
) -> None:
    """Log everything static once, then every track chunk by chunk of ``chunk_frames`` frames."""
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    times = traj.times

    human = human_model(traj.motion.height)
    tracks = [
        _model(
            rec,
            "/world/human/bodies",
            human,
            lambda rows: qpos_trajectory(human, _frames(traj.motion, rows)),
            times,
            alpha=200,
        )
    ]
    _log_paths(rec, "/world/human/hand_paths", traj.placement.to_world(traj.targets.pos), SIDE_COLORS)
    for name, obj in traj.motion.objects.items():
        tracks += _object(rec, f"/world/objects/{_entity(name)}", obj, times, chunk_frames)

    # The robot base as drawn (the side layout shifts it beside the human; overlay shows it where
    # the placement put it) and the rule that placed it.
    shown = _display_placement(traj.placement, layout)
    rec.log(
        "/world/placement",
        rr.Arrows3D(
            origins=[shown.translation, shown.translation],
            vectors=[0.3 * shown.rotation[:, 0], 0.5 * shown.rotation[:, 1]],
            colors=[(220, 60, 60), (60, 200, 60)],
            labels=[f"base ({traj.placement.method})", "faces"],
        ),
        static=True,
    )
    rec.log(
        "/world/robot",
        rr.Transform3D(translation=shown.translation, mat3x3=shown.rotation),
        static=True,
    )
    tracks.append(
        _model(rec, "/world/robot/bodies", robot.model, lambda rows: traj.q[rows], times, alpha=255)
    )
    _log_paths(rec, "/world/robot/target_paths", traj.targets.pos, TARGET_COLORS)
    _log_paths(rec, "/world/robot/tcp_paths", traj.tcp_pos, SIDE_COLORS)
    for i, side in enumerate(SIDES):
        tracks.append(
            _frames_track(
                rec, f"/world/robot/targets/{side}", traj.targets.pos[:, i], traj.targets.rot[:, i], times
            )
        )
        tracks.append(
            _frames_track(rec, f"/world/robot/tcp/{side}", traj.tcp_pos[:, i], traj.tcp_rot[:, i], times)
        )

    # curves: entity -> (T,) values, or the values of some frames (the tracking errors, computed
    # chunk by chunk like everything else derived)
    curves: dict[str, Curve] = {}
    for j, name in enumerate(traj.joint_names):
        curves[_curve(rec, f"/plots/joints/{_entity(name)}", name)] = traj.q[:, j]
    for i, side in enumerate(SIDES):
        fpos = _error(position_error, traj.tcp_pos[:, i], traj.targets.pos[:, i])
        fori = _error(rotation_angle, traj.tcp_rot[:, i], traj.targets.rot[:, i])
        curves[_curve(rec, f"/plots/fPOS/{side}", f"fPOS {side}", SIDE_COLORS[side])] = fpos
        curves[_curve(rec, f"/plots/fORI/{side}", f"fORI {side}", SIDE_COLORS[side])] = fori
    for name, values in metrics.items():
        curves[_curve(rec, f"/plots/metrics/{_entity(name)}", name)] = np.asarray(values, dtype=float)
    d = traj.diagnostics
    curves[_curve(rec, "/plots/solver/iterations", "iterations")] = d.iterations.astype(float)
    curves[_curve(rec, "/plots/solver/failed", "failed (1)")] = d.failed.astype(float)
    tracks.append(functools.partial(_curve_columns, curves, times))

    for start in range(0, traj.n_frames, chunk_frames):
        rows = slice(start, min(start + chunk_frames, traj.n_frames))
        for track in tracks:
            for entity, index, columns in track(rows):
                rec.send_columns(entity, indexes=index, columns=columns)
        # the file sink encodes on its own thread: wait for it, so that sent chunks never pile up
        rec.flush()


def _display_placement(placement: Placement, layout: str) -> Placement:
    if layout == "overlay":
        return placement
    # beside the human, along the human's right at the first frame (the robot base x axis)
    return Placement(placement.rotation, placement.translation + SPACING * placement.rotation[:, 0])


def _model(
    rec, root: str, model: mujoco.MjModel, qpos: Callable[[slice], np.ndarray], times: np.ndarray, alpha: int
) -> Track:
    """Log the static geometry of every body with some; the track of their poses, from
    ``qpos(frames)`` (F, nq) by forward kinematics."""
    bodies = []
    for body in range(1, model.nbody):
        entity = f"{root}/{_entity(model.body(body).name) or f'body{body}'}"
        # collision volumes are for the solvers, not the eye
        geoms = [
            g
            for g in range(model.ngeom)
            if model.geom_bodyid[g] == body and model.geom_group[g] != COLLISION_GROUP
        ]
        if not geoms:
            continue
        for archetype_name, archetype in _geometry(model, geoms, alpha).items():
            rec.log(f"{entity}/{archetype_name}", archetype, static=True)
        bodies.append((body, entity))

    def track(rows: slice) -> Iterator[Columns]:
        pos, quat = body_poses(model, qpos(rows))
        index = _index(times, rows)
        for body, entity in bodies:
            columns = rr.Transform3D.columns(translation=pos[:, body], quaternion=_xyzw(quat[:, body]))
            yield entity, index, columns

    return track


def _geometry(model: mujoco.MjModel, geoms: list[int], alpha: int) -> dict[str, rr.AsComponents]:
    """Rerun primitives for MuJoCo geoms, in their body's frame, one batch per kind."""
    batches: dict[str, dict[str, list]] = {}
    for g in geoms:
        gtype = mujoco.mjtGeom(int(model.geom_type[g]))
        if gtype not in _PRIMITIVES:  # planes, meshes, height fields: the bundled models use none
            continue
        kind, fields = _PRIMITIVES[gtype]
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[g])
        batch = batches.setdefault(kind, {"quaternions": [], "colors": []})
        for key, value in fields(model.geom_size[g], model.geom_pos[g], rot.reshape(3, 3)).items():
            batch.setdefault(key, []).append(value)
        batch["quaternions"].append(_xyzw(model.geom_quat[g]))
        batch["colors"].append((*np.round(255 * model.geom_rgba[g, :3]).astype(int), alpha))
    return {kind: _ARCHETYPES[kind](**batch, fill_mode=_FILL) for kind, batch in batches.items()}


# MuJoCo geom (size, pos, rot) -> Rerun fields. MuJoCo capsules are centred on pos; Rerun's start at
# the origin and run along +z, so they start half a length back.
_PRIMITIVES = {
    mujoco.mjtGeom.mjGEOM_CAPSULE: (
        "capsules",
        lambda size, pos, rot: {
            "lengths": 2 * size[1],
            "radii": size[0],
            "translations": pos - rot[:, 2] * size[1],
        },
    ),
    mujoco.mjtGeom.mjGEOM_CYLINDER: (
        "cylinders",
        lambda size, pos, rot: {"lengths": 2 * size[1], "radii": size[0], "centers": pos},
    ),
    mujoco.mjtGeom.mjGEOM_BOX: ("boxes", lambda size, pos, rot: {"half_sizes": size, "centers": pos}),
    mujoco.mjtGeom.mjGEOM_SPHERE: (
        "ellipsoids",
        lambda size, pos, rot: {"half_sizes": np.full(3, size[0]), "centers": pos},
    ),
    mujoco.mjtGeom.mjGEOM_ELLIPSOID: (
        "ellipsoids",
        lambda size, pos, rot: {"half_sizes": size, "centers": pos},
    ),
}
_ARCHETYPES = {
    "capsules": rr.Capsules3D,
    "cylinders": rr.Cylinders3D,
    "boxes": rr.Boxes3D,
    "ellipsoids": rr.Ellipsoids3D,
}


def _log_paths(rec, entity: str, pos: np.ndarray, colors: Mapping[str, tuple]) -> None:
    """Both arms' paths (T, 2, 3) as two static line strips."""
    rec.log(
        entity,
        rr.LineStrips3D(
            [pos[:, i] for i in range(len(SIDES))],
            colors=[colors[s] for s in SIDES],
            radii=0.003,
            labels=list(SIDES),
        ),
        static=True,
    )


def _frames_track(rec, entity: str, pos: np.ndarray, rot: np.ndarray, times: np.ndarray) -> Track:
    """Log axes at ``entity``; the track of its poses (T, 3) and (T, 3, 3)."""
    rec.log(entity, rr.TransformAxes3D(0.08), static=True)

    def track(rows: slice) -> Iterator[Columns]:
        yield entity, _index(times, rows), _pose_columns(pos[rows], rot[rows])

    return track


def _object(rec, entity: str, obj: ObjectMotion, times: np.ndarray, chunk_frames: int) -> list[Track]:
    """Log a scene object as a box around its markers (or a 5 cm cube); the track of its pose,
    where that is finite (none if it never is)."""
    known = np.all(np.isfinite(obj.position), axis=1) & np.all(np.isfinite(obj.rotation), axis=(1, 2))
    if not known.any():
        return []
    half, center = np.full(3, 0.025), np.zeros(3)
    if obj.markers:
        local = _local_markers(obj, np.flatnonzero(known), chunk_frames)
        local = local[np.all(np.isfinite(local), axis=1)]
        if len(local):
            lo, hi = np.percentile(local, [2, 98], axis=0)
            half, center = np.maximum((hi - lo) / 2, 0.01), (hi + lo) / 2
    rec.log(
        entity,
        rr.Boxes3D(
            half_sizes=[half],
            centers=[center],
            colors=[(160, 160, 160, 120)],
            fill_mode=_FILL,
            labels=[obj.name],
        ),
        static=True,
    )

    def track(rows: slice) -> Iterator[Columns]:
        frames = rows.start + np.flatnonzero(known[rows])
        if len(frames):
            index = [rr.TimeColumn("frame", sequence=frames), rr.TimeColumn("time", duration=times[frames])]
            yield entity, index, _pose_columns(obj.position[frames], obj.rotation[frames])

    return [track]


def _local_markers(obj: ObjectMotion, frames: np.ndarray, chunk_frames: int) -> np.ndarray:
    """(M * F, 3) positions of the M markers in the object's frame at ``frames`` (F,), marker by
    marker; computed ``chunk_frames`` frames at a time into one array, the only one as long as the take."""
    local = np.empty((len(obj.markers), len(frames), 3))
    for start in range(0, len(frames), chunk_frames):
        rows = frames[start : start + chunk_frames]
        rot, pos = obj.rotation[rows], obj.position[rows]
        for i, m in enumerate(obj.markers.values()):
            local[i, start : start + len(rows)] = np.einsum("tji,tj->ti", rot, m[rows] - pos)
    return local.reshape(-1, 3)


def _curve(rec, entity: str, name: str, color=None) -> str:
    """Log the style of a scalar curve at ``entity``; returns ``entity``."""
    style = rr.SeriesLines(names=name) if color is None else rr.SeriesLines(names=name, colors=[color])
    rec.log(entity, style, static=True)
    return entity


def _error(error: Callable, a: np.ndarray, b: np.ndarray) -> Callable[[slice], np.ndarray]:
    """The curve ``error(a[rows], b[rows])`` of the frames ``rows``."""
    return lambda rows: error(a[rows], b[rows])


def _curve_columns(curves: Mapping[str, Curve], times: np.ndarray, rows: slice) -> Iterator[Columns]:
    """The track of scalar curves."""
    index = _index(times, rows)
    for entity, values in curves.items():
        scalars = values(rows) if callable(values) else values[rows]
        yield entity, index, rr.Scalars.columns(scalars=scalars)


def _index(times: np.ndarray, rows: slice) -> list[rr.TimeColumn]:
    """The ``frame`` and ``time`` columns of the frames ``rows`` (a slice with start and stop)."""
    return [
        rr.TimeColumn("frame", sequence=np.arange(rows.start, rows.stop)),
        rr.TimeColumn("time", duration=times[rows]),
    ]


def _frames(motion: HumanMotion, rows: slice) -> HumanMotion:
    """The frames ``rows`` of ``motion``, as far as :func:`qpos_trajectory` reads it (no copies)."""
    return replace(
        motion,
        times=motion.times[rows],
        joints=motion.joints[rows],
        root_position=motion.root_position[rows],
        root_rotation=motion.root_rotation[rows],
    )


def _pose_columns(pos: np.ndarray, rot: np.ndarray):
    """Transform columns from (T, 3) positions and (T, 3, 3) rotations."""
    return rr.Transform3D.columns(translation=pos, quaternion=Rotation.from_matrix(rot).as_quat())


def _xyzw(wxyz: np.ndarray) -> np.ndarray:
    return np.roll(wxyz, -1, axis=-1)


def _entity(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_-." else "_" for c in name)
