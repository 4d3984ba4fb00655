"""Exports (issue 31): what a file gives back is the trajectory, by joint name, to the bit; a
trajectory a controller would reject is refused naming the frame and joint."""

from __future__ import annotations

import csv
import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from hlik import load_motion, load_robot, retarget
from hlik.braking import brought_to_rest
from hlik.cli import app
from hlik.export import export, first_violation
from hlik.export.csvfile import BASE_COLUMNS
from hlik.util.errors import HlikError
from hlik.util.paths import demo_motion_path


@pytest.fixture(scope="module")
def panda_qp():
    robot = load_robot("dual_panda")
    return robot, retarget(load_motion(demo_motion_path(), rate=100).crop(0, 0.6), robot, "qp")


def _read_csv(path):
    with open(path, newline="", encoding="utf-8") as f:
        lines = f.read().splitlines()
    comments = [line[2:] for line in lines if line.startswith("# ")]
    rows = list(csv.reader(line for line in lines if not line.startswith("#")))
    return comments, rows[0], np.array(rows[1:], dtype=float)


def test_csv_round_trip_gives_back_names_times_angles_and_base_exactly(panda_qp, tmp_path):
    """The take's rows are the trajectory to the bit; the rows after them brake it to rest (the
    demo's first 0.6 s end moving, which held would break the acceleration limit)."""
    robot, traj = panda_qp
    assert "the last, held after it" in first_violation(traj, robot)  # ends moving: a controller stops it
    rest, stop = brought_to_rest(traj, robot)
    assert stop.n_frames > 0 and first_violation(rest, robot) is None  # the QP keeps every limit
    path = export(traj, robot, tmp_path / "t.csv", "csv")
    comments, names, table = _read_csv(path)
    assert names == ["time", *robot.joint_names, *BASE_COLUMNS]
    take = slice(0, traj.n_frames)
    np.testing.assert_array_equal(table[take, 0], traj.times - traj.times[0])
    np.testing.assert_array_equal(table[take, 1 : 1 + robot.dof], traj.q)
    np.testing.assert_array_equal(table[traj.n_frames :, 1 : 1 + robot.dof], stop.q)
    np.testing.assert_allclose(np.diff(table[:, 0]), traj.period)
    braking = f"braking rows: the last {stop.n_frames} ("
    assert any(c.startswith(braking) and "the hands move on up to" in c for c in comments)
    base = table[:, 1 + robot.dof :]
    assert np.all(base == base[0])
    np.testing.assert_array_equal(base[0, :3], traj.placement.translation)
    w, x, y, z = base[0, 3:]
    np.testing.assert_allclose(
        Rotation.from_quat([x, y, z, w]).as_matrix(), traj.placement.rotation, atol=1e-12
    )
    assert any("quaternion order w, x, y, z" in c for c in comments)
    assert any("100 Hz" in c and "dual_panda" in c for c in comments)


def test_columns_follow_the_names_not_the_positions(panda_qp, tmp_path):
    """A reader that picks columns by name gets each joint's own angles (GMR users matched by
    column position and got another joint's)."""
    robot, traj = panda_qp
    _, names, table = _read_csv(export(traj, robot, tmp_path / "t.csv"))
    for j, name in enumerate(robot.joint_names):
        np.testing.assert_array_equal(table[: traj.n_frames, names.index(name)], traj.q[:, j])


@pytest.mark.parametrize("kind", ["position", "speed", "acceleration"])
def test_a_trajectory_a_controller_rejects_is_refused_naming_frame_and_joint(panda_qp, tmp_path, kind):
    """Each limit alone: the joint's path shifted past its stop (no speed changes), a constant 5
    rad/s drift (checked with acceleration limits lifted: from rest any drift accelerates first),
    a step into frame 20 (seen at frame 19, where the robot would have to accelerate)."""
    robot, traj = panda_qp
    q = traj.q.copy()
    j = robot.joint_names.index("left_joint4")
    if kind == "position":
        q[:, j] += robot.upper[j] + 0.01 - q[:, j].max()
        frame = int(np.argmax(q[:, j] > robot.upper[j]))
    elif kind == "speed":
        q[:, j] += 5.0 * (traj.times - traj.times[0])
        robot = dataclasses.replace(robot, acceleration_limit=np.full(robot.dof, np.inf))
        robot = dataclasses.replace(robot, effort_limit=np.full(robot.dof, np.inf))
        frame = 1
    else:
        q[20:, j] -= 0.05
        frame = 19
    bad = dataclasses.replace(traj, q=q)
    message = first_violation(bad, robot)
    assert (
        message is not None
        and message.startswith(f"frame {frame} (")
        and f"joint left_joint4 {kind}" in message
    )
    with pytest.raises(HlikError, match=f"not exported: frame {frame} ") as e:
        export(bad, robot, tmp_path / "bad.csv")
    assert "\n" not in str(e.value) and not (tmp_path / "bad.csv").exists()
    comments, _, _ = _read_csv(export(bad, robot, tmp_path / "bad.csv", allow_violations=True))
    assert any(
        c.startswith("WARNING: exported with --allow-violations") and f"frame {frame} " in c for c in comments
    )


