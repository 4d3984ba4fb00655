"""Robots from elsewhere: a URDF or MJCF plus a TOML, compiled with MjSpec (issue 17). The worked
example is the Unitree G1 of the pip package example-robot-data (the ``g1`` extra)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import G1, require_g1
from hlik.cli import app
from hlik.robot.collision import collision_pairs
from hlik.robot.model import COLLISION_GROUP, SIDES, SITES, load_robot, self_contacts, tcp_poses
from hlik.util.errors import RobotError
from hlik.util.paths import robots_dir
from hlik.util.spatial import site_poses


@pytest.fixture(scope="module")
def g1():
    require_g1()
    return load_robot(str(G1))


def test_g1_is_compiled_for_hlik(g1):
    """Legs and waist welded, the sites added, collision geoms where hlik looks, URDF speed limits."""
    assert g1.dof == 14 and g1.joint_names == g1.arm_joints["left"] + g1.arm_joints["right"]
    for side in SIDES:
        for site in SITES:
            g1.site_id(side, site)
    m = g1.model
    colliding = (m.geom_contype | m.geom_conaffinity) > 0
    assert np.all(m.geom_group[colliding] == COLLISION_GROUP) and np.any(
        m.geom_type == mujoco.mjtGeom.mjGEOM_MESH
    )
    assert not self_contacts(g1, g1.home) and len(collision_pairs(g1)) > 50
    np.testing.assert_allclose(g1.velocity_limit[g1.index("left_wrist_pitch_joint")], 22.0)
    assert "URDF <limit velocity>" in g1.velocity_source
    # standing on the floor, facing +y: the left shoulder on the left (-x), the hands in front
    pos, _ = site_poses(m, g1.home[None], g1.site_ids[:, [0, 3]].reshape(-1))
    left_shoulder, left_tcp, right_shoulder, _ = pos[0]
    assert left_shoulder[0] < 0 < right_shoulder[0] and 1.0 < left_shoulder[2] < 1.2 and left_tcp[1] > 0.15


def test_calibrate_writes_the_mapping_the_example_carries(g1, tmp_path):
    """`hlik calibrate X.toml --write` on a copy without mapping derives the stored one."""
    copy = tmp_path / "g1.toml"
    text = G1.read_text()
    copy.write_text(text[: text.index("[mapping.left]")])
    with pytest.raises(RobotError, match=r"no mapping for arm joint\(s\).*hlik calibrate .* --write"):
        load_robot(str(copy))
    result = CliRunner().invoke(app, ["calibrate", str(copy), "--write"])
    assert result.exit_code == 0, result.output
    assert load_robot(str(copy)).mapping == g1.mapping
    assert "matches" in CliRunner().invoke(app, ["calibrate", str(copy)]).output


def _armar3_copy(tmp_path: Path, edit, model_edit=lambda m: m) -> Path:
    """robots/armar3.toml beside a copy of its model, edited by ``edit(text) -> text`` (the model by
    ``model_edit``)."""
    (tmp_path / "mjcf").mkdir(exist_ok=True)
    model = (robots_dir() / "mjcf" / "armar3.xml").read_text()
    (tmp_path / "mjcf" / "armar3.xml").write_text(model_edit(model))
    path = tmp_path / "mine.toml"
    path.write_text(edit((robots_dir() / "armar3.toml").read_text()))
    return path


def test_a_joint_left_out_is_welded_at_its_home_angle(tmp_path):
    """Welding the hip yaw at 0.3 rad gives the TCPs of the full model with the hip at 0.3 rad."""
    full = load_robot("armar3")
    path = _armar3_copy(
        tmp_path,
        lambda t: (
            t.replace('extra_joints = ["HipPitch", "HipYaw"]', 'extra_joints = ["HipPitch"]')
            .replace("[home]", "[home]\nHipYaw = 0.3", 1)
            .replace('joints = ["HipPitch", "HipYaw"]', 'joints = ["HipPitch"]')
        ),
    )
    text = path.read_text()
    text = "\n".join(line for line in text.splitlines() if not line.startswith("HipYaw = ") or "0.3" in line)
    path.write_text(text)
    welded = load_robot(str(path))
    assert "HipYaw" not in welded.joint_names and welded.dof == full.dof - 1
    rng = np.random.default_rng(3)
    q = np.clip(full.home + rng.normal(0, 0.3, (5, full.dof)), full.lower, full.upper)
    q[:, full.index("HipYaw")] = 0.3
    keep = full.index(welded.joint_names)
    a, _ = site_poses(full.model, q, full.site_ids.reshape(-1))
    b, _ = site_poses(welded.model, q[:, keep], welded.site_ids.reshape(-1))
    np.testing.assert_allclose(a, b, atol=1e-9)


def test_base_pose_turns_and_lifts_the_whole_robot(tmp_path):
    full = load_robot("armar3")
    path = _armar3_copy(tmp_path, lambda t: t + "\n[base]\npos = [0.1, -0.2, 0.3]\nrpy = [0.0, 0.0, 0.5]\n")
    moved = load_robot(str(path))
    a, _ = site_poses(full.model, full.home[None], full.site_ids.reshape(-1))
    b, _ = site_poses(moved.model, moved.home[None], moved.site_ids.reshape(-1))
    c, s = np.cos(0.5), np.sin(0.5)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    np.testing.assert_allclose(b[0], a[0] @ turn.T + [0.1, -0.2, 0.3], atol=1e-9)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t.replace('"mjcf/armar3.xml"', '"package://no-such-pkg/armar3.xml"'),
         r"mine.toml: package 'no-such-pkg' .* \[package_dirs\] no-such-pkg ="),
        (lambda t: t.replace('"mjcf/armar3.xml"', '"mjcf/armar9.xml"'),
         r"mine.toml: model 'mjcf/armar9.xml' not found"),
        (lambda t: t.replace('"HipPitch", "HipYaw"]', '"HipPitch", "Hip_Yaw"]', 1),
         r"joints not in the model armar3.xml: Hip_Yaw"),
        (lambda t: t + '\n[sites]\nx_site = { body = "no_body" }\n', r"\[sites\] x_site: no body 'no_body'"),
        (lambda t: t + '\n[sites]\nleft_tcp = { body = "base" }\n', r"already has a site left_tcp"),
        (lambda t: t + '\n[collision]\nexclude = [["base"]]\n',
         r"\[collision\] exclude entries must be \[body, body\]"),
        (lambda t: t + '\n[base]\nrpy = [0, 0]\n', r"\[base\] rpy must be three finite numbers"),
    ],
)  # fmt: skip
def test_foreign_model_mistakes_are_one_line_naming_the_file(tmp_path, edit, message):
    with pytest.raises(RobotError, match=message):
        load_robot(str(_armar3_copy(tmp_path, edit)))


_ELBOW = '<joint name="Elbow_L" axis="0.965925826 0 -0.258819045" range="-2.146057 0.959931"/>'
_TCP = '<site name="left_tcp" pos="0 0.13 0" xyaxes="0.258819045 0 0.965925826 0.965925826 0 -0.258819045"/>'


def _swap_arms(t: str) -> str:
    swapped = t.replace("[arms.left]", "[arms.x]").replace("[arms.right]", "[arms.left]")
    return swapped.replace("[arms.x]", "[arms.right]")


@pytest.mark.parametrize(
    ("edit", "model_edit", "message"),
    [
        (lambda t: t, lambda m: m.replace('range="-2.146057 0.959931"', 'range="-122.96 55.0"'),
         r"armar3.xml: joint Elbow_L: range -122.96 to 55 rad, 178 rad wide: degrees"),
        (lambda t: t.replace("unlimited_joints = []\n", ""), lambda m: m.replace(_ELBOW, _ELBOW.replace(
            ' range="-2.146057 0.959931"', "")),
         r"mine.toml: the model gives Elbow_L no range; give it one, or list it in unlimited_joints"),
        (_swap_arms, lambda m: m,
         r"mine.toml: \[arms\] right: Shoulder1_L, .* move left_tcp, the left TCP \(the arms' joint lists "
         r"swapped\?\)"),
        (lambda t: t.replace("[effort_limits]", "[effort_limits]\nElbow_L = 0.02", 1).replace(
            "Elbow_L = 20.0\n", ""), lambda m: m,
         r"mine.toml: \[effort_limits\] Elbow_L = 0.02 N m cannot hold the home pose against gravity"),
        (lambda t: t, lambda m: m.replace(_TCP, "").replace(_ELBOW, _ELBOW + _TCP),
         r"mine.toml: \[arms\] left: Underarm_L, Wrist1_L, Wrist2_L do not move left_tcp"),
        (lambda t: t.replace("HipYaw = 1.0\n", "HipYaw = 57.3\n", 1).replace(
            "HipPitch = 1.0\n", "HipPitch = 90.0\n", 1), lambda m: m,
         r"mine.toml: \[velocity_limits\] HipPitch = 90 rad/s is faster than any robot joint .* in "
         r"degrees\? write rad/s"),
        (lambda t: t.replace("HipPitch = 10.0\n", "HipPitch = 5730\n", 1), lambda m: m,
         r"mine.toml: \[acceleration_limits\] HipPitch = 5730 rad/s\^2 is faster than any robot joint"),
    ],
)  # fmt: skip
def test_description_mistakes_that_would_retarget_wrongly_are_refused(tmp_path, edit, model_edit, message):
    """A range in degrees, a range left out, arms swapped, an effort in kN m, a TCP on the forearm,
    a speed or an acceleration in degrees:
    one line naming the file and the joint, before anything is retargeted (they had run with every
    limit off, or ended in a traceback from the manipulability or the calibration)."""
    toml = (robots_dir() / "armar3.toml").read_text()
    model = (robots_dir() / "mjcf" / "armar3.xml").read_text()
    assert edit(toml) != toml or model_edit(model) != model  # the mistake was made
    path = _armar3_copy(tmp_path, edit, model_edit)
    with pytest.raises(RobotError, match=message):
        load_robot(str(path))


def test_a_missing_mesh_names_the_urdf_and_the_mesh(tmp_path, g1):
    urdf = g1.model_file
    copy = tmp_path / "urdf" / urdf.name
    copy.parent.mkdir()
    copy.write_text(
        urdf.read_text().replace("package://example-robot-data/robots/g1_description/meshes/", "../meshes/")
    )
    toml = tmp_path / "g1.toml"
    toml.write_text(
        G1.read_text().replace(
            f'"package://example-robot-data/robots/g1_description/urdf/{urdf.name}"', f'"urdf/{urdf.name}"'
        )
    )
    with pytest.raises(RobotError, match=rf"{urdf.name}: mesh '../meshes/pelvis.STL' not found"):
        load_robot(str(toml))


@pytest.mark.parametrize("solver", ["jm", "jv", "qp", "slsqp"])
def test_g1_runs_every_solver_on_a_bvh_and_evaluates(g1, tmp_path, solver):
    """The whole pipeline on the worked example: BVH in, recording and scores out."""
    pytest.importorskip("bvhio")
    from test_any_motion import _bvh

    n = 15
    frames = np.zeros((n, 33))
    frames[:, 1] = 95.0
    frames[:, 13] = frames[:, 16] = -np.linspace(20, 70, n)
    frames[:, 25] = frames[:, 28] = -np.linspace(20, 50, n)
    motion = tmp_path / "reach.bvh"
    _bvh(motion, frames)
    runner = CliRunner()
    out = tmp_path / "g1.rrd"
    args = ["run", str(motion), "--robot", str(G1), "--solver", solver, "-o", str(out)]
    args += ["--criteria", "SYN,HJA_r"] if solver in ("qp", "slsqp") else []
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert out.stat().st_size > 1e6  # the meshes are in it
    evaluated = runner.invoke(app, ["evaluate", str(out.with_suffix(".npz")), "--json"])
    assert evaluated.exit_code == 0, evaluated.output
    assert '"m_hl"' in evaluated.output


def test_a_study_runs_on_the_g1(g1, tmp_path):
    from hlik.study.approaches import Approach
    from hlik.study.runner import run_study
    from hlik.util.paths import demo_motion_path as demo

    approaches = (Approach("jm", correlation=True), Approach("qp", correlation=True))
    result = run_study([demo()], [str(G1)], approaches, tmp_path, seconds=0.5, workers=1)
    assert not any(o.error for o in result.outcomes)
    assert sorted(p.name for p in (tmp_path / "cells").glob("*.parquet"))[0].startswith(
        "demo_pour_wipe__g1__"
    )


def test_a_scaled_subject_scales_every_position_and_keeps_the_angles(cut_take):
    from hlik.human import forward_kinematics, load_motion

    motion = load_motion(cut_take).frames(slice(0, 20))
    small = motion.scaled(0.7, " (test)")
    a, b = forward_kinematics(motion), forward_kinematics(small)
    for p, q in ((a.shoulder, b.shoulder), (a.elbow, b.elbow), (a.wrist, b.wrist), (a.tcp_pos, b.tcp_pos)):
        np.testing.assert_allclose(q, 0.7 * p, atol=1e-9)
    np.testing.assert_allclose(b.tcp_rot, a.tcp_rot, atol=1e-12)
    assert np.array_equal(small.joints, motion.joints) and "subject scaled by 0.700" in small.notes[-1]
    for name, obj in motion.objects.items():
        np.testing.assert_allclose(small.objects[name].position, 0.7 * obj.position)


def test_auto_scale_fits_the_subject_to_the_g1_arms(g1, cut_take, tmp_path):
    from hlik.human import load_motion
    from hlik.human.kinematics import human_model
    from hlik.problem.scale import arm_length, scale_subject

    motion = load_motion(cut_take).frames(slice(0, 5))
    scaled = scale_subject(motion, g1)  # the example's subject_scale = "auto"
    robot_arm = arm_length(g1.model, g1.home)
    assert 0.45 < robot_arm < 0.5  # shoulder to TCP, the README's 0.48 m
    human = human_model(scaled.height)
    np.testing.assert_allclose(arm_length(human, human.qpos0), robot_arm, rtol=1e-9)
    assert scale_subject(motion, load_robot("armar3")) is motion  # ARMAR-III, 2-Panda: as recorded
    assert scale_subject(motion, load_robot("armar6")).height > 1.4 * motion.height  # scaled to its arms
    bad = CliRunner().invoke(app, ["run", "--robot", str(G1), "--scale", "0", "-o", str(tmp_path / "x.rrd")])
    assert (
        bad.exit_code != 0 and "subject scale (--scale, subject_scale) must be auto or 0.1-10" in bad.output
    )
    assert not list(tmp_path.iterdir())


def test_auto_scale_keeps_the_subjects_reach_about_the_robots_shoulders(g1, cut_take):
    """``auto`` scales about the subject's shoulders and stands them at the robot's shoulder height:
    the hands' offsets from the shoulders scale by the arm ratio exactly, on the G1 (x0.8) and on
    ARMAR-6 (x1.5: about the floor its shoulders stood 0.7 m above the robot's, the targets over its
    head); where the feet leave the floor the note says by how much."""
    from hlik.human import forward_kinematics, load_motion
    from hlik.problem.scale import auto_scale, scale_subject, shoulder_heights

    motion = load_motion(cut_take).frames(slice(0, 5))
    a = forward_kinematics(motion)
    for robot in (g1, load_robot("armar6")):
        factor = auto_scale(robot, motion)
        scaled = scale_subject(motion, robot, "auto")
        b = forward_kinematics(scaled)
        mid_a, mid_b = a.shoulder.mean(axis=1, keepdims=True), b.shoulder.mean(axis=1, keepdims=True)
        np.testing.assert_allclose(b.tcp_pos - mid_b, factor * (a.tcp_pos - mid_a), atol=1e-9)
        shoulders, robot_z = shoulder_heights(robot, scaled)
        assert abs(shoulders[2] - robot_z) < 1e-9
        note = scaled.notes[-1]
        assert note.startswith(str(cut_take)) and "about its shoulders" in note and " the floor" in note
        # the objects move with the subject, and the note says to what height (the robot works there)
        before = np.nanmedian(np.concatenate([o.position[:, 2] for o in motion.objects.values()]))
        after = np.nanmedian(np.concatenate([o.position[:, 2] for o in scaled.objects.values()]))
        assert f"median height {before:.2f} m -> {after:.2f} m" in note
    assert (
        1.4 < auto_scale(load_robot("armar6"), motion) < 1.6
        and "feet 0.7" in note
        and "below the floor" in note
    )


def _coupled_armar3(tmp_path: Path, joint1: str, joint2: str) -> Path:
    """An ARMAR-III copy with two head joints (welded: not in [arms]) and a joint equality, what
    MuJoCo makes of a URDF ``<mimic>`` (google-deepmind/mujoco #3527)."""
    path = _armar3_copy(tmp_path, lambda t: t)
    xml = tmp_path / "mjcf" / "armar3.xml"
    text = xml.read_text()
    head = '<body name="head" pos="0 0 0.118">'
    text = text.replace(
        head, head + '<joint name="HeadTilt" axis="1 0 0"/><joint name="HeadPan" axis="0 0 1"/>'
    )
    text = text.replace(
        "</mujoco>", f'<equality><joint joint1="{joint1}" joint2="{joint2}"/></equality></mujoco>'
    )
    xml.write_text(text)
    return path


def test_a_coupling_between_welded_joints_goes_with_them(tmp_path):
    robot = load_robot(str(_coupled_armar3(tmp_path, "HeadTilt", "HeadPan")))
    bundled = load_robot("armar3")
    assert robot.joint_names == bundled.joint_names and robot.model.neq == 0
    np.testing.assert_allclose(
        tcp_poses(robot, robot.home[None])[0], tcp_poses(bundled, bundled.home[None])[0]
    )


@pytest.mark.parametrize(
    ("joint1", "joint2", "solved"),
    [("Wrist2_L", "Wrist1_L", "Wrist2_L, Wrist1_L"), ("HeadTilt", "HipYaw", "HipYaw")],
)
def test_a_coupling_of_a_solved_joint_is_refused_naming_it(tmp_path, joint1, joint2, solved):
    """The solvers move joints independently: a mimic joint they solve ran with exit 0 and the pair
    0.89 rad apart (G1 wrists); one they weld failed in MuJoCo's words."""
    path = _coupled_armar3(tmp_path, joint1, joint2)
    with pytest.raises(
        RobotError, match=f"joints {joint1} and {joint2} are coupled .* hlik solves {solved}:"
    ) as e:
        load_robot(str(path))
    assert str(e.value).startswith(str(path)) and "\n" not in str(e.value)


def test_calibrate_warns_of_a_tcp_frame_off_the_convention(tmp_path):
    """A left TCP site turned a quarter turn about its approach axis (x, the palm normal, where y
    should be): calibrate names the hand and the convention; the bundled model gets no warning."""
    from typer.testing import CliRunner

    from hlik.cli import app

    turned = _TCP.replace(
        'xyaxes="0.258819045 0 0.965925826 0.965925826 0 -0.258819045"',
        'xyaxes="0 1 0 -0.965925826 0 0.258819045"',
    )
    path = _armar3_copy(tmp_path, lambda t: t, lambda m: m.replace(_TCP, turned))
    out = CliRunner().invoke(app, ["calibrate", str(path)])
    assert out.exit_code == 0, out.output
    assert "the TCP site's frame is turned left" in out.output and "convention" in out.output, out.output
    assert "right" not in out.output.split("the TCP site's frame is turned")[1].split("from the MMM")[0]
    out = CliRunner().invoke(app, ["calibrate", "armar3"])
    assert "TCP site's frame is turned" not in out.output
