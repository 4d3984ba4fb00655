"""The viewer's layout (the blueprint: 3D scene, joint, error, metric and posture plots) and the
opening cameras framing the robot and the human."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import rerun.blueprint as rrb

from hlik.human.kinematics import human_model, qpos_trajectory
from hlik.recording.columns import _entity
from hlik.recording.scene import _display_placement, human_lift
from hlik.recording.style import CLUSTERS
from hlik.robot.model import SIDES, Robot
from hlik.trajectory import Trajectory
from hlik.util.spatial import body_poses

# Rerun's 3D view: vertical field of view (its default, 55 deg); the camera frames the figures in a
# cone a tenth narrower vertically, and 1.75 times as wide horizontally: the layout's scene view is
# 3/5 of a window's width and height, 1.9 times as wide as tall in a 1600 x 900 window (measured;
# at 1.2 the figures filled 46 % of its width), 1.75 in a 16:10 one.
FOV_Y = np.radians(55.0)
FRAME_TAN = 0.9 * np.tan(FOV_Y / 2)
ASPECT = 1.75
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


def _score_views(criteria: tuple[str, ...], unified: bool, fitted: bool) -> list[rrb.View]:
    """The score tabs of :func:`blueprint`: m_hl(t) and m_f(t), the criteria by cluster, posture,
    solver and fit."""
    scores: list[rrb.View] = [_plot("/plots/unified", "m_hl(t), m_f(t) (1 = best)")] if unified else []
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
    return scores


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
    rows.append(rrb.Tabs(*_score_views(criteria, unified, fitted), active_tab=0))
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
            # short titles: three panels side by side (ARMAR-III) cut "left arm: joint angles" short
            _plot("/plots/joints", title, [f"/plots/joints/{_entity(j)}" for j in joints])
            for title, joints in joint_groups(robot).items()
        )
    )


def _joint_unit(model: mujoco.MjModel, name: str) -> str:
    return "m" if model.joint(name).type == mujoco.mjtJoint.mjJNT_SLIDE else "rad"


def scene_camera(traj: Trajectory, robot: Robot, layout: str = "side", samples: int = 24) -> Camera:
    """The opening camera of the scene, world frame: in front of the human (where its pelvis faces,
    on average over the take), a little above, as near as keeps every human and robot body, every
    hand target and every scene object where recorded inside the view cone with room to spare.

    Only ``samples`` frames spread over the take are looked at (forward kinematics of a few frames).
    """
    rows = slice(0, traj.n_frames, max(1, -(-traj.n_frames // samples)))
    human = human_model(traj.motion.height)
    human_pos, _ = body_poses(human, qpos_trajectory(human, traj.motion.frames(rows)))
    shown = _display_placement(traj, robot, layout)
    robot_pos = _robot_points(traj, robot, rows) @ shown.rotation.T + shown.translation
    objects = [o.position[rows] for o in traj.motion.objects.values()]  # NaN where unseen: dropped
    lift = np.array([0.0, 0.0, human_lift(traj.motion, layout)])  # the human's world as drawn
    points = np.concatenate(
        [
            human_pos[:, 1:].reshape(-1, 3) + lift,
            robot_pos,
            traj.placement.to_world(traj.targets.pos[rows]).reshape(-1, 3) + lift,
            *(o + lift for o in objects),
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
    every point, grown by ``margin`` m (the points are bodies' origins: a head reaches 0.1-0.2 m past
    its own), inside the pyramid of half-angles atan(:data:`FRAME_TAN`)
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