def test_hlik_export_refuses_a_jm_run_and_writes_a_qp_run(tmp_path):
    """JM maps joint angles without the speed limits; the QP keeps them. ``hlik run --export``
    writes the export beside the run's files, or says in a warning why not."""
    runner = CliRunner()
    runs = {}
    for solver in ("jm", "qp"):
        out = tmp_path / f"{solver}.rrd"
        args = ["run", "--robot", "armar6", "--solver", solver, "-o", str(out), "--export", "lerobot"]
        runs[solver] = runner.invoke(app, args)
        assert runs[solver].exit_code == 0, runs[solver].output
    assert "not exported: frame" in runs["jm"].stderr and "--allow-violations --force" in runs["jm"].stderr
    assert not (tmp_path / "jm_lerobot").exists()
    assert (tmp_path / "qp_lerobot" / "meta" / "info.json").is_file() and "exported: " in runs["qp"].stdout
    refused = runner.invoke(app, ["export", str(tmp_path / "jm.npz")])
    assert refused.exit_code == 2 and "not exported: frame" in refused.output
    assert not (tmp_path / "jm.csv").exists()
    written = runner.invoke(app, ["export", str(tmp_path / "qp.npz")])
    assert written.exit_code == 0, written.output
    assert (tmp_path / "qp.csv").is_file()
    again = runner.invoke(app, ["export", str(tmp_path / "qp.npz")])
    assert again.exit_code == 2 and "exists; pass --force" in again.output


