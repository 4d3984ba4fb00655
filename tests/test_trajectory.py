"""Trajectory .npz round trip, bad files, and the pipeline's geometric properties."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import ROBOTS
from hlik import load_motion, load_robot
from hlik.criteria.functional import position_error, rotation_angle
from hlik.human.demo import demo_motion
from hlik.human.kinematics import forward_kinematics
from hlik.retarget import retarget
from hlik.robot.model import tcp_poses
from hlik.trajectory import load_trajectory
from hlik.util.errors import TrajectoryFormatError


@pytest.fixture(scope="module")
def demo():
    return demo_motion().crop(0.0, 3.0).resample(50.0)


def test_round_trip_keeps_every_array(tmp_path, takes):
    motion = load_motion(takes[0], rate=20.0)
    traj = retarget(motion, load_robot("armar3"))
    back = load_trajectory(traj.save(tmp_path / "t.npz"))
    assert (back.robot, back.solver, back.joint_names) == (traj.robot, traj.solver, traj.joint_names)
    for name in ("times", "q", "tcp_pos", "tcp_rot"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name))
    np.testing.assert_array_equal(back.targets.pos, traj.targets.pos)
    np.testing.assert_array_equal(back.targets.rot, traj.targets.rot)
    np.testing.assert_array_equal(back.placement.matrix, traj.placement.matrix)
    for name in ("q_map", "psi", "manip"):  # the human reference, stored, not recomputed
        np.testing.assert_array_equal(getattr(back.reference, name), getattr(traj.reference, name))
    for name in ("iterations", "converged", "failed", "solve_time"):
        np.testing.assert_array_equal(getattr(back.diagnostics, name), getattr(traj.diagnostics, name))
    ref, ref0 = back.motion, traj.motion
    assert ref.joint_names == ref0.joint_names and ref.height == ref0.height and ref.source == ref0.source
    np.testing.assert_array_equal(ref.joints, ref0.joints)
    assert set(ref.objects) == set(ref0.objects) and ref.objects
    for name, obj in ref0.objects.items():
        np.testing.assert_array_equal(ref.objects[name].rotation, obj.rotation)
        assert set(ref.objects[name].markers) == set(obj.markers)
    # the stored motion reproduces the human; the stored TCP poses are the FK of the stored q
    np.testing.assert_allclose(forward_kinematics(back.motion).tcp_pos, forward_kinematics(motion).tcp_pos)
    np.testing.assert_allclose(tcp_poses(load_robot("armar3"), back.q)[0], back.tcp_pos)


def test_save_is_atomic_and_leaves_no_temporary(tmp_path, demo):
    traj = retarget(demo, load_robot("dual_panda"))
    traj.save(tmp_path / "t.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["t.npz"]
    with pytest.raises(OSError):
        traj.save(tmp_path / "missing" / "t.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["t.npz"]


@pytest.mark.parametrize(
    "content,pattern",
    [
        (b"not a zip", "not a readable trajectory .npz"),
        (None, "not an hlik trajectory"),
    ],
)
def test_bad_files_name_the_file(tmp_path, content, pattern):
    path = tmp_path / "bad.npz"
    if content is None:
        np.savez(path, q=np.zeros((2, 3)))
    else:
        path.write_bytes(content)
    with pytest.raises(TrajectoryFormatError, match=pattern) as err:
        load_trajectory(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(TrajectoryFormatError, match="no such file"):
        load_trajectory(tmp_path / "missing.npz")


def test_inconsistent_shapes_are_refused(tmp_path, demo):
    path = retarget(demo, load_robot("armar6")).save(tmp_path / "t.npz")
    with np.load(path) as z:
        arrays = dict(z)
    arrays["q"] = arrays["q"][:, :-1]
    np.savez(path, **arrays)
    with pytest.raises(TrajectoryFormatError, match=r"q has shape .* expected"):
        load_trajectory(path)


def test_the_scenario_is_stored_and_files_without_it_still_read(tmp_path, demo):
    traj = retarget(demo, load_robot("armar6"))
    assert traj.scenario is None and load_trajectory(traj.save(tmp_path / "none.npz")).scenario is None
    for scenario in ("pose", "relative"):
        back = load_trajectory(replace(traj, scenario=scenario).save(tmp_path / f"{scenario}.npz"))
        assert back.scenario == scenario
    with np.load(tmp_path / "relative.npz") as z:
        arrays = dict(z)
    del arrays["scenario"]  # a file written before the scenario was stored
    np.savez(tmp_path / "older.npz", **arrays)
    assert load_trajectory(tmp_path / "older.npz").scenario is None
    arrays["scenario"] = np.array("relatve")
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(
        TrajectoryFormatError, match="bad.npz: scenario is 'relatve', expected pose or relative"
    ):
        load_trajectory(tmp_path / "bad.npz")
    with pytest.raises(ValueError, match="scenario"):  # nor written: it would be refused on reading
        replace(traj, scenario="Relative")


@pytest.mark.parametrize("robot", ROBOTS)
def test_jm_on_every_take_is_finite_and_within_limits(robot, takes):
    r = load_robot(robot)
    for take in takes:
        traj = retarget(load_motion(take, rate=25.0), r, "jm")
        assert np.all(np.isfinite(traj.q)), take.name
        assert np.all(traj.q >= r.lower - 1e-12) and np.all(traj.q <= r.upper + 1e-12), take.name
        extra = r.index(r.extra_joints) if r.extra_joints else np.array([], int)
        np.testing.assert_array_equal(
            traj.q[:, extra], np.broadcast_to(r.home[extra], (traj.n_frames, len(extra)))
        )


@pytest.mark.parametrize("robot", ROBOTS)
def test_jm_follows_the_mapping_where_limits_allow(robot, demo):
    r = load_robot(robot)
    q = retarget(demo, r).q
    mapped = r.mapping.apply(demo.joint_names, demo.joints)
    for name, angles in mapped.items():
        inside = (angles > r.lower[r.index(name)]) & (angles < r.upper[r.index(name)])
        np.testing.assert_allclose(q[inside, r.index(name)], angles[inside])


def test_targets_do_not_depend_on_where_the_human_stands(demo):
    """Turning and moving the whole recording over the floor leaves targets and errors in the robot
    frame unchanged; lifting it (a subject on a 10 cm step) lifts the targets, the robot stays on
    its floor (README "Placement")."""
    turn = Rotation.from_euler("z", 1.1).as_matrix()
    shift, lift = np.array([2.0, -3.0, 0.0]), np.array([0.0, 0.0, 0.1])
    moved = replace(
        demo,
        root_position=demo.root_position @ turn.T + shift + lift,
        root_rotation=turn @ demo.root_rotation,
    )
    r = load_robot("armar3")
    a, b = retarget(demo, r), retarget(moved, r)
    np.testing.assert_allclose(b.targets.pos, a.targets.pos + lift, atol=1e-9)
    np.testing.assert_allclose(b.targets.rot, a.targets.rot, atol=1e-9)
    np.testing.assert_allclose(b.placement.translation[2], a.placement.translation[2])
    np.testing.assert_allclose(
        b.placement.to_world(b.tcp_pos), a.placement.to_world(a.tcp_pos) @ turn.T + shift
    )


def test_tracking_errors_are_metrics():
    rng = np.random.default_rng(3)
    ra, rb = Rotation.random(50, random_state=rng), Rotation.random(50, random_state=rng)
    a, b = ra.as_matrix(), rb.as_matrix()
    np.testing.assert_allclose(rotation_angle(a, b), (ra.inv() * rb).magnitude(), atol=1e-7)
    np.testing.assert_allclose(rotation_angle(a, b), rotation_angle(b, a))
    np.testing.assert_allclose(rotation_angle(a, a), 0.0, atol=2e-8)
    p, t = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    np.testing.assert_allclose(position_error(p, t), np.sqrt(((p - t) ** 2).sum(1)))


def test_format_1_files_are_refused_with_a_reason(tmp_path, demo):
    path = retarget(demo.crop(0, 0.1), load_robot("armar3")).save(tmp_path / "t.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["format"] = np.array("hlik.trajectory/1")
    old = tmp_path / "old.npz"
    np.savez(old, **arrays)
    with pytest.raises(TrajectoryFormatError, match="hlik.trajectory/1.*run hlik run again"):
        load_trajectory(old)


def test_format_2_files_are_read_or_named_as_older(tmp_path, demo):
    """Format 2 gained arrays without a new number: a file of 3's layout marked 2 is read; one
    written before an array was added is called older, not broken ("missing array")."""
    traj = retarget(demo.crop(0, 0.1), load_robot("armar3"))
    path = traj.save(tmp_path / "t.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    assert str(arrays["format"]) == "hlik.trajectory/3"
    arrays["format"] = np.array("hlik.trajectory/2")
    np.savez(tmp_path / "two.npz", **arrays)
    np.testing.assert_array_equal(load_trajectory(tmp_path / "two.npz").q, traj.q)
    del arrays["base_method"]
    np.savez(tmp_path / "older.npz", **arrays)
    with pytest.raises(
        TrajectoryFormatError, match="older hlik.trajectory/2 layout .*'base_method'.*run hlik run"
    ):
        load_trajectory(tmp_path / "older.npz")
    arrays["format"] = np.array("hlik.trajectory/4")  # a newer hlik's: not "run hlik run again"
    np.savez(tmp_path / "newer.npz", **arrays)
    with pytest.raises(TrajectoryFormatError, match="hlik.trajectory/4 by a newer hlik.*update hlik"):
        load_trajectory(tmp_path / "newer.npz")
