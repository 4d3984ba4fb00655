"""Rerun recordings of a retargeted motion: robot and human, targets, joint and error curves.

Entity tree::

    /world/human/bodies/<body>      human model (MJCF geometry), world frame
    /world/human/hand_paths         recorded hand (TCP) paths
    /world/objects/<object>         scene objects as boxes fitted to their markers
    /world/labels/<object>          each object's name (``true_`` dropped) just above its box
    /world/placement                the robot base as drawn (x and forward arrows), labelled with its rule
    /world/robot                    placement (and side-by-side offset) of the robot base
    /world/robot/bodies/<body>      robot model (MJCF geometry), base frame
    /world/robot/target_paths       hand targets; /world/robot/targets/<side> the current target frame
    /world/robot/tcp_paths          robot TCP paths; /world/robot/tcp/<side> the current TCP frame
    /plots/joints/<joint>           joint angles, rad (m for a sliding joint)
    /plots/fPOS/<side>, /plots/fORI/<side>   tracking errors, m and rad
    /plots/fPOS_off, /plots/fORI_off     relative-pose errors (paper Eqs. 3-4), relative runs only
    /plots/metrics/<criterion>      per-frame scores f_x0(h(t)) of the criteria, in [0, 1]
    /plots/unified/{m_hl,m_f}       per-frame weighted scores whose means are m_hl and m_f
    /plots/posture/<who>_<side>_{elbow,hand}, /plots/posture/<who>_lean   posture measures of the
                                    robot and the subject (hlik.posture): elbow and hand ahead of the
                                    shoulders in arm lengths, trunk lean in rad
    /plots/solver/{iterations,failed}   solver diagnostics per frame
    /result                         markdown: motion, robot, solver, settings, scores, diagnostics
    /result/json                    the ``hlik evaluate --json`` object of the same evaluation

Timelines: ``frame`` (index) and ``time`` (seconds). Everything time-varying goes through
``send_columns``, chunk by chunk of frames (:data:`CHUNK_FRAMES`), so that a long take needs no
more memory than a short one to draw; log time is disabled so the same input gives the same file.
"""

from __future__ import annotations

import errno
import functools
import json
import shutil
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from scipy.spatial.transform import Rotation

from hlik.atomic import atomic_path
from hlik.criteria.functional import position_error, relative_errors, rotation_angle
from hlik.fk import body_poses
from hlik.human.fit import fit_error, keypoint_markers
from hlik.human.kinematics import human_model, qpos_trajectory
from hlik.human.motion import ObjectMotion
from hlik.metrics import Evaluation
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
# The time scale the score curves of the criteria of motion (MJE, MIS) are shown at, s: each frame's
# score flips between 0 and 1 with its jerk (metrics.Evaluation.curves says why); over 0.2 s the
# curve follows the motion as a viewer sees it, and still averages to m_i.
SCORE_WINDOW = 0.2


