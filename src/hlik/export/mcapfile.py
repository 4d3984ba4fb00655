"""A trajectory as an MCAP file of ROS 2 messages (``ros2msg`` schemas, CDR encoding), which
Foxglove and ``ros2 bag play`` read:

- ``/joint_states``: ``sensor_msgs/msg/JointState`` per frame (names, positions in rad,
  velocities in rad/s by the differencing of :func:`hlik.executable.joint_velocity`);
- ``/joint_trajectory``: one ``trajectory_msgs/msg/JointTrajectory`` with every frame as a point
  (positions, velocities, ``time_from_start``), at the first frame's time;
- ``/hlik/info``: one ``std_msgs/msg/String``, JSON: robot, solver, joint names, the limit a
  controller would reject (``null`` unless exported with ``--allow-violations``) and
  ``braking_frames``, how many of the last frames bring the joints to rest (:mod:`hlik.braking`;
  their targets hold the last frame's);
- ``/tcp_target/left``, ``/tcp_target/right``: ``geometry_msgs/msg/PoseStamped`` per frame, the
  hands' targets in the robot base frame (``frame_id`` ``base``; quaternions x, y, z, w as ROS has
  them).

Times start at 0 (the first frame); message stamps and log times agree.
"""

from __future__ import annotations

import json
from pathlib import Path

from scipy.spatial.transform import Rotation

from hlik.executable import joint_velocity
from hlik.robot.model import SIDES, Robot
from hlik.trajectory import Trajectory
from hlik.util.errors import HlikError

SEPARATOR = "=" * 80
TIME = "int32 sec\nuint32 nanosec"
HEADER = "builtin_interfaces/Time stamp\nstring frame_id"
DEFINITIONS = {
    "builtin_interfaces/Time": TIME,
    "builtin_interfaces/Duration": TIME,
    "std_msgs/Header": HEADER,
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    "geometry_msgs/Pose": "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
    "trajectory_msgs/JointTrajectoryPoint": (
        "float64[] positions\nfloat64[] velocities\nfloat64[] accelerations\nfloat64[] effort\n"
        "builtin_interfaces/Duration time_from_start"
    ),
}
MESSAGES = {  # message -> (its fields, the definitions it uses, in order)
    "sensor_msgs/msg/JointState": (
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort",
        ("std_msgs/Header", "builtin_interfaces/Time"),
    ),
    "trajectory_msgs/msg/JointTrajectory": (
        "std_msgs/Header header\nstring[] joint_names\ntrajectory_msgs/JointTrajectoryPoint[] points",
        ("std_msgs/Header", "builtin_interfaces/Time", "trajectory_msgs/JointTrajectoryPoint",
         "builtin_interfaces/Duration"),
    ),
    "std_msgs/msg/String": ("string data", ()),
    "geometry_msgs/msg/PoseStamped": (
        "std_msgs/Header header\ngeometry_msgs/Pose pose",
        ("std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/Pose", "geometry_msgs/Point",
         "geometry_msgs/Quaternion"),
    ),
}  # fmt: skip


def msgdef(datatype: str) -> str:
    """The ``ros2msg`` definition of ``datatype`` with the definitions it depends on."""
    fields, uses = MESSAGES[datatype]
    return "\n".join([fields, *(f"{SEPARATOR}\nMSG: {name}\n{DEFINITIONS[name]}" for name in uses)])


def _stamp(t: float) -> dict:
    ns = int(round(t * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def write(traj: Trajectory, robot: Robot, path: Path, violation: str | None = None, braking: int = 0) -> None:
    """Write ``traj`` to ``path`` (see the module docstring); ``violation`` (exported anyway) goes
    into the file's metadata ``hlik``."""
    try:
        from mcap_ros2.writer import Writer
    except ImportError:
        raise HlikError('exporting MCAP needs mcap-ros2-support: pip install -e ".[ros]"') from None

    times = traj.times - traj.times[0]
    velocity = joint_velocity(traj, robot)
    names = list(traj.joint_names)
    with open(path, "wb") as f:
        writer = Writer(f)
        schemas = {name: writer.register_msgdef(name, msgdef(name)) for name in MESSAGES}
        state, trajectory, text, pose = (schemas[n] for n in MESSAGES)
        info = {
            "robot": robot.name,
            "solver": traj.solver,
            "joint_names": names,
            "violation": violation,
            "braking_frames": braking,
        }
        writer.write_message("/hlik/info", text, {"data": json.dumps(info)}, log_time=0, publish_time=0)
        points = [
            {"positions": q.tolist(), "velocities": v.tolist(), "accelerations": [], "effort": [],
             "time_from_start": _stamp(t)}
            for t, q, v in zip(times, traj.q, velocity)
        ]  # fmt: skip
        writer.write_message(
            "/joint_trajectory",
            trajectory,
            {"header": {"stamp": _stamp(0.0), "frame_id": "base"}, "joint_names": names, "points": points},
            log_time=0,
            publish_time=0,
        )
        quats = Rotation.from_matrix(traj.targets.rot.reshape(-1, 3, 3)).as_quat().reshape(-1, 2, 4)
        for k, t in enumerate(times):
            ns, header = int(round(t * 1e9)), {"stamp": _stamp(t), "frame_id": "base"}
            message = {
                "header": header,
                "name": names,
                "position": traj.q[k].tolist(),
                "velocity": velocity[k].tolist(),
            }
            writer.write_message(
                "/joint_states", state, {**message, "effort": []}, log_time=ns, publish_time=ns
            )
            for a, side in enumerate(SIDES):
                p, (x, y, z, w) = traj.targets.pos[k, a], quats[k, a]
                orientation = {"x": float(x), "y": float(y), "z": float(z), "w": float(w)}
                target = {"position": dict(zip("xyz", p.tolist())), "orientation": orientation}
                writer.write_message(
                    f"/tcp_target/{side}",
                    pose,
                    {"header": header, "pose": target},
                    log_time=ns,
                    publish_time=ns,
                )
        writer.finish()