def test_mcap_round_trip_through_the_ros2_reader(panda_qp, tmp_path):
    """Read back with mcap-ros2-support's own reader: joint states by name with the positions and
    the velocities the checks use, the whole trajectory, the hands' target poses, all at the frames'
    times (ns)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from hlik.executable import joint_velocity

    robot, traj = panda_qp
    path = export(traj, robot, tmp_path / "t.mcap", "mcap")
    traj, stop = brought_to_rest(traj, robot)  # what an export writes: the take, then its braking
    topics: dict[str, list] = {}
    with open(path, "rb") as f:
        for _, channel, message, ros_msg in make_reader(
            f, decoder_factories=[DecoderFactory()]
        ).iter_decoded_messages():
            topics.setdefault(channel.topic, []).append((message.log_time, ros_msg))
    n = traj.n_frames
    expected = {"/hlik/info": 1, "/joint_trajectory": 1}
    expected |= {"/joint_states": n, "/tcp_target/left": n, "/tcp_target/right": n}
    assert {k: len(v) for k, v in topics.items()} == expected
    times_ns = np.round((traj.times - traj.times[0]) * 1e9).astype(int)
    states = topics["/joint_states"]
    assert [t for t, _ in states] == list(times_ns)
    assert all(list(m.name) == list(robot.joint_names) for _, m in states)
    np.testing.assert_array_equal([m.position for _, m in states], traj.q)
    np.testing.assert_array_equal([m.velocity for _, m in states], joint_velocity(traj, robot))
    whole = topics["/joint_trajectory"][0][1]
    assert list(whole.joint_names) == list(robot.joint_names)
    np.testing.assert_array_equal([p.positions for p in whole.points], traj.q)
    stamps = [p.time_from_start.sec * 10**9 + p.time_from_start.nanosec for p in whole.points]
    assert stamps == list(times_ns)
    for a, side in enumerate(("left", "right")):
        poses = [m.pose for _, m in topics[f"/tcp_target/{side}"]]
        pos = [[p.position.x, p.position.y, p.position.z] for p in poses]
        np.testing.assert_array_equal(pos, traj.targets.pos[:, a])
        quat = [[p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w] for p in poses]
        np.testing.assert_allclose(Rotation.from_quat(quat).as_matrix(), traj.targets.rot[:, a], atol=1e-12)
    assert '"violation": null' in topics["/hlik/info"][0][1].data
    assert f'"braking_frames": {stop.n_frames}' in topics["/hlik/info"][0][1].data and stop.n_frames > 0


def test_mcap_reads_as_a_ros2_bag(panda_qp, tmp_path):
    """rosbags (a second, independent reader of rosbag2 storage, with ROS 2 Humble's message
    definitions) opens the file as a bag: the topics, types and counts, and every message decoded
    with the values and times the trajectory holds."""
    pytest.importorskip("rosbags", reason='pip install -e ".[test]"')
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    robot, traj = panda_qp
    path = export(traj, robot, tmp_path / "t.mcap", "mcap")
    traj, _ = brought_to_rest(traj, robot)  # what an export writes: the take, then its braking
    n, got = traj.n_frames, {}
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as bag:
        types = {c.topic: (c.msgtype, c.msgcount) for c in bag.connections}
        for conn, stamp, raw in bag.messages():
            got.setdefault(conn.topic, []).append((stamp, bag.deserialize(raw, conn.msgtype)))
    assert types == {
        "/hlik/info": ("std_msgs/msg/String", 1),
        "/joint_trajectory": ("trajectory_msgs/msg/JointTrajectory", 1),
        "/joint_states": ("sensor_msgs/msg/JointState", n),
        "/tcp_target/left": ("geometry_msgs/msg/PoseStamped", n),
        "/tcp_target/right": ("geometry_msgs/msg/PoseStamped", n),
    }
    states = got["/joint_states"]
    assert [t for t, _ in states] == list(np.round((traj.times - traj.times[0]) * 1e9).astype(int))
    assert all(list(m.name) == list(robot.joint_names) for _, m in states)
    np.testing.assert_array_equal([m.position for _, m in states], traj.q)
    whole = got["/joint_trajectory"][0][1]
    np.testing.assert_array_equal([p.positions for p in whole.points], traj.q)
    left = [[m.pose.position.x, m.pose.position.y, m.pose.position.z] for _, m in got["/tcp_target/left"]]
    np.testing.assert_array_equal(left, traj.targets.pos[:, 0])


def test_an_output_named_for_another_format_is_refused(tmp_path):
    runner = CliRunner()
    out = tmp_path / "qp.rrd"
    assert (
        runner.invoke(app, ["run", "--robot", "dual_panda", "--solver", "qp", "-o", str(out)]).exit_code == 0
    )
    result = runner.invoke(
        app, ["export", str(out.with_suffix(".npz")), "--format", "mcap", "--out", str(tmp_path / "x.csv")]
    )
    assert result.exit_code == 2 and "--format mcap writes .mcap files" in result.output
    assert not (tmp_path / "x.csv").exists()


def test_lerobot_round_trip_gives_back_names_times_state_and_action(panda_qp, tmp_path):
    """The LeRobot v3 folder read back with pyarrow (and with LeRobot's own loader where it is
    installed; it needs PyTorch): the joints by name, the frames' times, state = q, action = the
    next q, the layout's metadata consistent."""
    import json

    import pyarrow.parquet as pq

    robot, traj = panda_qp
    folder = export(traj, robot, tmp_path / "take_lerobot", "lerobot")
    traj, stop = brought_to_rest(traj, robot)  # what an export writes: the take, then its braking
    info = json.loads((folder / "meta" / "info.json").read_text())
    assert info["hlik_braking_frames"] == stop.n_frames > 0
    assert info["codebase_version"] == "v3.0" and info["fps"] == 100 and info["total_frames"] == traj.n_frames
    assert info["features"]["observation.state"]["names"] == list(robot.joint_names)
    data = pq.read_table(folder / info["data_path"].format(chunk_index=0, file_index=0)).to_pydict()
    state, action = np.array(data["observation.state"]), np.array(data["action"])
    np.testing.assert_array_equal(state, traj.q.astype(np.float32))
    np.testing.assert_array_equal(action[:-1], state[1:])
    np.testing.assert_array_equal(action[-1], state[-1])
    np.testing.assert_allclose(data["timestamp"], traj.times - traj.times[0], atol=1e-6)
    assert data["index"] == data["frame_index"] == list(range(traj.n_frames))
    episode = pq.read_table(folder / "meta/episodes/chunk-000/file-000.parquet").to_pylist()[0]
    assert episode["length"] == episode["dataset_to_index"] == traj.n_frames
    tasks = pq.read_table(folder / "meta" / "tasks.parquet")
    assert tasks.column("task").to_pylist() == episode["tasks"] and tasks.schema.pandas_metadata[
        "index_columns"
    ] == ["task"]
    stats = json.loads((folder / "meta" / "stats.json").read_text())
    np.testing.assert_allclose(stats["action"]["max"], action.max(axis=0), rtol=1e-6)
    try:
        from lerobot.datasets.lerobot_dataset import LeRobotDataset
    except ImportError:
        return
    dataset = LeRobotDataset("local/take", root=folder)
    assert len(dataset) == traj.n_frames and dataset.fps == 100
    np.testing.assert_array_equal(dataset[7]["action"].numpy(), state[8])
