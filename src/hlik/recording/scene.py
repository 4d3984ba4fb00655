"""The 3D scene: robot and human models (MJCF geometry as meshes), hand paths and frames, keypoints,
scene objects and the placement as drawn."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping

import mujoco
import numpy as np
import rerun as rr
from scipy.ndimage import median_filter

from hlik.human.kinematics import human_model, lowest_points, qpos_trajectory
from hlik.human.motion import HumanMotion, ObjectMotion
from hlik.problem.placement import Placement
from hlik.recording.columns import Columns, Track, _entity, _index, _pose_columns
from hlik.recording.style import _FILL, SIDE_COLORS, SPACING
from hlik.robot.model import COLLISION_GROUP, SIDES, Robot
from hlik.trajectory import Trajectory
from hlik.util.spatial import body_poses, xyzw

# a hand target within 3 cm of an object's box holds it: the Cut take's hand on the cucumber
# 0-4 mm, on the knife's handle 1.0-1.3 cm once picked up (6.5 cm while it lies on the table)
HOLD_DISTANCE = 0.03  # m
HOLD_SMOOTHING = 0.3  # s
FIXTURE_SPAN = 0.02  # m
OBJECT_COLOR = (160, 160, 160, 120)
FLOOR_SINK = 0.05  # m: a human drawn deeper in the floor than this is lifted onto it (side layout)
SIDE_GAP = 0.3  # m between the figures' nearest body origins (a hand's geometry reaches 0.1-0.2 m past)
ObjectBox = tuple[np.ndarray, np.ndarray, np.ndarray]  # known (T,) bool, half sizes (3,), centre (3,)


def _display_placement(traj: Trajectory, robot: Robot, layout: str) -> Placement:
    """Where the robot base is drawn: the placement (overlay), or shifted along its x axis (the
    human's right at the first frame) by :func:`side_spacing` (side)."""
    placement = traj.placement
    if layout == "overlay":
        return placement
    shift = side_spacing(traj, robot) * placement.rotation[:, 0]
    return Placement(placement.rotation, placement.translation + shift)


def human_lift(motion: HumanMotion, layout: str, samples: int = 24) -> float:
    """How far the side layout draws the human's world (its bodies, hand paths, keypoints and the
    scene's objects) above where it is, m: so that a subject scaled about its shoulders
    (``subject_scale = "auto"``), whose feet then sink below the floor (ARMAR-6: 0.7 m), is drawn
    standing on it: its lowest geometry at z = 0 in the frames it stands highest (the 90th
    percentile over ``samples`` frames; a fit that stoops in some frames sinks there, and lifting
    the whole take by those would float it where it stands). 0 in the overlay layout, where the
    robot stands in the human's world, and where nothing sinks :data:`FLOOR_SINK` deep."""
    if layout == "overlay":
        return 0.0
    standing = float(np.percentile(lowest_points(motion, samples)[1], 90))
    return -standing if standing < -FLOOR_SINK else 0.0


def side_spacing(traj: Trajectory, robot: Robot, samples: int = 24) -> float:
    """How far the side layout shifts the robot along its base x axis, m: :data:`SPACING`, or more
    where an arm reaches sideways, so that the human's bodies and the robot's bodies and TCPs stay
    :data:`SIDE_GAP` apart along that axis in every one of ``samples`` frames spread over the take
    (a scaled subject's hand had been drawn inside the robot's: ARMAR-6 on the demo, 16 cm)."""
    rows = slice(0, traj.n_frames, max(1, -(-traj.n_frames // samples)))
    human = human_model(traj.motion.height)
    human_pos, _ = body_poses(human, qpos_trajectory(human, traj.motion.frames(rows)))
    robot_pos, _ = body_poses(robot.model, traj.q[rows])
    x = traj.placement.rotation[:, 0]
    human_x = (human_pos[:, 1:] - traj.placement.translation) @ x  # (S, bodies) along the base x
    robot_x = np.concatenate([robot_pos[:, 1:, 0], traj.tcp_pos[rows, :, 0]], axis=1)  # base frame
    reach = np.max(human_x, axis=1) - np.min(robot_x, axis=1)  # (S,) the shift that makes them touch
    return float(max(SPACING, np.nanmax(reach) + SIDE_GAP))


def _model(
    rec,
    root: str,
    model: mujoco.MjModel,
    qpos: Callable[[slice], np.ndarray],
    times: np.ndarray,
    alpha: int,
    tint: tuple[int, int, int] | None = None,
) -> Track:
    """Log the static geometry of every body with some (in ``tint`` where given, else the model's
    colours); the track of their poses, from ``qpos(frames)`` (F, nq) by forward kinematics."""
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
        for archetype_name, archetype in _geometry(model, geoms, alpha, tint).items():
            rec.log(f"{entity}/{archetype_name}", archetype, static=True)
        bodies.append((body, entity))

    def track(rows: slice) -> Iterator[Columns]:
        pos, quat = body_poses(model, qpos(rows))
        index = _index(times, rows)
        for body, entity in bodies:
            columns = rr.Transform3D.columns(translation=pos[:, body], quaternion=xyzw(quat[:, body]))
            yield entity, index, columns

    return track


def _geometry(
    model: mujoco.MjModel, geoms: list[int], alpha: int, tint: tuple[int, int, int] | None = None
) -> dict[str, rr.AsComponents]:
    """Rerun primitives for MuJoCo geoms, in their body's frame, one batch per kind."""
    batches: dict[str, dict[str, list]] = {}
    meshes = [g for g in geoms if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]
    for g in geoms:
        gtype = mujoco.mjtGeom(int(model.geom_type[g]))
        if gtype not in _PRIMITIVES:  # planes and height fields: robots have none
            continue
        kind, fields = _PRIMITIVES[gtype]
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[g])
        batch = batches.setdefault(kind, {"quaternions": [], "colors": []})
        for key, value in fields(model.geom_size[g], model.geom_pos[g], rot.reshape(3, 3)).items():
            batch.setdefault(key, []).append(value)
        batch["quaternions"].append(xyzw(model.geom_quat[g]))
        batch["colors"].append((*(tint or np.round(255 * model.geom_rgba[g, :3]).astype(int)), alpha))
    archetypes = {kind: _ARCHETYPES[kind](**batch, fill_mode=_FILL) for kind, batch in batches.items()}
    if meshes:
        archetypes["mesh"] = _mesh(model, meshes, alpha, tint)
    return archetypes


def _mesh(
    model: mujoco.MjModel, geoms: list[int], alpha: int, tint: tuple[int, int, int] | None = None
) -> rr.Mesh3D:
    """One Rerun mesh of a body's mesh geoms (models imported from URDF or Menagerie), in the
    body's frame: MuJoCo stores each mesh centred in its geom's frame."""
    positions, triangles, colors, offset = [], [], [], 0
    for g in geoms:
        mesh = int(model.geom_dataid[g])
        vert = model.mesh_vert[model.mesh_vertadr[mesh] : model.mesh_vertadr[mesh] + model.mesh_vertnum[mesh]]
        face = model.mesh_face[model.mesh_faceadr[mesh] : model.mesh_faceadr[mesh] + model.mesh_facenum[mesh]]
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[g])
        positions.append(vert @ rot.reshape(3, 3).T + model.geom_pos[g])
        triangles.append(face + offset)
        offset += len(vert)
        mat = int(model.geom_matid[g])
        rgba = model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g]
        colors.append(np.tile((*(tint or np.round(255 * rgba[:3]).astype(int)), alpha), (len(vert), 1)))
    return rr.Mesh3D(
        vertex_positions=np.concatenate(positions),
        triangle_indices=np.concatenate(triangles),
        vertex_colors=np.concatenate(colors).astype(np.uint8),
    )


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


def _log_paths(
    rec, entity: str, pos: np.ndarray, colors: Mapping[str, tuple], show_labels: bool = True
) -> None:
    """Both arms' paths (T, 2, 3) as two static line strips, labelled ``left``/``right`` on hover;
    ``show_labels``: the labels drawn too, at ``<entity>/labels``, :data:`LABEL_LIFT` above each
    path's highest point (drawn on the strips, they sat on the hands; three pairs of them piled up
    on the robot's hands in side views)."""
    rec.log(
        entity,
        rr.LineStrips3D(
            [pos[:, i] for i in range(len(SIDES))],
            colors=[colors[s] for s in SIDES],
            radii=0.003,
            labels=list(SIDES),
            show_labels=False,
        ),
        static=True,
    )
    if show_labels:
        finite = [pos[:, i][np.all(np.isfinite(pos[:, i]), axis=1)] for i in range(len(SIDES))]
        above = [[*np.mean(p[:, :2], axis=0), p[:, 2].max() + LABEL_LIFT] for p in finite if len(p)]
        if len(above) == len(SIDES):
            rec.log(
                f"{entity}/labels",
                rr.Points3D(above, radii=0.004, colors=[colors[s] for s in SIDES], labels=list(SIDES)),
                static=True,
            )


LABEL_LIFT = 0.12  # m: a path's label this far above its highest point, clear of the hand


def _keypoints_track(rec, entity: str, markers: Mapping[str, np.ndarray], times: np.ndarray) -> Track:
    """Log the keypoints a fitted motion was fitted to; the track of their positions."""
    names = list(markers)
    points = np.stack([markers[n] for n in names], axis=1)  # (T, K, 3)
    colors = [SIDE_COLORS[n.split("_", 1)[0]] for n in names]
    rec.log(
        entity,
        rr.Points3D.from_fields(radii=0.015, colors=colors, labels=names, show_labels=False),
        static=True,
    )

    def track(rows: slice) -> Iterator[Columns]:
        p = points[rows]
        columns = rr.Points3D.columns(positions=p.reshape(-1, 3)).partition(lengths=[p.shape[1]] * len(p))
        yield entity, _index(times, rows), columns

    return track


def _frames_track(rec, entity: str, pos: np.ndarray, rot: np.ndarray, times: np.ndarray) -> Track:
    """Log axes at ``entity``; the track of its poses (T, 3) and (T, 3, 3)."""
    rec.log(entity, rr.TransformAxes3D(0.08), static=True)

    def track(rows: slice) -> Iterator[Columns]:
        yield entity, _index(times, rows), _pose_columns(pos[rows], rot[rows])

    return track


def _object_box(obj: ObjectMotion, chunk_frames: int) -> ObjectBox | None:
    """Where the object's pose is known (T,) bool, and the box drawn for it in its own frame:
    half sizes and centre (3,), m, around its markers (a 5 cm cube for one without, which
    :func:`_object_shape` draws as axes); None if it never is."""
    known = np.all(np.isfinite(obj.position), axis=1) & np.all(np.isfinite(obj.rotation), axis=(1, 2))
    if not known.any():
        return None
    half, center = np.full(3, 0.025), np.zeros(3)
    if obj.markers:
        local = _local_markers(obj, np.flatnonzero(known), chunk_frames)
        local = local[np.all(np.isfinite(local), axis=1)]
        if len(local):
            lo, hi = np.percentile(local, [2, 98], axis=0)
            half, center = np.maximum((hi - lo) / 2, 0.01), (hi + lo) / 2
    return known, half, center


def _object_shape(obj: ObjectMotion, half: np.ndarray, center: np.ndarray) -> rr.Boxes3D | rr.TransformAxes3D:
    """The box fitted to an object's markers; an object recorded without markers (a pose alone: the
    KIT takes' sideboard) has no known extent, so it is drawn as its frame's axes, not as a box of
    made-up size."""
    if not obj.markers:
        return rr.TransformAxes3D(0.15)
    return rr.Boxes3D(half_sizes=[half], centers=[center], colors=[OBJECT_COLOR], fill_mode=_FILL)


def _object(rec, entity: str, obj: ObjectMotion, times: np.ndarray, box: ObjectBox) -> list[Track]:
    """Log a scene object as its box (:func:`_object_box`) at ``/world/objects/<entity>`` and its
    name, ``true_`` dropped, 3 cm above the box's top at ``/world/labels/<entity>`` (a label on the
    box itself sits on the hand holding it); the track of both, where the object's pose is known."""
    known, half, center = box
    box_entity, label = f"/world/objects/{entity}", f"/world/labels/{entity}"
    rec.log(box_entity, _object_shape(obj, half, center), static=True)
    rec.log(
        label,
        # on hover only: held objects sit in the hands, where a drawn label would cover them
        rr.Points3D(
            [[0.0, 0.0, 0.0]],
            radii=0.004,
            colors=[(90, 90, 90)],
            labels=[object_label(obj.name)],
            show_labels=False,
        ),
        static=True,
    )

    def track(rows: slice) -> Iterator[Columns]:
        frames = rows.start + np.flatnonzero(known[rows])
        if len(frames):
            index = [rr.TimeColumn("frame", sequence=frames), rr.TimeColumn("time", duration=times[frames])]
            pos, rot = obj.position[frames], obj.rotation[frames]
            yield box_entity, index, _pose_columns(pos, rot)
            # the box's centre, raised by its half-height along the world's z (rotated box) + 3 cm
            top = np.abs(rot[:, 2, :]) @ half + 0.03
            above = pos + rot @ center + top[:, None] * [0.0, 0.0, 1.0]
            yield label, index, rr.Transform3D.columns(translation=above)

    return [track]


def holding_hand(traj: Trajectory, obj: ObjectMotion, box: ObjectBox) -> np.ndarray:
    """(T,) which hand holds ``obj`` at each frame: 0 left, 1 right, -1 none. A hand holds it where
    its target (the subject's hand) is within :data:`HOLD_DISTANCE` of the object's box
    (:func:`_object_box`), the nearer hand where both are, decided per :data:`HOLD_SMOOTHING` (a
    running median, so that a hand passing by does not pick it up); an object that never moves
    more than :data:`FIXTURE_SPAN` (a board, the sideboard) is held by none, though a hand rests
    on it."""
    known, half, center = box
    holder = np.full(traj.n_frames, -1)
    if np.ptp(obj.position[known], axis=0).max() <= FIXTURE_SPAN:
        return holder
    pos, rot = traj.placement.to_base(obj.position, obj.rotation)
    local = np.einsum("tji,tkj->tki", rot, traj.targets.pos - pos[:, None]) - center  # (T, 2, 3)
    gap = np.linalg.norm(np.maximum(np.abs(local) - half, 0.0), axis=2)
    gap = np.where(np.isfinite(gap), gap, np.inf)
    holder = np.where(gap.min(axis=1) <= HOLD_DISTANCE, gap.argmin(axis=1), -1)
    width = int(round(HOLD_SMOOTHING * traj.motion.rate)) if traj.n_frames > 1 else 1
    return median_filter(holder, size=width | 1, mode="nearest")


def carried_pose(
    traj: Trajectory, obj: ObjectMotion, holder: np.ndarray, frames: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The object's pose at ``frames`` (F,) in the robot base frame as the robot would carry it:
    where ``holder`` (T,) (:func:`holding_hand`) names a hand, the robot TCP's pose times the
    object's pose in that hand's target frame; elsewhere the recorded pose. (F, 3) m, (F, 3, 3)."""
    pos, rot = traj.placement.to_base(obj.position[frames], obj.rotation[frames])
    side = holder[frames]
    for i in range(len(SIDES)):
        held = side == i
        t = frames[held]
        turn = traj.tcp_rot[t, i] @ np.swapaxes(traj.targets.rot[t, i], 1, 2)
        pos[held] = traj.tcp_pos[t, i] + np.einsum("tij,tj->ti", turn, pos[held] - traj.targets.pos[t, i])
        rot[held] = turn @ rot[held]
    return pos, rot


def _held_object(rec, entity: str, obj: ObjectMotion, traj: Trajectory, box: ObjectBox) -> list[Track]:
    """The object as the robot would carry it, at ``/world/robot/objects/<entity>`` (the robot's
    base frame: beside the robot in the side layout): moved with the robot TCP of the hand that
    holds it (:func:`holding_hand`), its pose relative to that hand's target kept, so the box
    sits where the robot's hand would take it; elsewhere where the recording puts it."""
    known, half, center = box
    path = f"/world/robot/objects/{entity}"
    rec.log(path, _object_shape(obj, half, center), static=True)
    holder = holding_hand(traj, obj, box)

    def track(rows: slice) -> Iterator[Columns]:
        frames = rows.start + np.flatnonzero(known[rows])
        if len(frames):
            index = [
                rr.TimeColumn("frame", sequence=frames),
                rr.TimeColumn("time", duration=traj.times[frames]),
            ]
            yield path, index, _pose_columns(*carried_pose(traj, obj, holder, frames))

    return [track]


def object_label(name: str) -> str:
    """The name shown for a scene object: the KIT takes' ``true_`` prefix (ground-truth object
    poses) dropped, ``true_knife_black`` -> ``knife_black``."""
    return name.removeprefix("true_") or name


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
