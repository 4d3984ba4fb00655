"""Writing a recording: the disk-space check, then every entity, chunk by chunk."""

from __future__ import annotations

import errno
import functools
import json
import shutil
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import rerun as rr

from hlik.criteria.functional import position_error, relative_errors, rotation_angle
from hlik.human.fit import fit_error, keypoint_markers
from hlik.human.kinematics import human_model, qpos_trajectory
from hlik.metrics import Evaluation
from hlik.recording.columns import Curve, Track, _curve, _curve_columns, _entity, _error
from hlik.recording.panel import summary
from hlik.recording.scene import (
    ObjectBox,
    _display_placement,
    _frames_track,
    _held_object,
    _keypoints_track,
    _log_paths,
    _model,
    _object,
    _object_box,
    human_lift,
)
from hlik.recording.style import (
    CHUNK_FRAMES,
    CLUSTERS,
    LAYOUTS,
    PALETTE,
    SIDE_COLORS,
    TARGET_COLORS,
    score_window,
)
from hlik.recording.view import _joint_unit, blueprint, joint_groups, robot_camera, scene_camera
from hlik.robot.model import SIDES, Robot
from hlik.robot.state import robot_state
from hlik.trajectory import Trajectory
from hlik.util.atomic import atomic_path


def write_recording(
    path: str | Path,
    trajectory: Trajectory,
    robot: Robot,
    layout: str = "side",
    metrics: Mapping[str, np.ndarray] | None = None,
    chunk_frames: int = CHUNK_FRAMES,
    evaluation: Evaluation | None = None,
    info: Mapping[str, str] | None = None,
    simulated: np.ndarray | None = None,
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
            (see :meth:`hlik.metrics.Evaluation.curves`); wins over ``evaluation``'s curves, which
            show the criteria of motion over :data:`SCORE_WINDOW` (:func:`score_window`).
        chunk_frames: Frames per chunk of columns (positive); the file shows the same for any.
        evaluation: The trajectory's scores: their per-frame curves (unless ``metrics``), the
            per-frame m_hl(t) and m_f(t), and the table of the text panel ``/result``.
        info: Free-form settings shown in the text panel, key -> value (``stack``, ``criteria``,
            ``corpus``, ``scenario``, ...); scenario ``relative`` (or the evaluation's) makes
            fPOS_off / fORI_off the main tracking plots.
        simulated: (T, n) joint angles of the trajectory replayed through physics
            (:func:`hlik.replay.replay`), drawn translucent orange over the commanded robot
            (``/world/robot/simulated``), each simulated TCP's distance from the commanded one
            plotted beside fPOS (``/plots/fPOS/simulated_<side>``, m).
    """
    _check_arguments(layout, chunk_frames)
    curves = _score_curves(trajectory, metrics, evaluation)
    info = dict(info or {})
    scenario = (
        evaluation.scenario if evaluation is not None else info.get("scenario", trajectory.scenario or "pose")
    )
    path = Path(path)
    _check_space(path, trajectory.n_frames)
    recording_id = f"{trajectory.motion.name}-{robot.name}-{trajectory.solver}"
    fit = fit_error(trajectory.motion)
    cameras = scene_camera(trajectory, robot, layout), robot_camera(trajectory, robot)
    view = blueprint(robot, scenario, tuple(curves), evaluation is not None, *cameras, fitted=fit is not None)
    with atomic_path(path) as tmp:
        rec = rr.RecordingStream("hlik", recording_id=recording_id)
        try:
            rec.set_log_time_enabled(False)
            rec.save(tmp, default_blueprint=view)
            _log(rec, trajectory, robot, layout, curves, chunk_frames, scenario, evaluation, fit, simulated)
            _log_result(rec, summary(trajectory, robot, evaluation, info), evaluation)
        finally:
            rec.disconnect()  # writes the footer; the file is complete only now
    return path


def _check_arguments(layout: str, chunk_frames: int) -> None:
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    if chunk_frames < 1:
        raise ValueError(f"chunk_frames must be positive, got {chunk_frames}")


def _log_result(rec: rr.RecordingStream, text: str, evaluation: Evaluation | None) -> None:
    """The text panel ``/result`` (``text``, Markdown) and the exact scores beside it (JSON)."""
    rec.log("/result", rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)
    if evaluation is not None:
        exact = json.dumps(evaluation.to_json(), indent=2)
        rec.log("/result/json", rr.TextDocument(exact, media_type=rr.MediaType.TEXT), static=True)


def _score_curves(
    trajectory: Trajectory, metrics: Mapping[str, np.ndarray] | None, evaluation: Evaluation | None
) -> dict[str, np.ndarray]:
    """The per-frame score curves to plot: ``metrics``, else the evaluation's (the criteria of
    motion over :func:`score_window`), each checked to have one value a frame.

    Raises:
        ValueError: a curve or the evaluation of another length than the trajectory.
    """
    window = score_window(trajectory)
    curves = dict(metrics) if metrics is not None else (evaluation.curves(window) if evaluation else {})
    for name, values in curves.items():
        if np.shape(values) != (trajectory.n_frames,):
            raise ValueError(f"metric {name!r}: {np.shape(values)} values for {trajectory.n_frames} frames")
    if evaluation is not None and len(evaluation.collisions) != trajectory.n_frames:
        raise ValueError(
            f"evaluation of {len(evaluation.collisions)} frames for a trajectory of {trajectory.n_frames}"
        )
    return curves


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


def _log(
    rec,
    traj: Trajectory,
    robot: Robot,
    layout: str,
    metrics: Mapping[str, np.ndarray],
    chunk_frames: int = CHUNK_FRAMES,
    scenario: str = "pose",
    evaluation: Evaluation | None = None,
    fit: np.ndarray | None = None,
    simulated: np.ndarray | None = None,
) -> None:
    """Log everything static once, then every track chunk by chunk of ``chunk_frames`` frames.

    ``fit`` (T,): the MMM fit error of a motion fitted to keypoints; its keypoints are drawn too.
    ``simulated`` (T, n): a physics replay's joint angles, drawn over the robot."""
    times = traj.times
    tracks = _scene(rec, traj, robot, layout, chunk_frames, fit)
    curves = _curves(rec, traj, robot, metrics, scenario, evaluation, fit)
    if simulated is not None:
        tracks.append(_simulated(rec, robot, simulated, times))
        curves |= _simulated_curves(rec, traj, robot, simulated)
    tracks.append(functools.partial(_curve_columns, curves, times))

    for start in range(0, traj.n_frames, chunk_frames):
        rows = slice(start, min(start + chunk_frames, traj.n_frames))
        for track in tracks:
            for entity, index, columns in track(rows):
                rec.send_columns(entity, indexes=index, columns=columns)
        # the file sink encodes on its own thread: wait for it, so that sent chunks never pile up
        rec.flush()


def _scene(
    rec, traj: Trajectory, robot: Robot, layout: str, chunk_frames: int, fit: np.ndarray | None
) -> list[Track]:
    """Log the 3D scene's static parts; the tracks of its moving ones (human, objects, robot, frames)."""
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    lift = human_lift(traj.motion, layout)
    for world in ("/world/human", "/world/objects", "/world/labels"):  # the human's world, on the floor
        if lift:
            rec.log(world, rr.Transform3D(translation=[0.0, 0.0, lift]), static=True)
    tracks, boxes = _human_scene(rec, traj, chunk_frames, fit)
    return tracks + _robot_scene(rec, traj, robot, layout, boxes)


def _human_scene(
    rec, traj: Trajectory, chunk_frames: int, fit: np.ndarray | None
) -> tuple[list[Track], dict[str, ObjectBox]]:
    """The human, its hand paths, keypoints and the scene objects; the tracks and the objects' boxes."""
    times = traj.times
    human = human_model(traj.motion.height)
    tracks = [
        _model(
            rec,
            "/world/human/bodies",
            human,
            lambda rows: qpos_trajectory(human, traj.motion.frames(rows)),
            times,
            alpha=200,
        )
    ]
    _log_paths(rec, "/world/human/hand_paths", traj.placement.to_world(traj.targets.pos), SIDE_COLORS)
    if fit is not None:
        tracks.append(_keypoints_track(rec, "/world/human/keypoints", keypoint_markers(traj.motion), times))
    fitted = {name: _object_box(obj, chunk_frames) for name, obj in traj.motion.objects.items()}
    boxes = {name: box for name, box in fitted.items() if box is not None}  # never known: not drawn
    for name, box in boxes.items():
        tracks += _object(rec, _entity(name), traj.motion.objects[name], times, box)
    return tracks, boxes


def _robot_scene(
    rec, traj: Trajectory, robot: Robot, layout: str, boxes: dict[str, ObjectBox]
) -> list[Track]:
    """The robot, its placement, the objects as it would carry them, its target and TCP paths and frames."""
    times = traj.times
    # The robot base as drawn (the side layout shifts it beside the human; overlay shows it where
    # the placement put it) and the rule that placed it.
    shown = _display_placement(traj, robot, layout)
    rec.log(
        "/world/placement",
        rr.Arrows3D(
            origins=[shown.translation, shown.translation],
            vectors=[0.3 * shown.rotation[:, 0], 0.5 * shown.rotation[:, 1]],
            colors=[(220, 60, 60), (60, 200, 60)],
            labels=[f"base ({traj.placement.method})", "faces"],
            show_labels=False,  # on hover: drawn, they overlap the base
        ),
        static=True,
    )
    rec.log(
        "/world/robot",
        rr.Transform3D(translation=shown.translation, mat3x3=shown.rotation),
        static=True,
    )
    tracks = [_model(rec, "/world/robot/bodies", robot.model, lambda rows: traj.q[rows], times, alpha=255)]
    for name, box in boxes.items():  # and as the robot would carry them
        tracks += _held_object(rec, _entity(name), traj.motion.objects[name], traj, box)
    _log_paths(rec, "/world/robot/target_paths", traj.targets.pos, TARGET_COLORS, show_labels=False)
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

    return tracks


def _simulated(rec, robot: Robot, q: np.ndarray, times: np.ndarray) -> Track:
    """The replayed robot, translucent orange, in the commanded robot's base frame."""
    return _model(
        rec, "/world/robot/simulated", robot.model, lambda rows: q[rows], times, alpha=110, tint=(255, 140, 0)
    )


def _simulated_curves(rec, traj: Trajectory, robot: Robot, q: np.ndarray) -> dict[str, Curve]:
    """Each replayed TCP's distance from the commanded one (m): (T, 2), small, computed once."""
    deviation = np.linalg.norm(robot_state(robot, q).tcp - traj.tcp_pos, axis=-1)
    curves: dict[str, Curve] = {}
    for i, side in enumerate(SIDES):
        label = f"simulated {side} TCP off the commanded (m)"
        curves[_curve(rec, f"/plots/fPOS/simulated_{side}", label, TARGET_COLORS[side])] = deviation[:, i]
    return curves


def _curves(
    rec,
    traj: Trajectory,
    robot: Robot,
    metrics: Mapping[str, np.ndarray],
    scenario: str,
    evaluation: Evaluation | None,
    fit: np.ndarray | None,
) -> dict[str, Curve]:
    """Declare every plotted series; entity -> its values (T,), or a function of the frames (the
    tracking errors, computed chunk by chunk like everything else derived)."""
    curves: dict[str, Curve] = {}
    for joints in joint_groups(robot).values():
        for k, name in enumerate(joints):
            label = f"{name} ({_joint_unit(robot.model, name)})"
            entity = _curve(rec, f"/plots/joints/{_entity(name)}", label, PALETTE[k % len(PALETTE)])
            curves[entity] = traj.q[:, traj.joint_names.index(name)]
    for i, side in enumerate(SIDES):
        fpos = _error(position_error, traj.tcp_pos[:, i], traj.targets.pos[:, i])
        fori = _error(rotation_angle, traj.tcp_rot[:, i], traj.targets.rot[:, i])
        curves[_curve(rec, f"/plots/fPOS/{side}", f"fPOS {side} (m)", SIDE_COLORS[side])] = fpos
        curves[_curve(rec, f"/plots/fORI/{side}", f"fORI {side} (rad)", SIDE_COLORS[side])] = fori
    if scenario == "relative":
        arrays = (traj.tcp_pos, traj.tcp_rot, traj.targets.pos, traj.targets.rot)
        off = lambda rows, k: relative_errors(*(a[rows] for a in arrays))[k]  # noqa: E731
        curves[_curve(rec, "/plots/fPOS_off", "fPOS_off (m)", PALETTE[0])] = functools.partial(off, k=0)
        curves[_curve(rec, "/plots/fORI_off", "fORI_off (rad)", PALETTE[0])] = functools.partial(off, k=1)
    ordered = [c for members in CLUSTERS.values() for c in members if c in metrics]
    ordered += [c for c in metrics if c not in ordered]
    # colours restart in every cluster panel; "other" criteria follow on
    slot = {c: k for members in CLUSTERS.values() for k, c in enumerate(members)}
    for n, name in enumerate(ordered):
        color = PALETTE[slot.get(name, n) % len(PALETTE)]
        entity = _curve(rec, f"/plots/metrics/{_entity(name)}", f"{name} (score)", color)
        curves[entity] = np.asarray(metrics[name], dtype=float)
    if evaluation is not None:
        m_hl, m_f = evaluation.unified_curves(score_window(traj))
        curves[_curve(rec, "/plots/unified/m_hl", "m_hl(t) (score)", PALETTE[0])] = m_hl
        curves[_curve(rec, "/plots/unified/m_f", "m_f(t) (score)", PALETTE[1])] = m_f
        for who, body, colors in (
            ("robot", evaluation.posture.robot, SIDE_COLORS),
            ("subject", evaluation.posture.subject, TARGET_COLORS),
        ):
            for i, side in enumerate(SIDES):
                shares = (body.elbow_front_share, body.wrist_front_share, body.hand_front_share)
                for part, values in zip(("elbow", "wrist", "hand"), shares, strict=True):
                    label = f"{who} {side} {part} ahead (arm lengths)"
                    entity = _curve(rec, f"/plots/posture/{who}_{side}_{part}", label, colors[side])
                    curves[entity] = values[:, i]
            entity = _curve(rec, f"/plots/posture/{who}_lean", f"{who} trunk lean (rad)", colors["left"])
            curves[entity] = body.lean
    if fit is not None:
        curves[_curve(rec, "/plots/fit/error", "fit error (m)", PALETTE[0])] = fit
    d = traj.diagnostics
    curves[_curve(rec, "/plots/solver/iterations", "iterations (count)", PALETTE[0])] = d.iterations.astype(
        float
    )
    curves[_curve(rec, "/plots/solver/failed", "failed (1 = yes)", PALETTE[3])] = d.failed.astype(float)
    return curves
