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
``send_columns``; log time is disabled so the same input gives the same file.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from scipy.spatial.transform import Rotation

from hlik.atomic import atomic_path
from hlik.criteria.functional import position_error, rotation_angle
from hlik.fk import body_poses
from hlik.human.kinematics import human_model, qpos_trajectory
from hlik.human.motion import ObjectMotion
from hlik.problem.placement import Placement
from hlik.robot.model import COLLISION_GROUP, SIDES, Robot
from hlik.trajectory import Trajectory

LAYOUTS = ("side", "overlay")
SIDE_COLORS = {"left": (66, 133, 244), "right": (244, 140, 40)}
TARGET_COLORS = {"left": (120, 200, 255), "right": (255, 200, 120)}
SPACING = 1.2  # m between human and robot shoulders in the side-by-side layout

_FILL = rr.components.FillMode.Solid


def write_recording(
    path: str | Path,
    trajectory: Trajectory,
    robot: Robot,
    layout: str = "side",
    metrics: Mapping[str, np.ndarray] | None = None,
) -> Path:
    """Write ``trajectory`` as a Rerun ``.rrd`` file, atomically.

    Args:
        path: Output file.
        trajectory: The retargeted motion.
        robot: The robot it was retargeted to (for its geometry).
        layout: ``"side"`` (robot beside the human) or ``"overlay"`` (robot placed on the human).
        metrics: Criterion name -> (T,) per-frame score f_x0(h(t)), logged under ``/plots/metrics``
            (see :meth:`hlik.metrics.Evaluation.curves`).
    """
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    path = Path(path)
    recording_id = f"{trajectory.motion.name}-{robot.name}-{trajectory.solver}"
    with atomic_path(path) as tmp:
        rec = rr.RecordingStream("hlik", recording_id=recording_id)
        try:
            rec.set_log_time_enabled(False)
            rec.save(tmp, default_blueprint=blueprint())
            _log(rec, trajectory, robot, layout, metrics or {})
        finally:
            rec.disconnect()  # writes the footer; the file is complete only now
    return path


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


def _log(rec, traj: Trajectory, robot: Robot, layout: str, metrics: Mapping[str, np.ndarray]) -> None:
    index = _index(np.arange(traj.n_frames), traj.times)
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    human = human_model(traj.motion.height)
    _log_model(rec, "/world/human/bodies", human, qpos_trajectory(human, traj.motion), index, alpha=200)
    human_hands = traj.placement.to_world(traj.targets.pos)
    _log_paths(rec, "/world/human/hand_paths", human_hands, SIDE_COLORS)
    for name, obj in traj.motion.objects.items():
        _log_object(rec, f"/world/objects/{_entity(name)}", obj, traj.times)

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
    _log_model(rec, "/world/robot/bodies", robot.model, traj.q, index, alpha=255)
    _log_paths(rec, "/world/robot/target_paths", traj.targets.pos, TARGET_COLORS)
    _log_paths(rec, "/world/robot/tcp_paths", traj.tcp_pos, SIDE_COLORS)
    for i, side in enumerate(SIDES):
        _log_frames(
            rec, f"/world/robot/targets/{side}", traj.targets.pos[:, i], traj.targets.rot[:, i], index
        )
        _log_frames(rec, f"/world/robot/tcp/{side}", traj.tcp_pos[:, i], traj.tcp_rot[:, i], index)

    for j, name in enumerate(traj.joint_names):
        _log_curve(rec, f"/plots/joints/{_entity(name)}", traj.q[:, j], index, name)
    fpos = position_error(traj.tcp_pos, traj.targets.pos)
    fori = rotation_angle(traj.tcp_rot, traj.targets.rot)
    for i, side in enumerate(SIDES):
        _log_curve(rec, f"/plots/fPOS/{side}", fpos[:, i], index, f"fPOS {side}", SIDE_COLORS[side])
        _log_curve(rec, f"/plots/fORI/{side}", fori[:, i], index, f"fORI {side}", SIDE_COLORS[side])
    for name, values in metrics.items():
        _log_curve(rec, f"/plots/metrics/{_entity(name)}", np.asarray(values, dtype=float), index, name)
    d = traj.diagnostics
    _log_curve(rec, "/plots/solver/iterations", d.iterations.astype(float), index, "iterations")
    _log_curve(rec, "/plots/solver/failed", d.failed.astype(float), index, "failed (1)")


def _display_placement(placement: Placement, layout: str) -> Placement:
    if layout == "overlay":
        return placement
    # beside the human, along the human's right at the first frame (the robot base x axis)
    return Placement(placement.rotation, placement.translation + SPACING * placement.rotation[:, 0])


def _log_model(rec, root: str, model: mujoco.MjModel, qpos: np.ndarray, index: list, alpha: int) -> None:
    """Static geometry per body, then the body poses of every frame as transform columns."""
    pos, quat = body_poses(model, qpos)
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
        rec.send_columns(
            entity,
            indexes=index,
            columns=rr.Transform3D.columns(translation=pos[:, body], quaternion=_xyzw(quat[:, body])),
        )


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


def _log_frames(rec, entity: str, pos: np.ndarray, rot: np.ndarray, index: list) -> None:
    rec.log(entity, rr.TransformAxes3D(0.08), static=True)
    rec.send_columns(entity, indexes=index, columns=_pose_columns(pos, rot))


def _log_object(rec, entity: str, obj: ObjectMotion, times: np.ndarray) -> None:
    """A scene object as a box around its markers (or a 5 cm cube), where its pose is finite."""
    known = np.all(np.isfinite(obj.position), axis=1) & np.all(np.isfinite(obj.rotation), axis=(1, 2))
    if not known.any():
        return
    half, center = np.full(3, 0.025), np.zeros(3)
    if obj.markers:
        # marker positions in the object frame, over the frames where everything is known
        local = np.concatenate(
            [
                np.einsum("tji,tj->ti", obj.rotation[known], m[known] - obj.position[known])
                for m in obj.markers.values()
            ]
        )
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
    frames = np.flatnonzero(known)
    rec.send_columns(
        entity,
        indexes=_index(frames, times[frames]),
        columns=_pose_columns(obj.position[known], obj.rotation[known]),
    )


def _log_curve(rec, entity: str, values: np.ndarray, index: list, name: str, color=None) -> None:
    style = rr.SeriesLines(names=name) if color is None else rr.SeriesLines(names=name, colors=[color])
    rec.log(entity, style, static=True)
    rec.send_columns(entity, indexes=index, columns=rr.Scalars.columns(scalars=values))


def _index(frames: np.ndarray, times: np.ndarray) -> list[rr.TimeColumn]:
    return [rr.TimeColumn("frame", sequence=frames), rr.TimeColumn("time", duration=times)]


def _pose_columns(pos: np.ndarray, rot: np.ndarray):
    """Transform columns from (T, 3) positions and (T, 3, 3) rotations."""
    return rr.Transform3D.columns(translation=pos, quaternion=Rotation.from_matrix(rot).as_quat())


def _xyzw(wxyz: np.ndarray) -> np.ndarray:
    return np.roll(wxyz, -1, axis=-1)


def _entity(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_-." else "_" for c in name)