def write_recording(
    path: str | Path,
    trajectory: Trajectory,
    robot: Robot,
    layout: str = "side",
    metrics: Mapping[str, np.ndarray] | None = None,
    chunk_frames: int = CHUNK_FRAMES,
    evaluation: Evaluation | None = None,
    info: Mapping[str, str] | None = None,
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
    """
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    if chunk_frames < 1:
        raise ValueError(f"chunk_frames must be positive, got {chunk_frames}")
    window = score_window(trajectory)
    curves = dict(metrics) if metrics is not None else (evaluation.curves(window) if evaluation else {})
    for name, values in curves.items():
        if np.shape(values) != (trajectory.n_frames,):
            raise ValueError(f"metric {name!r}: {np.shape(values)} values for {trajectory.n_frames} frames")
    if evaluation is not None and len(evaluation.collisions) != trajectory.n_frames:
        raise ValueError(
            f"evaluation of {len(evaluation.collisions)} frames for a trajectory of {trajectory.n_frames}"
        )
    info = dict(info or {})
    scenario = evaluation.scenario if evaluation is not None else info.get("scenario", "pose")
    path = Path(path)
    _check_space(path, trajectory.n_frames)
    recording_id = f"{trajectory.motion.name}-{robot.name}-{trajectory.solver}"
    fit = fit_error(trajectory.motion)
    view = blueprint(
        robot,
        scenario=scenario,
        criteria=tuple(curves),
        unified=evaluation is not None,
        fitted=fit is not None,
        camera=scene_camera(trajectory, robot, layout),
        robot_camera=robot_camera(trajectory, robot),
    )
    with atomic_path(path) as tmp:
        rec = rr.RecordingStream("hlik", recording_id=recording_id)
        try:
            rec.set_log_time_enabled(False)
            rec.save(tmp, default_blueprint=view)
            _log(rec, trajectory, robot, layout, curves, chunk_frames, scenario, evaluation, fit)
            text = summary(trajectory, robot, evaluation, info)
            rec.log("/result", rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)
            if evaluation is not None:
                exact = json.dumps(evaluation.to_json(), indent=2)
                rec.log("/result/json", rr.TextDocument(exact, media_type=rr.MediaType.TEXT), static=True)
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


# The paper's clusters of the human-likeness criteria (formulas.md §10), one plot panel each; the
# three singletons share one. Criteria not named here (user-registered) share an "other" panel.
CLUSTERS = {
    "hand pose and arm posture": ("EEA", "SOA_x", "SOA_q", "EEA_r"),
    "joint space": ("HJL", "SYN", "HJA_r", "SYN_r"),
    "manipulability, jerk, minimum info": ("MAN_r", "MJE", "MIS"),
    "functional": ("fJLA", "fPOS", "fORI", "fPOS_off", "fORI_off"),
}

# Colours of the series of one panel, in order: Tableau 10, told apart at a glance. Joint k of
# either arm gets the same colour, so that the arms compare at a glance.
PALETTE = (
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
)

# Rerun's 3D view: vertical field of view (its default, 55 deg); the camera frames the figures in a
# cone a tenth narrower vertically, and 1.2 times as wide horizontally (the default layout's view
# is about 1.5 times as wide as tall).
FOV_Y = np.radians(55.0)
FRAME_TAN = 0.9 * np.tan(FOV_Y / 2)
ASPECT = 1.2
ELEVATION = 0.35  # the eye rises this much per metre it stands in front: a slight view from above


@dataclass(frozen=True, eq=False)
class Camera:
    """Where a 3D view opens: the eye at ``position`` looking at ``target``, (3,) m each, in the
    view's frame."""

    position: np.ndarray
    target: np.ndarray

    def controls(self) -> rrb.EyeControls3D:
        return rrb.EyeControls3D(
            kind="Orbital",
            position=[float(v) for v in self.position],
            look_target=[float(v) for v in self.target],
            eye_up=[0.0, 0.0, 1.0],
        )


def blueprint(
    robot: Robot | None = None,
    scenario: str = "pose",
    criteria: tuple[str, ...] = (),
    unified: bool = False,
    camera: Camera | None = None,
    robot_camera: Camera | None = None,
    fitted: bool = False,
) -> rrb.Blueprint:
    """The 3D scene (human and robot, or the robot alone, in tabs) over the result panel, beside
    the plots: joint angles per arm, tracking errors, scores by cluster, solver diagnostics.

    Args:
        robot: Splits the joint plot into left arm, right arm and other joints (one plot if None).
        scenario: ``relative`` plots fPOS_off / fORI_off first, the absolute errors as context.
        criteria: Names of the criteria with score curves (one panel per cluster they fall in).
        unified: Whether m_hl(t) and m_f(t) are logged (they then open the score tabs).
        camera, robot_camera: Where the scene (world frame) and robot (base frame) views open.
        fitted: Whether the motion was fitted to keypoints (a tab with the fit error).
    """
    scene = rrb.Spatial3DView(
        origin="/world", name="human and robot", eye_controls=camera.controls() if camera else None
    )
    alone = rrb.Spatial3DView(
        origin="/world/robot",
        name="robot alone",
        eye_controls=robot_camera.controls() if robot_camera else None,
    )
    left = rrb.Vertical(
        rrb.Tabs(scene, alone, active_tab=0),
        rrb.TextDocumentView(origin="/result", contents="/result", name="result"),
        row_shares=[3, 2],
    )
    rows: list[rrb.Container | rrb.View] = [_joint_views(robot)]
    absolute = [("fPOS", "fPOS: TCP position error (m)"), ("fORI", "fORI: TCP orientation error (rad)")]
    if scenario == "relative":
        main = [
            ("fPOS_off", "fPOS_off (m), optimised"),
            ("fORI_off", "fORI_off (rad), optimised"),
        ]
        rows.append(rrb.Horizontal(*(_plot(f"/plots/{e}", name) for e, name in main)))
        absolute = [(e, f"{e} ({unit}), context") for e, unit in (("fPOS", "m"), ("fORI", "rad"))]
    rows.append(rrb.Horizontal(*(_plot(f"/plots/{e}", name) for e, name in absolute)))
    scores = [_plot("/plots/unified", "m_hl(t), m_f(t) (1 = best)")] if unified else []
    others = tuple(c for c in criteria if not any(c in members for members in CLUSTERS.values()))
    for title, members in [*CLUSTERS.items(), ("other", others)]:
        shown = [c for c in members if c in criteria]
        if shown:
            contents = [f"/plots/metrics/{_entity(c)}" for c in shown]
            scores.append(_plot("/plots/metrics", f"scores: {title}", contents))
    if unified:
        scores.append(_plot("/plots/posture", "posture: elbows, hands ahead of the shoulders; trunk lean"))
    scores.append(_plot("/plots/solver", "solver: iterations per frame, failed"))
    if fitted:
        scores.append(_plot("/plots/fit", "MMM fit: largest elbow/wrist error (m)"))
    rows.append(rrb.Tabs(*scores, active_tab=0))
    return rrb.Blueprint(
        rrb.Horizontal(
            left, rrb.Vertical(*rows, row_shares=[3] + [2] * (len(rows) - 1)), column_shares=[3, 2]
        ),
        collapse_panels=True,
    )


def _plot(origin: str, name: str, contents: list[str] | None = None) -> rrb.TimeSeriesView:
    """A time-series panel, its legend in the top right corner (out of the way of most curves)."""
    return rrb.TimeSeriesView(
        origin=origin,
        contents=contents or "$origin/**",
        name=name,
        plot_legend=rrb.PlotLegend(corner="RightTop"),
    )


def joint_groups(robot: Robot) -> dict[str, tuple[str, ...]]:
    """Panel title -> joint names: the left arm's, the right arm's, then any others (hip, waist)."""
    arms = {f"{side} arm": tuple(robot.arm_joints[side]) for side in SIDES}
    taken = {j for joints in arms.values() for j in joints}
    rest = tuple(j for j in robot.joint_names if j not in taken)
    return {**arms, **({"other joints": rest} if rest else {})}


def _joint_views(robot: Robot | None) -> rrb.Container | rrb.View:
    if robot is None:
        return _plot("/plots/joints", "joint angles")
    return rrb.Horizontal(
        *(
            _plot("/plots/joints", f"{title}: joint angles", [f"/plots/joints/{_entity(j)}" for j in joints])
            for title, joints in joint_groups(robot).items()
        )
    )


def _joint_unit(model: mujoco.MjModel, name: str) -> str:
    return "m" if model.joint(name).type == mujoco.mjtJoint.mjJNT_SLIDE else "rad"


def scene_camera(traj: Trajectory, robot: Robot, layout: str = "side", samples: int = 24) -> Camera:
    """The opening camera of the scene, world frame: in front of the human (where its pelvis faces,
    on average over the take), a little above, as near as keeps every human and robot body and
    every hand target inside the view cone with room to spare.

    Only ``samples`` frames spread over the take are looked at (forward kinematics of a few frames).
    """
    rows = slice(0, traj.n_frames, max(1, -(-traj.n_frames // samples)))
    human = human_model(traj.motion.height)
    human_pos, _ = body_poses(human, qpos_trajectory(human, traj.motion.frames(rows)))
    shown = _display_placement(traj.placement, layout)
    robot_pos = _robot_points(traj, robot, rows) @ shown.rotation.T + shown.translation
    points = np.concatenate(
        [
            human_pos[:, 1:].reshape(-1, 3),
            robot_pos,
            traj.placement.to_world(traj.targets.pos[rows]).reshape(-1, 3),
        ]
    )
    facing = traj.motion.root_rotation[:, :, 1].mean(axis=0)  # MMM root frame: y forward
    return _framing(points, facing, fallback=traj.placement.rotation[:, 1])


def robot_camera(traj: Trajectory, robot: Robot, samples: int = 24) -> Camera:
    """The opening camera of the robot-alone view, robot base frame: in front of the robot (its
    base y axis), framing its bodies and TCP paths over the take."""
    rows = slice(0, traj.n_frames, max(1, -(-traj.n_frames // samples)))
    forward = np.array([0.0, 1.0, 0.0])
    return _framing(_robot_points(traj, robot, rows), forward, fallback=forward)


def _robot_points(traj: Trajectory, robot: Robot, rows: slice) -> np.ndarray:
    """(N, 3) robot body origins at the frames ``rows``, TCPs and targets there, base frame."""
    pos, _ = body_poses(robot.model, traj.q[rows])
    return np.concatenate(
        [pos[:, 1:].reshape(-1, 3), traj.tcp_pos[rows].reshape(-1, 3), traj.targets.pos[rows].reshape(-1, 3)]
    )


def _framing(points: np.ndarray, facing: np.ndarray, fallback: np.ndarray, margin: float = 0.15) -> Camera:
    """A camera looking back against ``facing`` (its horizontal part; ``fallback``'s if it has
    none) at the centre of the box around ``points`` (N, 3), from the nearest distance that puts
    every point, grown by ``margin`` m, inside the pyramid of half-angles atan(:data:`FRAME_TAN`)
    up and down and atan(:data:`ASPECT` * :data:`FRAME_TAN`) left and right."""
    points = points[np.all(np.isfinite(points), axis=1)]
    forward = _horizontal(facing)
    if forward is None:
        forward = _horizontal(fallback)
    if forward is None:
        forward = np.array([0.0, 1.0, 0.0])
    lo, hi = points.min(axis=0), points.max(axis=0)
    target = (lo + hi) / 2
    back = forward + [0.0, 0.0, ELEVATION]
    back /= np.linalg.norm(back)  # from the target towards the eye
    right = np.cross(-back, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, -back)
    rel = points - target
    lateral = np.maximum(np.abs(rel @ right) / ASPECT, np.abs(rel @ up)) + margin
    # a point at lateral offset s, z nearer the eye than the target, is inside when s <= (d - z) tan
    distance = float(np.max(rel @ back + margin + lateral / FRAME_TAN))
    return Camera(target + distance * back, target)


def _horizontal(v: np.ndarray) -> np.ndarray | None:
    """The unit horizontal direction of ``v`` (3,), or None if it is (nearly) vertical."""
    h = np.array([v[0], v[1], 0.0])
    norm = np.linalg.norm(h)
    return h / norm if norm > 1e-6 else None


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
    scenario: str = "pose",
    evaluation: Evaluation | None = None,
    fit: np.ndarray | None = None,
) -> None:
    """Log everything static once, then every track chunk by chunk of ``chunk_frames`` frames.

    ``fit`` (T,): the MMM fit error of a motion fitted to keypoints; its keypoints are drawn too."""
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
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
    for name, obj in traj.motion.objects.items():
        tracks += _object(rec, _entity(name), obj, times, chunk_frames)

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
            show_labels=False,  # on hover: drawn, they overlap the base
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
                for part, values in (("elbow", body.elbow_front_share), ("hand", body.hand_front_share)):
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
        batch["quaternions"].append(_xyzw(model.geom_quat[g]))
        batch["colors"].append((*np.round(255 * model.geom_rgba[g, :3]).astype(int), alpha))
    archetypes = {kind: _ARCHETYPES[kind](**batch, fill_mode=_FILL) for kind, batch in batches.items()}
    if meshes:
        archetypes["mesh"] = _mesh(model, meshes, alpha)
    return archetypes


def _mesh(model: mujoco.MjModel, geoms: list[int], alpha: int) -> rr.Mesh3D:
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
        colors.append(np.tile((*np.round(255 * rgba[:3]).astype(int), alpha), (len(vert), 1)))
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


def _object(rec, entity: str, obj: ObjectMotion, times: np.ndarray, chunk_frames: int) -> list[Track]:
    """Log a scene object as a box around its markers (or a 5 cm cube) at ``/world/objects/<entity>``
    and its name, ``true_`` dropped, 3 cm above the box's top at ``/world/labels/<entity>`` (a label
    on the box itself sits on the hand holding it); the track of both, where the object's pose is
    finite (none if it never is)."""
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
    box, label = f"/world/objects/{entity}", f"/world/labels/{entity}"
    rec.log(
        box,
        rr.Boxes3D(half_sizes=[half], centers=[center], colors=[(160, 160, 160, 120)], fill_mode=_FILL),
        static=True,
    )
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
            yield box, index, _pose_columns(pos, rot)
            # the box's centre, raised by its half-height along the world's z (rotated box) + 3 cm
            top = np.abs(rot[:, 2, :]) @ half + 0.03
            above = pos + rot @ center + top[:, None] * [0.0, 0.0, 1.0]
            yield label, index, rr.Transform3D.columns(translation=above)

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


def score_window(trajectory: Trajectory) -> int:
    """:data:`SCORE_WINDOW` in frames of ``trajectory`` (odd, at least 1)."""
    dt = float(np.median(np.diff(trajectory.times))) if trajectory.n_frames > 1 else SCORE_WINDOW
    return 2 * int(round(SCORE_WINDOW / dt / 2.0)) + 1


def summary(traj: Trajectory, robot: Robot, evaluation: Evaluation | None, info: Mapping[str, str]) -> str:
    """The markdown of the result panel: motion, robot, solver, placement and ``info``'s settings;
    the scores (the numbers of ``hlik evaluate --json``, rounded); the solver's diagnostics; the
    hlik version."""
    from hlik.version import __version__

    d = traj.diagnostics
    rate = (traj.n_frames - 1) / (traj.times[-1] - traj.times[0]) if traj.n_frames > 1 else 0.0
    settings = {
        "motion": f"{traj.motion.name} ({traj.n_frames} frames, {rate:.0f} Hz)",
        "robot": f"{robot.title} ({robot.name})",
        "solver": traj.solver,
        "placement": traj.placement.method,
        **{k: str(v) for k, v in info.items()},
    }
    source = traj.motion.source
    title = Path(source).stem if source else traj.motion.name  # the file, as the CLI names runs
    lines = [f"### {title} on {robot.name}, {traj.solver}", ""]
    table = []
    if evaluation is not None:  # the scores first: what the panel is opened for
        result = evaluation.to_json()
        lines += [
            f"**m_hl = {result['m_hl']:.4f}**, m_f = {result['m_f']:.4f}, "
            f"m_hl,f = {result['m_hl_f']:.4f} (scenario {result['scenario']}; "
            f"weights and x0: {_cell(result['metric'])})",
            "",
        ]
        table = ["", "| criterion | mean h | m |", "|---|---:|---:|"]
        for group in ("metrics", "functional"):
            table += [f"| {k} | {v['h']:.4g} | {v['m']:.4f} |" for k, v in result[group].items()]
    lines += ["| | |", "|---|---|"]
    lines += [f"| {k} | {_cell(v)} |" for k, v in settings.items()]
    lines += table
    n = traj.n_frames
    lines += [
        "",
        "| diagnostics | |",
        "|---|---:|",
        f"| failed frames | {d.n_failed} of {n} |",
        f"| unconverged frames | {d.n_unconverged} of {n} |",
    ]
    if evaluation is not None:
        lines += [
            f"| frames in self-collision | {int(np.count_nonzero(evaluation.collisions))} of {n} |",
            f"| max speed ratio | {evaluation.max_speed_ratio:.3g} |",
        ]
    lines += ["", f"hlik {__version__}"]
    return "\n".join(lines) + "\n"


def _cell(text: str) -> str:
    """``text`` safe in a markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ")


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


def _pose_columns(pos: np.ndarray, rot: np.ndarray):
    """Transform columns from (T, 3) positions and (T, 3, 3) rotations."""
    return rr.Transform3D.columns(translation=pos, quaternion=Rotation.from_matrix(rot).as_quat())


def _xyzw(wxyz: np.ndarray) -> np.ndarray:
    return np.roll(wxyz, -1, axis=-1)


def _entity(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_-." else "_" for c in name)
