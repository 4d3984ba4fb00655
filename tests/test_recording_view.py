"""What a user sees on opening a recording: the camera in front of both figures, plots split per
arm with distinct colours and units, scores grouped, relative-pose errors for relative runs, the
result panel holding the numbers of ``hlik evaluate --json``, object labels without ``true_``.

Inputs are a second of the real Cut take (ARMAR-6, JM solver); outputs go to tmp_path.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from hlik.criteria import registry
from hlik.criteria.learned import learn
from hlik.human.kinematics import human_model, qpos_trajectory
from hlik.human.load import load_motion
from hlik.metrics import evaluate
from hlik.problem.placement import placement_from_spec
from hlik.recording import (
    ASPECT,
    FRAME_TAN,
    joint_groups,
    object_label,
    robot_camera,
    scene_camera,
    score_window,
    write_recording,
)
from hlik.recording.scene import _display_placement
from hlik.retarget import retarget
from hlik.robot.model import load_robot
from hlik.util.spatial import body_poses


@pytest.fixture(scope="module")
def armar6():
    return load_robot("armar6")


@pytest.fixture(scope="module")
def cut(cut_take):
    return load_motion(cut_take, rate=100.0).crop(2.0, 3.0)


@pytest.fixture(scope="module", params=["pose", "relative"])
def run(request, cut, armar6, tmp_path_factory):
    """A trajectory, its evaluation in the scenario and the content of its recording."""
    traj = retarget(cut, armar6, "jm", placement_from_spec("shoulders", armar6, cut))
    ev = evaluate(traj, armar6, learn(armar6), scenario=request.param)
    path = tmp_path_factory.mktemp("rec") / "r.rrd"
    info = {"stack": "ee_pose", "criteria": "SYN, HJA_r", "corpus": "demo | x"}
    write_recording(path, traj, armar6, evaluation=ev, info=info)
    return traj, ev, path, _static(path), _temporal(path)


def _static(path) -> dict[str, dict]:
    out: dict[str, dict] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.is_static:
            row = chunk.to_record_batch().to_pylist()[-1]
            out.setdefault(chunk.entity_path, {}).update(row)
    return out


def _temporal(path) -> dict[str, pa.Table]:
    batches: dict[str, list] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if not chunk.is_static:
            batch = chunk.to_record_batch()
            batch = batch.drop_columns([n for n in batch.schema.names if n.endswith("RowId")])
            batches.setdefault(chunk.entity_path, []).append(batch)
    return {e: pa.Table.from_batches(b).sort_by("frame") for e, b in batches.items()}


def _scalars(table: pa.Table) -> np.ndarray:
    return np.array([v[0] for v in table.column("Scalars:scalars").to_pylist()])


def test_result_panel_holds_the_numbers_of_evaluate_json(run):
    traj, ev, _, static, _ = run
    exact = json.loads(static["/result/json"]["TextDocument:text"][0])
    assert exact == json.loads(json.dumps(ev.to_json()))  # what `hlik evaluate --json` prints
    panel = static["/result"]
    assert panel["TextDocument:media_type"] == ["text/markdown"]
    text = panel["TextDocument:text"][0]
    for key, label in (("m_hl", "m_hl"), ("m_f", "m_f"), ("m_hl_f", "m_hl,f")):
        shown = float(re.search(rf"{re.escape(label)} = ([0-9.]+)", text).group(1))
        assert shown == pytest.approx(exact[key], abs=5e-5), key
    for group in ("metrics", "functional"):
        for name, pair in exact[group].items():
            row = re.search(rf"\| {name} \| ([^|]+) \| ([^|]+) \|", text)  # three to a row
            assert row, name
            assert float(row.group(2)) == pytest.approx(pair["m"], abs=5e-5)
            assert float(row.group(1)) == pytest.approx(pair["h"], rel=1e-3, abs=1e-12)
    assert len(exact["metrics"]) == len(registry.human_likeness()) == 11
    # the scores and every criterion's before the settings: they show without scrolling
    scores, settings = text.split("\n| | |\n")
    assert "| criterion |" in scores and "| stack |" in settings
    assert scores.count("\n") <= 12
    for needle in ("| stack | ee_pose |", "| solver | jm |", "| placement | shoulders |", "demo \\| x"):
        assert needle in text
    assert f"| failed frames | {traj.diagnostics.n_failed} of {traj.n_frames} |" in text
    assert f"| frames in self-collision | {int(ev.collisions.sum())} of {traj.n_frames} |" in text
    assert re.search(r"^hlik \d+\.\d+", text, re.M)


def test_unified_curves_average_to_the_scores(run):
    traj, ev, _, _, temporal = run
    window = score_window(traj)
    assert window == 21  # 0.2 s at 100 Hz
    m_hl, m_f = ev.unified_curves(window)
    assert np.mean(m_hl) == pytest.approx(ev.m_hl, abs=1e-12)
    assert np.mean(m_f) == pytest.approx(ev.m_f, abs=1e-12)
    np.testing.assert_array_equal(_scalars(temporal["/plots/unified/m_hl"]), m_hl)
    np.testing.assert_array_equal(_scalars(temporal["/plots/unified/m_f"]), m_f)
    for name, curve in ev.curves(window).items():  # evaluation's curves logged when no metrics are given
        np.testing.assert_array_equal(_scalars(temporal[f"/plots/metrics/{name}"]), curve)
        assert np.mean(curve) == pytest.approx(ev.m[name], abs=1e-12)


def test_camera_is_in_front_and_frames_both_figures(run, armar6):
    traj, _, _, _, _ = run
    cam = scene_camera(traj, armar6, "side")
    facing = traj.motion.root_rotation[:, :, 1].mean(axis=0)
    facing[2] = 0
    pelvis = traj.motion.root_position.mean(axis=0)
    assert np.dot(cam.position - pelvis, facing) > 0.5  # in front of the human
    # every human body and robot body (drawn beside it) at every frame lies inside the view pyramid
    human = human_model(traj.motion.height)
    rows = slice(None)
    human_pos = body_poses(human, qpos_trajectory(human, traj.motion.frames(rows)))[0][:, 1:]
    shown = _display_placement(traj, armar6, "side")
    robot_pos = body_poses(armar6.model, traj.q)[0][:, 1:] @ shown.rotation.T + shown.translation
    for points in (human_pos.reshape(-1, 3), robot_pos.reshape(-1, 3)):
        _assert_in_view(cam, points)
    # the robot also seen from its front in its own view
    alone = robot_camera(traj, armar6)
    assert alone.position[1] > 0.5
    _assert_in_view(alone, body_poses(armar6.model, traj.q)[0][:, 1:].reshape(-1, 3))


def test_the_side_layout_keeps_the_figures_apart(armar6):
    """The demo's subject, scaled to ARMAR-6's arms, reaches sideways: the side layout shifts the
    robot further than its 1.2 m until no body of either comes within SIDE_GAP of the other along the
    shift, frame by frame; a shift never falls below SPACING."""
    import hlik
    from hlik.recording.scene import SIDE_GAP, SPACING, side_spacing

    traj = hlik.run(hlik.RunSpec(robot="armar6", solver="jm", span=(2.0, 5.0))).trajectory
    shift = side_spacing(traj, armar6)  # from 24 frames spread over the take
    assert shift > SPACING
    shown = _display_placement(traj, armar6, "side")
    np.testing.assert_allclose(
        shown.translation - traj.placement.translation, shift * traj.placement.rotation[:, 0]
    )
    human = human_model(traj.motion.height)
    human_pos = body_poses(human, qpos_trajectory(human, traj.motion.frames(slice(None))))[0][:, 1:]
    robot_pos = body_poses(armar6.model, traj.q)[0][:, 1:] @ shown.rotation.T + shown.translation
    x = traj.placement.rotation[:, 0]
    gap = (robot_pos @ x).min(axis=1) - (human_pos @ x).max(axis=1)  # (T,) along the shift
    assert gap.min() >= SIDE_GAP - 0.02  # between the sampled frames, a little nearer
    assert _display_placement(traj, armar6, "overlay") == traj.placement


def test_a_subject_sunk_by_its_scale_is_drawn_on_the_floor(armar6, cut, tmp_path):
    """Scaled about its shoulders to ARMAR-6's arms, the demo's subject sinks 0.7 m into the floor:
    the side layout draws its world (bodies, hand paths, objects) lifted so that its lowest geometry
    is on the floor; overlay does not move it, nor a recorded subject standing on the floor."""
    import mujoco

    import hlik
    from hlik.recording.scene import human_lift

    traj = hlik.run(hlik.RunSpec(robot="armar6", solver="jm", span=(2.0, 3.0))).trajectory
    lift = human_lift(traj.motion, "side", samples=traj.n_frames)
    assert 0.5 < lift < 1.0 and human_lift(traj.motion, "overlay") == 0.0
    assert human_lift(cut, "side") == 0.0  # a KIT take at its own scale stands on the floor
    model = human_model(traj.motion.height)
    data = mujoco.MjData(model)
    lowest = np.inf
    for q in qpos_trajectory(model, traj.motion.frames(slice(None))):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)  # contacts aside: the geoms' world boxes
        for g in range(model.ngeom):
            corners = np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1).T * model.geom_aabb[g, 3:]
            world = (corners + model.geom_aabb[g, :3]) @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
            lowest = min(lowest, world[:, 2].min())
    assert lowest + lift == pytest.approx(0.0, abs=1e-6)
    rrd = tmp_path / "lifted.rrd"
    write_recording(rrd, traj, armar6)
    static = {c.entity_path: c.to_record_batch() for c in RrdReader(rrd).stream().to_chunks() if c.is_static}
    for world in ("/world/human", "/world/objects", "/world/labels"):
        translation = static[world].column("Transform3D:translation").to_pylist()[0][0]
        assert translation == pytest.approx([0.0, 0.0, human_lift(traj.motion, "side")], abs=1e-6), world


def _assert_in_view(cam, points):
    ahead = cam.target - cam.position
    ahead /= np.linalg.norm(ahead)
    right = np.cross(ahead, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, ahead)
    rel = points - cam.position
    depth = rel @ ahead
    assert np.all(depth > 0.3)
    assert np.all(np.abs(rel @ up) / depth <= FRAME_TAN)
    assert np.all(np.abs(rel @ right) / depth <= ASPECT * FRAME_TAN)


def test_blueprint_opens_on_these_cameras_with_a_robot_view(run, armar6):
    traj, _, path, _, _ = run
    reader = RrdReader(path)
    names, eyes = {}, {}
    for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks():
        batch = chunk.to_record_batch()
        if "ViewBlueprint:display_name" in batch.schema.names:
            names[chunk.entity_path] = batch.column("ViewBlueprint:display_name").to_pylist()[0][0]
        if "EyeControls3D:position" in batch.schema.names:
            view = chunk.entity_path.rsplit("/", 1)[0]
            eyes[view] = [
                np.array(batch.column(f"EyeControls3D:{k}").to_pylist()[0][0])
                for k in ("position", "look_target")
            ]
    by_name = {names[v]: eye for v, eye in eyes.items()}
    assert set(by_name) == {"human and robot", "robot alone"}
    for name, cam in (
        ("human and robot", scene_camera(traj, armar6)),
        ("robot alone", robot_camera(traj, armar6)),
    ):
        np.testing.assert_allclose(by_name[name][0], cam.position, atol=1e-5)
        np.testing.assert_allclose(by_name[name][1], cam.target, atol=1e-5)
    assert {"left arm", "right arm", "result"} <= set(names.values())
    assert sum(n.startswith("scores: ") for n in names.values()) == 4  # the paper's clusters
    relative = "fPOS_off (m), optimised" in names.values()
    assert relative == (run[1].scenario == "relative")


def test_joint_curves_split_per_arm_with_units_and_distinct_colours(run, armar6):
    traj, _, _, static, temporal = run
    groups = joint_groups(armar6)
    assert list(groups) == ["left arm", "right arm"]
    assert set(groups["left arm"]) == set(armar6.arm_joints["left"])
    for joints in groups.values():
        colours = [tuple(static[f"/plots/joints/{j}"]["SeriesLines:colors"]) for j in joints]
        assert len(set(colours)) == len(joints)  # distinct within a panel
        for j in joints:
            assert static[f"/plots/joints/{j}"]["SeriesLines:names"] == [f"{j} (rad)"]
            np.testing.assert_array_equal(
                _scalars(temporal[f"/plots/joints/{j}"]), traj.q[:, traj.joint_names.index(j)]
            )
    names = [static[f"/plots/metrics/{k}"]["SeriesLines:names"][0] for k in ("SYN", "fPOS")]
    assert names == ["SYN (score)", "fPOS (score)"]


def test_armar3_hip_joints_get_their_own_panel():
    armar3 = load_robot("armar3")
    groups = joint_groups(armar3)
    assert groups["other joints"] == ("HipPitch", "HipYaw")
    assert sorted(j for g in groups.values() for j in g) == sorted(armar3.joint_names)


def test_relative_runs_plot_the_relative_errors(run):
    traj, ev, _, _, temporal = run
    if ev.scenario == "relative":
        off = _scalars(temporal["/plots/fPOS_off"])
        np.testing.assert_allclose(off.mean(), ev.h["fPOS_off"].mean(), rtol=1e-9)
        assert "/plots/fORI_off" in temporal
    else:
        assert "/plots/fPOS_off" not in temporal
    assert "/plots/fPOS/left" in temporal  # the absolute errors stay, for context


def test_object_labels_drop_true_and_sit_above_the_box(run):
    traj, _, _, static, temporal = run
    assert object_label("true_knife_black") == "knife_black"
    assert object_label("true_") == "true_" and object_label("bowl") == "bowl"
    objects = [e for e in static if e.startswith("/world/objects/")]
    assert objects
    for entity in objects:
        assert "Boxes3D:labels" not in static[entity]  # no label on the box, over the hand
        name = entity.rsplit("/", 1)[1]
        label = static[f"/world/labels/{name}"]["Points3D:labels"]
        assert label == [object_label(name)] and not label[0].startswith("true_")
        box = temporal[entity].column("Transform3D:translation").to_pylist()
        above = temporal[f"/world/labels/{name}"].column("Transform3D:translation").to_pylist()
        z_box = np.array([v[0][2] if isinstance(v[0], list) else v[2] for v in box])
        z_label = np.array([v[0][2] if isinstance(v[0], list) else v[2] for v in above])
        assert np.all(z_label > z_box)


def test_an_object_without_markers_is_drawn_as_its_frame_not_a_box(run):
    """The Cut take's sideboard is recorded as a pose alone: its extent is unknown, so it is drawn
    as axes at the human and at the robot, while every object with markers is a box."""
    traj, _, _, static, _ = run
    for name, obj in traj.motion.objects.items():
        for entity in (f"/world/objects/{name}", f"/world/robot/objects/{name}"):
            if entity not in static:  # a pose never known: not drawn
                continue
            drawn = " ".join(static[entity])
            assert ("Boxes3D" in drawn) == bool(obj.markers), (entity, drawn)
            assert ("TransformAxes3D" in drawn) != bool(obj.markers), (entity, drawn)
    assert any(not obj.markers for obj in traj.motion.objects.values())


def test_the_posture_measures_are_logged_for_the_robot_and_the_subject(run):
    _, ev, _, _, temporal = run
    for who, body in (("robot", ev.posture.robot), ("subject", ev.posture.subject)):
        np.testing.assert_allclose(_scalars(temporal[f"/plots/posture/{who}_lean"]), body.lean)
        for i, side in enumerate(("left", "right")):
            logged = _scalars(temporal[f"/plots/posture/{who}_{side}_elbow"])
            np.testing.assert_allclose(logged, body.elbow_front_share[:, i])
            logged = _scalars(temporal[f"/plots/posture/{who}_{side}_wrist"])
            np.testing.assert_allclose(logged, body.wrist_front_share[:, i])


def test_the_robot_carries_the_objects_its_hands_hold(run, cut_take, armar6):
    # held: the robot's TCP pose times the object's pose in the target's frame; the others stay put
    from dataclasses import replace

    from hlik.recording.scene import _object_box, carried_pose, holding_hand

    traj, _, _, static, temporal = run
    knife = traj.motion.objects["true_knife_black"]
    box = _object_box(knife, 100)
    holder = holding_hand(traj, knife, box)
    assert set(holder) <= {-1, 1} and (holder == 1).any()  # the right hand picks the knife up
    frames = np.arange(traj.n_frames)
    recorded = traj.placement.to_base(knife.position, knife.rotation)
    on_target = replace(traj, tcp_pos=traj.targets.pos, tcp_rot=traj.targets.rot)
    for got, want in zip(carried_pose(on_target, knife, holder, frames), recorded):
        np.testing.assert_allclose(got, want, atol=1e-12)
    shift = np.array([0.05, -0.02, 0.01])
    moved = replace(on_target, tcp_pos=traj.targets.pos + shift)
    pos, _ = carried_pose(moved, knife, holder, frames)
    np.testing.assert_allclose(pos - recorded[0], np.where((holder == 1)[:, None], shift, 0.0), atol=1e-12)
    # every object with a pose is drawn at the robot too, and a fixture (the sideboard) stays put
    drawn = {e.rsplit("/", 1)[1] for e in static if e.startswith("/world/robot/objects/")}
    assert drawn == {e.rsplit("/", 1)[1] for e in static if e.startswith("/world/objects/")}
    board = traj.motion.objects["true_kitchen_sideboard"]
    assert (holding_hand(traj, board, _object_box(board, 100)) == -1).all()
    assert "/world/robot/objects/true_knife_black" in temporal


def test_one_left_right_label_pair_per_figure(run):
    # three labelled pairs (hand paths, target paths, TCP paths) piled up on the hands in side views
    traj, _, _, static, _ = run
    for entity in ("/world/robot/target_paths", "/world/human/hand_paths", "/world/robot/tcp_paths"):
        assert static[entity]["LineStrips3D:show_labels"] == [False]  # on the strip they sat on the hands
    assert "/world/robot/target_paths/labels" not in static
    paths = {
        "/world/human/hand_paths": traj.placement.to_world(traj.targets.pos),
        "/world/robot/tcp_paths": traj.tcp_pos,
    }
    for entity, pos in paths.items():  # drawn above each path, clear of its hand
        labels = static[f"{entity}/labels"]
        assert list(np.ravel(labels["Points3D:labels"])) == ["left", "right"]
        above = np.reshape(labels["Points3D:positions"], (2, 3))[:, 2]
        np.testing.assert_allclose(above, pos[..., 2].max(axis=0) + 0.12, atol=1e-5)
